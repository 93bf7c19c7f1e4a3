#include "robot/enon_model.h"

#include <cmath>
#include <cstdio>

#include "core/error.h"
#include "core/yaml.h"

namespace refgrasp::robot {
namespace {

void checkLimits(const JointLimits& l, const std::string& what) {
  check(std::isfinite(l.min_rad) && std::isfinite(l.max_rad) && l.min_rad <= l.max_rad, what,
        "min_rad must not exceed max_rad");
  check(std::isfinite(l.max_speed_radps) && l.max_speed_radps > 0, what,
        "max_speed_radps must be positive");
}

// Sequence items have no dotted name: errors from YamlFile are re-thrown with the item's prefix.
template <typename F>
auto withPrefix(const std::string& prefix, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const ConfigError& e) {
    const std::string head = e.file() + ": " + e.field() + ": ";
    const std::string what = e.what();
    const std::string problem = what.size() > head.size() ? what.substr(head.size()) : what;
    throw ConfigError(e.file(), prefix + "." + e.field(), problem);
  }
}

JointLimits readLimits(const YamlFile& f, const YAML::Node& node, const std::string& field) {
  JointLimits l;
  l.min_rad = f.number(node, field + ".min_rad");
  l.max_rad = f.number(node, field + ".max_rad");
  l.max_speed_radps = f.number(node, field + ".max_speed_radps");
  if (l.min_rad > l.max_rad) f.fail(field, "min_rad > max_rad");
  if (l.max_speed_radps <= 0) f.fail(field + ".max_speed_radps", "must be positive");
  return l;
}

double positive(const YamlFile& f, const YAML::Node& node, const std::string& field) {
  const double v = f.number(node, field);
  if (v <= 0) f.fail(field, "must be positive");
  return v;
}

// A value in [lo, hi]: periods and rates bound the loops and the frames a run makes.
double bounded(const YamlFile& f, const YAML::Node& node, const std::string& field, double lo,
               double hi, const std::string& unit) {
  const double v = f.number(node, field);
  if (v <= 0) f.fail(field, "must be positive");
  if (v < lo || v > hi) {
    char buf[128];
    std::snprintf(buf, sizeof buf, "must be in [%g, %g] %s", lo, hi, unit.c_str());
    f.fail(field, buf);
  }
  return v;
}

double nonNegative(const YamlFile& f, const YAML::Node& node, const std::string& field) {
  const double v = f.number(node, field);
  if (v < 0) f.fail(field, "must not be negative");
  return v;
}

LinkCapsule readLink(const YamlFile& f, const YAML::Node& node, const std::string& field, int dof) {
  LinkCapsule l;
  l.from_frame = f.integer(node, field + ".from_frame");
  l.to_frame = f.integer(node, field + ".to_frame");
  l.radius_m = positive(f, node, field + ".radius_m");
  if (l.from_frame < 0 || l.from_frame > dof)
    f.fail(field + ".from_frame", "expected a DH frame 0.." + std::to_string(dof));
  if (l.to_frame <= l.from_frame || l.to_frame > dof)
    f.fail(field + ".to_frame", "expected a DH frame " + std::to_string(l.from_frame + 1) + ".." +
                                    std::to_string(dof) + " (after from_frame)");
  return l;
}

}  // namespace

void EnonModel::check() const {
  refgrasp::check(control_period_s > 0 && std::isfinite(control_period_s), "enon",
                  "control_period_s must be positive");
  refgrasp::check(watchdog_period_s > 0 && std::isfinite(watchdog_period_s), "enon",
                  "watchdog_period_s must be positive");
  refgrasp::check(base.track_width_m > 0 && base.max_linear_speed_mps > 0 &&
                      base.max_angular_speed_radps > 0 && base.max_wheel_speed_mps > 0,
                  "enon.base", "sizes and speed limits must be positive");
  checkLimits(head.pan, "enon.head.pan");
  checkLimits(head.tilt, "enon.head.tilt");
  refgrasp::check(head.bMp.isFinite() && head.tMc.isFinite(), "enon.head", "poses must be finite");
  refgrasp::check(head.frame_rate_hz > 0, "enon.head", "frame_rate_hz must be positive");
  refgrasp::check(base.body_radius_m > 0 && base.body_height_m > 0, "enon.base",
                  "body_radius_m and body_height_m must be positive");
  refgrasp::check(!arm.joints.empty(), "enon.arm", "needs at least one joint");
  for (const LinkCapsule* l : {&arm.upper_arm, &arm.forearm})
    refgrasp::check(l->from_frame >= 0 && l->from_frame < l->to_frame && l->to_frame <= arm.dof() &&
                        l->radius_m > 0,
                    "enon.arm", "link capsules need 0 <= from_frame < to_frame <= dof and radius_m > 0");
  for (const auto& j : arm.joints) checkLimits(j.limits, "enon.arm." + j.name);
  refgrasp::check(arm.dls_damping >= 0, "enon.arm", "dls_damping must not be negative");
  refgrasp::check(gripper.close_time_s >= 0 && gripper.open_time_s >= 0 &&
                      gripper.grasp_tolerance_m > 0 && gripper.grasp_tolerance_rad > 0,
                  "enon.gripper", "times must be >= 0 and tolerances positive");
  refgrasp::check(gripper.open_width_m > 0 && gripper.finger_radius_m > 0 &&
                      gripper.palm_radius_m > 0 && gripper.palm_offset_m > 0 &&
                      gripper.finger_length_m > gripper.palm_offset_m,
                  "enon.gripper",
                  "sizes must be positive and finger_length_m must exceed palm_offset_m");
}

