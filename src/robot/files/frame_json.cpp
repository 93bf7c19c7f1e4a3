#include "robot/files/frame_json.h"

#include <cmath>

#include "core/error.h"

namespace refgrasp::files {

namespace {

Json vectorJson(const Eigen::VectorXd& v) {
  Json a = Json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) a.push_back(v[i]);
  return a;
}

bool fail(std::string* problem, const std::string& field, const std::string& what) {
  *problem = field + ": " + what;
  return false;
}

// A finite number at j[key]; `fallback` when absent and allowed.
bool number(const Json& j, const char* key, double* out, std::string* problem, bool required) {
  if (!j.contains(key)) return !required || fail(problem, key, "missing");
  if (!j[key].is_number()) return fail(problem, key, "not a number");
  *out = j[key].get<double>();
  return std::isfinite(*out) || fail(problem, key, "not finite");
}

bool numbers(const Json& j, const char* key, Eigen::VectorXd* out, std::string* problem,
             int n = -1) {
  if (!j.contains(key)) return fail(problem, key, "missing");
  const Json& a = j[key];
  if (!a.is_array() || (n >= 0 && static_cast<int>(a.size()) != n))
    return fail(problem, key, n >= 0 ? "needs " + std::to_string(n) + " numbers" : "not a list");
  out->resize(static_cast<Eigen::Index>(a.size()));
  for (size_t i = 0; i < a.size(); ++i) {
    if (!a[i].is_number() || !std::isfinite(a[i].get<double>()))
      return fail(problem, key, "element " + std::to_string(i) + " is not a finite number");
    (*out)[static_cast<Eigen::Index>(i)] = a[i].get<double>();
  }
  return true;
}

// The pose at j[key] (core/json.h): false and "<key>: <field>: <problem>" when it does not fit.
bool pose(const Json& j, const char* key, Pose* out, std::string* problem) {
  try {
    *out = poseFromJson(j[key], key);
    return true;
  } catch (const ConfigError& e) {
    *problem = e.what();
    return false;
  }
}

}  // namespace

Json captureToJson(const robot::CaptureState& c) {
  Json j = Json::object();
  if (c.head) j["head"] = {{"pan_rad", c.head->pan_rad}, {"tilt_rad", c.head->tilt_rad}};
  if (c.bMc) j["bMc"] = poseJson(*c.bMc);
  if (c.wMb_odom) j["wMb_odom"] = poseJson(*c.wMb_odom);
  return j;
}

bool captureFromJson(const Json& j, robot::CaptureState* c, std::string* problem) {
  *c = {};
  if (!j.is_object()) return fail(problem, "capture", "not an object");
  if (j.contains("head")) {
    robot::HeadJoints h;
    const Json& hj = j["head"];
    if (!hj.is_object()) return fail(problem, "head", "not an object");
    std::string p;
    if (!number(hj, "pan_rad", &h.pan_rad, &p, true) ||
        !number(hj, "tilt_rad", &h.tilt_rad, &p, true))
      return fail(problem, "head", p);
    c->head = h;
  }
  for (const char* key : {"bMc", "wMb_odom"}) {
    if (!j.contains(key)) continue;
    Pose P;
    if (!pose(j, key, &P, problem)) return false;
    (std::string(key) == "bMc" ? c->bMc : c->wMb_odom) = P;
  }
  return true;
}

Json truthToJson(const std::vector<robot::ObjectTruth>& truth) {
  Json a = Json::array();
  for (const auto& t : truth) {
    Json o = {{"object", t.object}, {"cMo", poseJson(t.cMo)}};
    if (t.rMo) o["rMo"] = poseJson(*t.rMo);
    a.push_back(o);
  }
  return a;
}

bool truthFromJson(const Json& j, std::vector<robot::ObjectTruth>* truth, std::string* problem) {
  truth->clear();
  if (!j.is_array()) return fail(problem, "truth", "not a list");
  for (size_t i = 0; i < j.size(); ++i) {
    const Json& o = j[i];
    const std::string where = "truth[" + std::to_string(i) + "]";
    if (!o.is_object() || !o.contains("object") || !o["object"].is_string())
      return fail(problem, where + ".object", "missing or not a string");
    robot::ObjectTruth t;
    t.object = o["object"].get<std::string>();
    std::string p;
    if (!o.contains("cMo")) return fail(problem, where + ".cMo", "missing");
    if (!pose(o, "cMo", &t.cMo, &p)) return fail(problem, where, p);
    if (o.contains("rMo")) {
      Pose r;
      if (!pose(o, "rMo", &r, &p)) return fail(problem, where, p);
      t.rMo = r;
    }
    truth->push_back(t);
  }
  return true;
}

Json robotStateToJson(const robot::RobotState& s) {
  return {{"stamp", s.stamp},
          {"wMb_odom", poseJson(s.wMb_odom)},
          {"base_v_mps", s.base_v_mps},
          {"base_w_radps", s.base_w_radps},
          {"pan_rad", s.pan_rad},
          {"tilt_rad", s.tilt_rad},
          {"pan_radps", s.pan_radps},
          {"tilt_radps", s.tilt_radps},
          {"arm_q_rad", vectorJson(s.arm_q_rad)},
          {"arm_qdot_radps", vectorJson(s.arm_qdot_radps)},
          {"gripper", robot::toString(s.gripper)},
          {"held_object", s.held_object},
          {"watchdog_tripped", s.watchdog_tripped}};
}

bool robotStateFromJson(const Json& j, robot::RobotState* s, std::string* problem) {
  *s = {};
  if (!j.is_object()) return fail(problem, "robot", "not an object");
  const std::pair<const char*, double*> scalars[] = {
      {"stamp", &s->stamp},         {"base_v_mps", &s->base_v_mps},
      {"base_w_radps", &s->base_w_radps}, {"pan_rad", &s->pan_rad},
      {"tilt_rad", &s->tilt_rad},   {"pan_radps", &s->pan_radps},
      {"tilt_radps", &s->tilt_radps}};
  for (const auto& [key, out] : scalars)
    if (!number(j, key, out, problem, true)) return false;
  if (!j.contains("wMb_odom")) return fail(problem, "wMb_odom", "missing");
  if (!pose(j, "wMb_odom", &s->wMb_odom, problem) ||
      !numbers(j, "arm_q_rad", &s->arm_q_rad, problem) ||
      !numbers(j, "arm_qdot_radps", &s->arm_qdot_radps, problem))
    return false;
  if (!j.contains("gripper") || !j["gripper"].is_string())
    return fail(problem, "gripper", "missing or not a string");
  const std::string g = j["gripper"].get<std::string>();
  bool known = false;
  for (auto p : {robot::GripperPhase::kOpen, robot::GripperPhase::kClosing,
                 robot::GripperPhase::kClosedEmpty, robot::GripperPhase::kHolding,
                 robot::GripperPhase::kOpening})
    if (g == robot::toString(p)) s->gripper = p, known = true;
  if (!known) return fail(problem, "gripper", "unknown phase '" + g + "'");
  if (j.contains("held_object") && j["held_object"].is_string())
    s->held_object = j["held_object"].get<std::string>();
  if (j.contains("watchdog_tripped") && j["watchdog_tripped"].is_boolean())
    s->watchdog_tripped = j["watchdog_tripped"].get<bool>();
  return true;
}

}  // namespace refgrasp::files
