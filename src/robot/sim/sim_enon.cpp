#include "robot/sim/sim_enon.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/error.h"

namespace refgrasp::sim {

using robot::GripperCommand;
using robot::GripperPhase;
using robot::HeadMode;
using robot::ReturnType;

namespace {

// Event times closer than this are the same instant (avoids zero-length integration steps).
constexpr double kTimeEps = 1e-12;
// Collision checks along an integration step: no point of the robot moves more than this between two.
constexpr double kMaxMotionPerCheck = 0.002;
// A held object heavier than the payload slips once the hand has moved its grasp frame this far.
constexpr double kSlipDistance = 0.005;
constexpr double kSlipAngle = 0.05;

const char* const kCapsuleNames[] = {"upper_arm", "forearm", "palm", "finger_x+", "finger_x-"};
constexpr int kFirstFinger = 3;

// Calls f with the solid in the world, as an OrientedBox or an OrientedCylinder.
template <class F>
void withShape(const Solid& sd, const Pose& wMo, F&& f) {
  if (sd.cylinder) {
    f(OrientedCylinder{wMo * sd.oMs, sd.half_m.x(), sd.half_m.z()});
  } else {
    f(OrientedBox{wMo * sd.oMs, sd.half_m});
  }
}

uint64_t splitmix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

}  // namespace

// ---- camera ------------------------------------------------------------------------------------

class SimStereoCamera : public robot::StereoSource {
 public:
  explicit SimStereoCamera(SimEnon* sim)
      : sim_(sim),
        camera_(sim->model_.head.rig, sim->scenario_.camera,
                splitmix64(sim->scenario_.seed ^ 0xCA3Eull), sim->scenario_.exposure_s) {}

  const StereoRig& rig() const override { return sim_->model_.head.rig; }

  ReturnType grab(Seconds time, std::optional<robot::StereoFrame>* frame) override {
    frame->reset();
    if (!sim_->active_) return ReturnType::kError;
    const double fps = sim_->model_.head.frame_rate_hz;
    // Newest capture whose delivery (capture + frame delay) is due by `time`.
    const long k = static_cast<long>(
        std::floor((time - sim_->scenario_.faults.frame_delay_s) * fps + 1e-9));
    if (k < 0 || k <= last_index_) return ReturnType::kOk;
    last_index_ = k;
    if (sim_->frameDropped(k)) return ReturnType::kOk;
    const Seconds t = static_cast<double>(k) / fps;
    const SimEnon::Snapshot now = sim_->snapshotAt(t);
    // Camera velocity over the exposure, from the true poses half an exposure either side.
    const double half = 0.5 * std::max(sim_->scenario_.exposure_s, 1e-3);
    const SimEnon::Snapshot a = sim_->snapshotAt(t - half), b = sim_->snapshotAt(t + half);
    const Pose aMb = a.wMl.inverse() * b.wMl;
    Twist lVl;
    lVl.v = aMb.t / (2 * half);
    lVl.w = aMb.rotationVector() / (2 * half);
    World world = sim_->world_;
    for (size_t i = 0; i < world.objects.size(); ++i) world.objects[i].wMo = now.wMo[i];
    sim_->last_frame_ = sim_->render_images_ ? camera_.render(world, now.wMl, lVl, t)
                                             : camera_.poses(world, now.wMl, t);
    robot::StereoFrame out;
    out.left = sim_->last_frame_->left;
    out.right = sim_->last_frame_->right;
    out.stamp = t;
    out.index = k;
    out.capture.head = robot::HeadJoints{now.pan, now.tilt};
    // Ground truth of the objects a detector could look for (those with a definition).
    for (size_t i = 0; i < world.objects.size(); ++i)
      if (!world.objects[i].definition.empty())
        out.truth.push_back({world.objects[i].name, sim_->last_frame_->left_cMo[i],
                             sim_->last_frame_->right_cMo[i]});
    *frame = std::move(out);
    return ReturnType::kOk;
  }