EnonModel loadEnonModel(const std::string& path) {
  const YamlFile f(path);
  const YAML::Node& r = f.root();
  EnonModel m;
  m.path = path;
  m.control_period_s = bounded(f, r, "control_period_s", 1e-3, 1.0, "s");
  m.watchdog_period_s = bounded(f, r, "watchdog_period_s", m.control_period_s, 60.0, "s (from control_period_s)");

  m.base.track_width_m = positive(f, r, "base.track_width_m");
  m.base.max_linear_speed_mps = positive(f, r, "base.max_linear_speed_mps");
  m.base.max_angular_speed_radps = positive(f, r, "base.max_angular_speed_radps");
  m.base.max_wheel_speed_mps = positive(f, r, "base.max_wheel_speed_mps");
  m.base.body_radius_m = positive(f, r, "base.body.radius_m");
  m.base.body_height_m = positive(f, r, "base.body.height_m");

  m.head.bMp = f.pose(r, "head.mount");
  m.head.tilt_height_m = f.number(r, "head.tilt_height_m");
  m.head.pan = readLimits(f, r, "head.pan");
  m.head.tilt = readLimits(f, r, "head.tilt");
  m.head.tMc = f.pose(r, "head.camera_mount");
  m.head.frame_rate_hz = bounded(f, r, "head.frame_rate_hz", 0.1, 1000.0, "Hz");
  m.head.rig_path = f.resolve(f.string(r, "head.stereo_rig"));
  try {
    m.head.rig = loadStereoRig(m.head.rig_path);
  } catch (const ConfigError& e) {
    f.fail("head.stereo_rig", e.what());
  }

  m.arm.side = f.string(r, "arm.side");
  if (m.arm.side != "right" && m.arm.side != "left")
    f.fail("arm.side", "expected right or left, got '" + m.arm.side + "'");
  m.arm.bM0 = f.pose(r, "arm.mount");
  m.arm.nMe = f.pose(r, "arm.tool");
  m.arm.dls_damping = nonNegative(f, r, "arm.dls_damping");
  const YAML::Node joints = f.get(r, "arm.joints");
  if (!joints.IsDefined() || joints.IsNull()) f.fail("arm.joints", "missing (expected a list)");
  if (!joints.IsSequence() || joints.size() == 0)
    f.fail("arm.joints", "expected a non-empty list of DH rows");
  if (joints.size() > 32) f.fail("arm.joints", std::to_string(joints.size()) + " joints, at most 32");
  for (size_t i = 0; i < joints.size(); ++i) {
    const std::string prefix = "arm.joints[" + std::to_string(i) + "]";
    const YAML::Node row = joints[i];
    if (!row.IsMap()) f.fail(prefix, "expected a mapping with name, a_m, alpha_rad, d_m, ...");
    DhJoint j = withPrefix(prefix, [&] {
      DhJoint d;
      d.name = f.string(row, "name");
      d.a_m = f.number(row, "a_m");
      d.alpha_rad = f.number(row, "alpha_rad");
      d.d_m = f.number(row, "d_m");
      d.theta_offset_rad = f.number(row, "theta_offset_rad");
      d.limits = readLimits(f, row, "limits");
      return d;
    });
    for (const auto& other : m.arm.joints)
      if (other.name == j.name) f.fail(prefix + ".name", "duplicate joint name '" + j.name + "'");
    m.arm.joints.push_back(j);
  }
  m.arm.upper_arm = readLink(f, r, "arm.upper_arm", m.arm.dof());
  m.arm.forearm = readLink(f, r, "arm.forearm", m.arm.dof());

  m.gripper.close_time_s = nonNegative(f, r, "gripper.close_time_s");
  m.gripper.open_time_s = nonNegative(f, r, "gripper.open_time_s");
  m.gripper.grasp_tolerance_m = positive(f, r, "gripper.grasp_tolerance_m");
  m.gripper.grasp_tolerance_rad = positive(f, r, "gripper.grasp_tolerance_rad");
  m.gripper.max_payload_kg = positive(f, r, "gripper.max_payload_kg");
  m.gripper.open_width_m = positive(f, r, "gripper.open_width_m");
  m.gripper.finger_length_m = positive(f, r, "gripper.finger_length_m");
  m.gripper.finger_radius_m = positive(f, r, "gripper.finger_radius_m");
  m.gripper.palm_offset_m = positive(f, r, "gripper.palm_offset_m");
  m.gripper.palm_radius_m = positive(f, r, "gripper.palm_radius_m");
  if (m.gripper.finger_length_m <= m.gripper.palm_offset_m)
    f.fail("gripper.finger_length_m",
           "must exceed palm_offset_m (the fingertips reach past the gripper frame e)");
  f.rejectUnknownFields();
  return m;
}

}  // namespace refgrasp::robot