 private:
  SimEnon* sim_;
  SyntheticStereoCamera camera_;
  long last_index_ = -1;
};

// ---- SimEnon -----------------------------------------------------------------------------------

SimEnon::SimEnon(const robot::EnonModel& model, const Scenario& scenario)
    : model_(model),
      kin_(model.arm),
      scenario_(scenario),
      world_(scenario.world),
      odom_rng_(splitmix64(scenario.seed ^ 0x0D0Dull)) {
  model_.check();
  const Faults& f = scenario_.faults;
  if (!f.stuck_joint.empty()) {
    std::vector<std::string> names = {"head.pan", "head.tilt"};
    for (const auto& j : model_.arm.joints) names.push_back("arm." + j.name);
    if (std::find(names.begin(), names.end(), f.stuck_joint) == names.end()) {
      std::string known;
      for (const auto& n : names) known += (known.empty() ? "" : ", ") + n;
      throw ConfigError(scenario_.path, "faults.stuck_joint",
                        "unknown joint '" + f.stuck_joint + "' (known: " + known + ")");
    }
  }
  for (int i = 0; i < kin_.dof(); ++i)
    if (f.stuck_joint == "arm." + model_.arm.joints[static_cast<size_t>(i)].name) stuck_arm_joint_ = i;
  base_true_ = {scenario_.start_x_m, scenario_.start_y_m, scenario_.start_theta_rad};
  base_odom_ = base_true_;
  q_ = Eigen::VectorXd::Zero(kin_.dof());
  for (int i = 0; i < kin_.dof(); ++i) {
    const auto& l = model_.arm.joints[static_cast<size_t>(i)].limits;
    q_[i] = std::clamp(0.0, l.min_rad, l.max_rad);
  }
  qdot_ = Eigen::VectorXd::Zero(kin_.dof());
  active_cmd_ = robot::RobotCommand::zero(kin_.dof());
  const robot::GripperModel& g = model_.gripper;
  gap_from_ = gap_to_ = g.open_width_m;
  // Any point beyond a joint is within the sum of the link lengths, the tool and the hand of its axis.
  for (const auto& j : model_.arm.joints) arm_lever_m_ += std::abs(j.a_m) + std::abs(j.d_m);
  arm_lever_m_ += model_.arm.nMe.t.norm() + g.palm_offset_m + g.finger_length_m + g.open_width_m / 2 +
                  2 * g.finger_radius_m + g.palm_radius_m +
                  std::max(model_.arm.upper_arm.radius_m, model_.arm.forearm.radius_m);
  pushSnapshot();
}

SimEnon::~SimEnon() = default;

ReturnType SimEnon::configure() {
  configured_ = true;
  return ReturnType::kOk;
}

ReturnType SimEnon::activate() {
  if (!configured_) {
    last_error_ = "sim: activate() before configure()";
    return ReturnType::kError;
  }
  active_ = true;
  checkNow();
  return ReturnType::kOk;
}

ReturnType SimEnon::deactivate() {
  active_ = false;
  queue_.clear();
  active_cmd_ = robot::RobotCommand::zero(kin_.dof());
  v_ = w_ = pan_rate_ = tilt_rate_ = 0;
  qdot_.setZero();
  return ReturnType::kOk;
}

std::unique_ptr<robot::StereoSource> SimEnon::makeCamera() {
  return std::make_unique<SimStereoCamera>(this);
}

Pose SimEnon::wMc() const { return wMb() * robot::headCameraPose(model_.head, pan_, tilt_); }
Pose SimEnon::wMe() const { return wMb() * kin_.forward(q_); }

bool SimEnon::frameDropped(long index) const {
  const double p = scenario_.faults.frame_drop_probability;
  if (p <= 0) return false;
  const uint64_t h = splitmix64(scenario_.seed ^ splitmix64(static_cast<uint64_t>(index)));
  return static_cast<double>(h >> 11) * 0x1.0p-53 < p;
}

void SimEnon::setJointPositions(const Eigen::VectorXd& q) {
  if (q.size() != kin_.dof()) return;
  for (int i = 0; i < kin_.dof(); ++i) {
    const auto& l = model_.arm.joints[static_cast<size_t>(i)].limits;
    q_[i] = std::clamp(q[i], l.min_rad, l.max_rad);
  }
  if (held_ >= 0) world_.objects[static_cast<size_t>(held_)].wMo = wMe() * eMo_held_;
  checkNow();
  pushSnapshot();
}

bool SimEnon::stuck(const std::string& joint) const {
  const Faults& f = scenario_.faults;
  return f.stuck_joint == joint && time_ >= f.stuck_after_s - kTimeEps;
}

ReturnType SimEnon::write(Seconds time, Seconds /*period*/, const robot::RobotCommand& cmd,
                          Seconds valid_for_s) {
  if (collided()) {
    last_error_ = collisions_.front().message();
    return ReturnType::kError;
  }
  if (!active_) {
    last_error_ = "sim: write() while not active";
    return ReturnType::kError;
  }
  if (!cmd.isFinite() || cmd.arm_qdot_radps.size() != kin_.dof()) {
    last_error_ = "sim: command not finite or not one rate per arm joint (" +
                  std::to_string(cmd.arm_qdot_radps.size()) + " for " + std::to_string(kin_.dof()) + ")";
    return ReturnType::kError;
  }
  const Seconds due = time + scenario_.faults.command_latency_s;
  // Commands reach the controller in order; a later write never overtakes an earlier one.
  const Seconds last_due = queue_.empty() ? -1e300 : queue_.back().due;
  queue_.push_back({std::max(due, last_due), cmd, valid_for_s});
  if (scenario_.faults.command_latency_s <= 0) applyDue(time_);
  return ReturnType::kOk;
}

void SimEnon::applyDue(Seconds now) {
  if (collided()) return;  // emergency stop: nothing is taken any more
  while (!queue_.empty() && queue_.front().due <= now + kTimeEps) {
    const Queued q = queue_.front();
    queue_.pop_front();
    active_cmd_ = q.cmd;
    active_until_ = q.due + q.valid_for;
    const Seconds start = std::max(q.due, now);
    if (q.cmd.gripper == GripperCommand::kClose &&
        (gripper_ == GripperPhase::kOpen || gripper_ == GripperPhase::kOpening)) {
      gripper_ = GripperPhase::kClosing;
      gripper_done_ = start + model_.gripper.close_time_s;
      moveFingers(start, 0.0, model_.gripper.close_time_s);
      // The item the fingers close on: the grasp frame nearest e, within the opening.
      const Pose e = wMe();
      double best = model_.gripper.open_width_m;
      finger_exempt_ = -1;
      for (size_t i = 0; i < world_.objects.size(); ++i) {
        const SimObject& o = world_.objects[i];
        if (o.kind != ObjectKind::kItem) continue;
        const double d = translationError(e, o.wMo * o.oMg);
        if (d < best) best = d, finger_exempt_ = static_cast<int>(i);
      }
    } else if (q.cmd.gripper == GripperCommand::kOpen && gripper_ != GripperPhase::kOpen &&
               gripper_ != GripperPhase::kOpening) {
      held_ = -1;  // released where it is
      gripper_ = GripperPhase::kOpening;
      gripper_done_ = start + model_.gripper.open_time_s;
      moveFingers(start, model_.gripper.open_width_m, model_.gripper.open_time_s);
    }
  }
  if (now >= active_until_ - kTimeEps) {
    // The command timed out on the controller side: zero velocity, head and arm hold.
    const GripperCommand g = active_cmd_.gripper;
    active_cmd_ = robot::RobotCommand::zero(kin_.dof());
    active_cmd_.gripper = g;
  }
  finishGripper(now);
}

void SimEnon::finishGripper(Seconds now) {
  if (collided() || now < gripper_done_ - kTimeEps) return;
  if (gripper_ == GripperPhase::kOpening) {
    gripper_ = GripperPhase::kOpen;
    finger_exempt_ = -1;
  }
  if (gripper_ != GripperPhase::kClosing) return;
  // Closing finished: hold the nearest item whose grasp frame is within tolerance and that fits
  // between the fingers.
  const Pose e = wMe();
  const Eigen::Vector3d x_e = e.R.col(0);
  int best = -1;
  double best_dist = 0;
  for (size_t i = 0; i < world_.objects.size(); ++i) {
    const SimObject& o = world_.objects[i];
    if (o.kind != ObjectKind::kItem) continue;
    const Pose g = o.wMo * o.oMg;
    const double d = translationError(e, g);
    if (d <= model_.gripper.grasp_tolerance_m &&
        rotationError(e, g) <= model_.gripper.grasp_tolerance_rad &&
        widthAlong(o, x_e) <= model_.gripper.open_width_m && (best < 0 || d < best_dist)) {
      best = static_cast<int>(i);
      best_dist = d;
    }
  }
  held_ = best;
  if (best >= 0) {
    const SimObject& o = world_.objects[static_cast<size_t>(best)];
    eMo_held_ = e.inverse() * o.wMo;
    wMo_grasped_ = o.wMo;
    wMg_grasped_ = o.wMo * o.oMg;
    finger_exempt_ = best;
    moveFingers(now, widthAlong(o, x_e), 0);  // the fingers stopped on its sides
    gripper_ = GripperPhase::kHolding;
  } else {
    gripper_ = GripperPhase::kClosedEmpty;
  }
}

double SimEnon::widthAlong(const SimObject& o, const Eigen::Vector3d& u) const {
  if (o.solids.empty()) return 0;
  double lo = 1e300, hi = -1e300;
  for (const Solid& sd : o.solids)
    withShape(sd, o.wMo, [&](const auto& shape) {
      const double c = u.dot((o.wMo * sd.oMs).t), h = extentAlong(shape, u) / 2;
      lo = std::min(lo, c - h);
      hi = std::max(hi, c + h);
    });
  return hi - lo;
}

void SimEnon::slipIfTooHeavy() {
  if (held_ < 0) return;
  SimObject& o = world_.objects[static_cast<size_t>(held_)];
  if (o.mass_kg <= model_.gripper.max_payload_kg) return;
  const Pose g = o.wMo * o.oMg;
  if (translationError(g, wMg_grasped_) <= kSlipDistance && rotationError(g, wMg_grasped_) <= kSlipAngle)
    return;
  // Too heavy: it drops back to where it was grasped and the fingers close on nothing. They stay
  // exempt against it until the gripper is open again.
  o.wMo = wMo_grasped_;
  held_ = -1;
  gripper_ = GripperPhase::kClosedEmpty;
  moveFingers(time_, 0.0, 0);
}

double SimEnon::fingerGapAt(Seconds t) const {
  if (t >= gap_t1_) return gap_to_;
  if (t <= gap_t0_) return gap_from_;
  return gap_from_ + (gap_to_ - gap_from_) * (t - gap_t0_) / (gap_t1_ - gap_t0_);
}

void SimEnon::moveFingers(Seconds start, double to_gap, Seconds duration) {
  gap_from_ = fingerGapAt(start);
  gap_to_ = to_gap;
  gap_t0_ = start;
  gap_t1_ = start + duration;
}

// ---- collisions --------------------------------------------------------------------------------

std::string Collision::message() const {
  const double mm = depth_m * 1000;
  char buf[256];
  std::snprintf(buf, sizeof(buf), "collision at t=%.2f s: %s with %s (%.*f mm)", time, link.c_str(),
                object.c_str(), mm >= 10 ? 0 : mm >= 1 ? 1 : 2, mm);
  return buf;
}

SimEnon::Kinematic SimEnon::kinematicAfter(Seconds s) const {
  const robot::RobotCommand& c = active_cmd_;
  double v = c.base_v_mps, w = c.base_w_radps;
  robot::clipBaseVelocity(model_.base, &v, &w);
  Kinematic k{robot::integrateUnicycle(base_true_, v, w, s), q_, fingerGapAt(time_ + s)};
  for (int i = 0; i < kin_.dof(); ++i) {
    const auto& j = model_.arm.joints[static_cast<size_t>(i)];
    if (i != stuck_arm_joint_ || !stuck(scenario_.faults.stuck_joint))
      k.q[i] = robot::integrateJoint(j.limits, q_[i], c.arm_qdot_radps[i], s);
  }
  return k;
}

double SimEnon::motionBound(Seconds s) const {
  const robot::RobotCommand& c = active_cmd_;
  double v = c.base_v_mps, w = c.base_w_radps;
  robot::clipBaseVelocity(model_.base, &v, &w);
  const double reach = std::max(model_.base.body_radius_m, model_.arm.bM0.t.head<2>().norm() + arm_lever_m_);
  double speed = std::abs(v) + std::abs(w) * reach;
  for (int i = 0; i < kin_.dof(); ++i)
    speed += std::min(std::abs(c.arm_qdot_radps[i]),
                      model_.arm.joints[static_cast<size_t>(i)].limits.max_speed_radps) * arm_lever_m_;
  double motion = speed * s;
  // Fingers: each moves half the change of the gap.
  const Seconds t0 = std::max(time_, gap_t0_), t1 = std::min(time_ + s, gap_t1_);
  if (t1 > t0) motion += 0.5 * std::abs(fingerGapAt(t1) - fingerGapAt(t0));
  return motion;
}

RobotShapes SimEnon::shapesOf(const Kinematic& k) const {
  const Pose wMb = k.base.toPose();
  const std::vector<Pose> f = kin_.frames(k.q);
  const Pose e = wMb * f.back();
  const robot::GripperModel& g = model_.gripper;
  RobotShapes out;
  const auto link = [&](const robot::LinkCapsule& l) {
    return Capsule{wMb * f[static_cast<size_t>(l.from_frame)].t, wMb * f[static_cast<size_t>(l.to_frame)].t,
                   l.radius_m};
  };
  const double x = k.gap / 2 + g.finger_radius_m, back = -g.palm_offset_m,
               tip = g.finger_length_m - g.palm_offset_m;
  out.capsules = {
      {kCapsuleNames[0], link(model_.arm.upper_arm)},
      {kCapsuleNames[1], link(model_.arm.forearm)},
      {kCapsuleNames[2], {e * Eigen::Vector3d(-x, 0, back), e * Eigen::Vector3d(x, 0, back), g.palm_radius_m}},
      {kCapsuleNames[3], {e * Eigen::Vector3d(x, 0, back), e * Eigen::Vector3d(x, 0, tip), g.finger_radius_m}},
      {kCapsuleNames[4], {e * Eigen::Vector3d(-x, 0, back), e * Eigen::Vector3d(-x, 0, tip), g.finger_radius_m}},
  };
  out.base = {Eigen::Vector2d(k.base.x_m, k.base.y_m), 0.0, model_.base.body_height_m,
              model_.base.body_radius_m};
  return out;
}

RobotShapes SimEnon::shapes() const { return shapesOf({base_true_, q_, fingerGapAt(time_)}); }

template <class F>
void SimEnon::visitPairs(const RobotShapes& sh, const double& below, F&& f) const {
  for (size_t i = 0; i < world_.objects.size(); ++i) {
    const SimObject& o = world_.objects[i];
    if (static_cast<int>(i) == held_) continue;
    for (const Solid& sd : o.solids)
      withShape(sd, o.wMo, [&](const auto& solid) {
        for (size_t c = 0; c < sh.capsules.size(); ++c) {
          if (static_cast<int>(c) >= kFirstFinger && static_cast<int>(i) == finger_exempt_) continue;
          const Capsule& cap = sh.capsules[c].second;
          // Broad phase: a lower bound from the capsule's bounding sphere.
          const double bound = 0.5 * (cap.b - cap.a).norm() + cap.radius_m;
          if (signedDistance(solid, Eigen::Vector3d(0.5 * (cap.a + cap.b))) - bound >= below) continue;
          f(sh.capsules[c].first, o, signedDistance(solid, cap));
        }
        if (o.kind != ObjectKind::kFloor) f("base", o, signedDistance(solid, sh.base));
      });
  }
}

std::vector<Collision> SimEnon::contacts(const Kinematic& k, Seconds t) const {
  std::vector<Collision> found;
  visitPairs(shapesOf(k), 0.0, [&](const std::string& link, const SimObject& o, double d) {
    if (d >= 0) return;
    for (Collision& c : found)
      if (c.link == link && c.object == o.name) {
        c.depth_m = std::max(c.depth_m, -d);
        return;
      }
    found.push_back({t, link, o.name, -d});
  });
  std::sort(found.begin(), found.end(),
            [](const Collision& a, const Collision& b) { return a.depth_m > b.depth_m; });
  return found;
}

Proximity SimEnon::nearest() const {
  Proximity p;
  visitPairs(shapes(), p.distance_m, [&](const std::string& link, const SimObject& o, double d) {
    if (d < p.distance_m) p = {link, o.name, d};
  });
  return p;
}

void SimEnon::checkNow() {
  if (collided()) return;
  latch(contacts({base_true_, q_, fingerGapAt(time_)}, time_));
}

void SimEnon::latch(std::vector<Collision> found) {
  if (found.empty() || collided()) return;
  collisions_ = std::move(found);
  last_error_ = collisions_.front().message();
  // Emergency stop: every actuator, now and for good.
  queue_.clear();
  active_cmd_ = robot::RobotCommand::zero(kin_.dof());
  active_until_ = time_;
  v_ = w_ = pan_rate_ = tilt_rate_ = 0;
  qdot_.setZero();
}

std::string SimEnon::lastError() const { return last_error_; }

int SimEnon::targetObject() const {
  for (size_t i = 0; i < world_.objects.size(); ++i)
    if (world_.objects[i].is_target) return static_cast<int>(i);
  return -1;
}

std::optional<GraspError> SimEnon::graspError(int object) const {
  if (object < 0 || object >= static_cast<int>(world_.objects.size())) return std::nullopt;
  const SimObject& o = world_.objects[static_cast<size_t>(object)];
  const Pose e = wMe(), g = o.wMo * o.oMg;
  return GraspError{translationError(e, g), rotationError(e, g), e.inverse() * g};
}

Eigen::VectorXd SimEnon::jointLimitMargins() const {
  Eigen::VectorXd m(kin_.dof());
  for (int i = 0; i < kin_.dof(); ++i) {
    const auto& l = model_.arm.joints[static_cast<size_t>(i)].limits;
    m[i] = std::min(q_[i] - l.min_rad, l.max_rad - q_[i]);
  }
  return m;
}

void SimEnon::integrate(Seconds full_dt) {
  if (full_dt <= 0) return;
  if (collided()) return;  // stopped where the contact was found
  // Collision checks along the step, at sub-steps short enough that nothing tunnels; the motion
  // ends at the first contact. The last sub-step is the full step (the same closed form).
  std::vector<Collision> found;
  Seconds dt = full_dt;
  const double n_checks = std::ceil(motionBound(full_dt) / kMaxMotionPerCheck);
  const int n = static_cast<int>(std::clamp(n_checks, 1.0, 1e5));
  for (int k = 1; k <= n && found.empty(); ++k) {
    const Seconds s = k == n ? full_dt : full_dt * k / n;
    found = contacts(kinematicAfter(s), time_ + s);
    if (!found.empty()) dt = s;
  }
  const robot::RobotCommand& c = active_cmd_;
  // Base: exact arc; odometry integrates a noisy copy of the same increment.
  double v = c.base_v_mps, w = c.base_w_radps;
  robot::clipBaseVelocity(model_.base, &v, &w);
  v_ = v;
  w_ = w;
  base_true_ = robot::integrateUnicycle(base_true_, v, w, dt);
  const Faults& f = scenario_.faults;
  double ds = v * dt, dth = w * dt;
  if (f.odom_noise_m_per_m > 0 || f.odom_noise_rad_per_rad > 0) {
    std::normal_distribution<double> n01(0.0, 1.0);
    ds += f.odom_noise_m_per_m * std::sqrt(std::abs(ds)) * n01(odom_rng_);
    dth += f.odom_noise_rad_per_rad * std::sqrt(std::abs(dth)) * n01(odom_rng_);
  }
  base_odom_ = robot::integrateUnicycle(base_odom_, ds / dt, dth / dt, dt);

  // Head.
  const double pan0 = pan_, tilt0 = tilt_;
  const auto& h = model_.head;
  if (!stuck("head.pan"))
    pan_ = c.head_mode == HeadMode::kPosition ? robot::moveJointTowards(h.pan, pan_, c.pan, dt)
                                              : robot::integrateJoint(h.pan, pan_, c.pan, dt);
  if (!stuck("head.tilt"))
    tilt_ = c.head_mode == HeadMode::kPosition
                ? robot::moveJointTowards(h.tilt, tilt_, c.tilt, dt)
                : robot::integrateJoint(h.tilt, tilt_, c.tilt, dt);
  pan_rate_ = (pan_ - pan0) / dt;
  tilt_rate_ = (tilt_ - tilt0) / dt;

  // Arm.
  for (int i = 0; i < kin_.dof(); ++i) {
    const auto& j = model_.arm.joints[static_cast<size_t>(i)];
    const double q0 = q_[i];
    if (i != stuck_arm_joint_ || !stuck(scenario_.faults.stuck_joint))
      q_[i] = robot::integrateJoint(j.limits, q_[i], c.arm_qdot_radps[i], dt);
    qdot_[i] = (q_[i] - q0) / dt;
  }
  if (held_ >= 0) world_.objects[static_cast<size_t>(held_)].wMo = wMe() * eMo_held_;
  slipIfTooHeavy();
  latch(std::move(found));
}

ReturnType SimEnon::read(Seconds time, Seconds /*period*/, robot::RobotState* state) {
  if (!configured_) {
    last_error_ = "sim: read() before configure()";
    return ReturnType::kError;
  }
  if (active_) {
    applyDue(time_);
    while (time_ < time - kTimeEps) {
      Seconds next = time;
      if (!queue_.empty()) next = std::min(next, queue_.front().due);
      if (active_until_ > time_ + kTimeEps) next = std::min(next, active_until_);
      const Faults& f = scenario_.faults;
      if (!f.stuck_joint.empty() && f.stuck_after_s > time_ + kTimeEps)
        next = std::min(next, f.stuck_after_s);
      if ((gripper_ == GripperPhase::kClosing || gripper_ == GripperPhase::kOpening) &&
          gripper_done_ > time_ + kTimeEps)
        next = std::min(next, gripper_done_);
      integrate(next - time_);
      time_ = next;
      applyDue(time_);
    }
    if (time > time_) time_ = time;
  }
  pushSnapshot();

  state->stamp = time_;
  state->wMb_odom = base_odom_.toPose();
  state->base_v_mps = v_;
  state->base_w_radps = w_;
  state->pan_rad = pan_;
  state->tilt_rad = tilt_;
  state->pan_radps = pan_rate_;
  state->tilt_radps = tilt_rate_;
  state->arm_q_rad = q_;
  state->arm_qdot_radps = qdot_;
  state->gripper = gripper_;
  state->held_object = held_ >= 0 ? world_.objects[static_cast<size_t>(held_)].name : "";
  if (collided()) {
    last_error_ = collisions_.front().message();
    return ReturnType::kError;
  }
  return ReturnType::kOk;
}

void SimEnon::pushSnapshot() {
  Snapshot s;
  s.t = time_;
  s.wMl = wMc();
  s.pan = pan_;
  s.tilt = tilt_;
  for (const auto& o : world_.objects) s.wMo.push_back(o.wMo);
  if (!history_.empty() && history_.back().t >= s.t - kTimeEps) history_.pop_back();
  history_.push_back(std::move(s));
  // Enough history for the frame delay and the exposure.
  const double keep = 1.0 + scenario_.faults.frame_delay_s + scenario_.exposure_s;
  while (history_.size() > 2 && history_.front().t < time_ - keep) history_.pop_front();
}

SimEnon::Snapshot SimEnon::snapshotAt(Seconds t) const {
  if (t <= history_.front().t) return history_.front();
  if (t >= history_.back().t) return history_.back();
  const auto it = std::lower_bound(history_.begin(), history_.end(), t,
                                   [](const Snapshot& s, Seconds x) { return s.t < x; });
  const Snapshot& b = *it;
  const Snapshot& a = *(it - 1);
  const double s = (t - a.t) / (b.t - a.t);
  Snapshot out;
  out.t = t;
  out.wMl = interpolate(a.wMl, b.wMl, s);
  out.pan = (1 - s) * a.pan + s * b.pan;
  out.tilt = (1 - s) * a.tilt + s * b.tilt;
  for (size_t i = 0; i < a.wMo.size(); ++i) out.wMo.push_back(interpolate(a.wMo[i], b.wMo[i], s));
  return out;
}

std::unique_ptr<robot::Robot> makeSimRobot(const robot::EnonModel& model, const Scenario& scenario) {
  auto hw = std::make_unique<SimEnon>(model, scenario);
  auto cam = hw->makeCamera();
  return std::make_unique<robot::Robot>(model, std::move(hw), std::move(cam));
}

namespace {

class StandaloneSimCamera : public robot::StereoSource {
 public:
  StandaloneSimCamera(const robot::EnonModel& model, const Scenario& scenario)
      : sim_(model, scenario),
        period_(1.0 / model.head.frame_rate_hz),
        delay_(scenario.faults.frame_delay_s) {
    sim_.configure();
    sim_.activate();
    camera_ = sim_.makeCamera();
  }
  const StereoRig& rig() const override { return camera_->rig(); }
  ReturnType grab(Seconds, std::optional<robot::StereoFrame>* frame) override {
    frame->reset();
    // Frame k is captured at k * period and delivered frame_delay_s later.
    const Seconds t = static_cast<double>(next_++) * period_ + delay_;
    robot::RobotState state;
    if (sim_.read(t, next_ == 1 ? 0.0 : period_, &state) != ReturnType::kOk) return ReturnType::kError;
    return camera_->grab(t + 1e-9, frame);
  }

 private:
  SimEnon sim_;
  std::unique_ptr<robot::StereoSource> camera_;
  Seconds period_, delay_;
  int64_t next_ = 0;
};

}  // namespace

std::unique_ptr<robot::StereoSource> makeStandaloneSimCamera(const robot::EnonModel& model,
                                                             const Scenario& scenario) {
  return std::make_unique<StandaloneSimCamera>(model, scenario);
}

void registerSimBackend() {
  robot::registerBackend("sim", [](const robot::EnonModel& model, const robot::BackendConfig& c) {
    const auto it = c.params.find("scenario");
    if (it == c.params.end() || it->second.empty())
      throw ConfigError(c.source.empty() ? model.path : c.source, "scenario",
                        "backend 'sim' needs a scenario file");
    const std::string source = c.source.empty() ? model.path : c.source;
    bool render = true;
    if (const auto r = c.params.find("render"); r != c.params.end()) {
      if (r->second != "true" && r->second != "false")
        throw ConfigError(source, "render", "expected true or false, got '" + r->second + "'");
      render = r->second == "true";
    }
    auto robot = makeSimRobot(model, loadScenario(it->second));
    dynamic_cast<SimEnon&>(robot->hardware()).setRenderImages(render);
    return robot;
  });
}

}  // namespace refgrasp::sim
