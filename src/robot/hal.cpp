#include "robot/hal.h"

#include <stdexcept>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace refgrasp::robot {

const char* toString(ReturnType r) {
  switch (r) {
    case ReturnType::kOk: return "ok";
    case ReturnType::kError: return "error";
    case ReturnType::kDeactivate: return "deactivate";
  }
  return "?";
}

const char* toString(GripperPhase p) {
  switch (p) {
    case GripperPhase::kOpen: return "open";
    case GripperPhase::kClosing: return "closing";
    case GripperPhase::kClosedEmpty: return "closed_empty";
    case GripperPhase::kHolding: return "holding";
    case GripperPhase::kOpening: return "opening";
  }
  return "?";
}

RobotCommand RobotCommand::zero(int arm_dof) {
  RobotCommand c;
  c.arm_qdot_radps = Eigen::VectorXd::Zero(arm_dof);
  return c;
}

bool RobotCommand::isFinite() const {
  return std::isfinite(base_v_mps) && std::isfinite(base_w_radps) && std::isfinite(pan) &&
         std::isfinite(tilt) && arm_qdot_radps.allFinite();
}

std::string RobotState::csvHeader(int dof) {
  std::ostringstream s;
  s << "time_s,odom_x_m,odom_y_m,odom_theta_rad,v_mps,w_radps,pan_rad,tilt_rad,pan_radps,"
       "tilt_radps";
  for (int i = 0; i < dof; ++i) s << ",q" << i << "_rad";
  for (int i = 0; i < dof; ++i) s << ",qdot" << i << "_radps";
  s << ",gripper,held_object,watchdog_tripped";
  return s.str();
}

std::string RobotState::csvRow() const {
  std::ostringstream s;
  s.precision(9);
  const double theta = std::atan2(wMb_odom.R(1, 0), wMb_odom.R(0, 0));
  s << stamp << ',' << wMb_odom.t.x() << ',' << wMb_odom.t.y() << ',' << theta << ','
    << base_v_mps << ',' << base_w_radps << ',' << pan_rad << ',' << tilt_rad << ',' << pan_radps
    << ',' << tilt_radps;
  for (Eigen::Index i = 0; i < arm_q_rad.size(); ++i) s << ',' << arm_q_rad[i];
  for (Eigen::Index i = 0; i < arm_qdot_radps.size(); ++i) s << ',' << arm_qdot_radps[i];
  s << ',' << toString(gripper) << ',' << held_object << ',' << (watchdog_tripped ? 1 : 0);
  return s.str();
}

// ---- component views ---------------------------------------------------------------------------

void Base::setVelocity(double v, double w) {
  clipBaseVelocity(r_->model_.base, &v, &w);
  r_->pending_.base_v_mps = v;
  r_->pending_.base_w_radps = w;
  r_->commanded();
}
Pose Base::wMb() const { return r_->state_.wMb_odom; }
const BaseModel& Base::model() const { return r_->model_.base; }

void Head::setVelocity(double pan_rate, double tilt_rate) {
  const HeadModel& h = r_->model_.head;
  r_->pending_.head_mode = HeadMode::kVelocity;
  r_->pending_.pan = std::clamp(pan_rate, -h.pan.max_speed_radps, h.pan.max_speed_radps);
  r_->pending_.tilt = std::clamp(tilt_rate, -h.tilt.max_speed_radps, h.tilt.max_speed_radps);
  r_->commanded();
}
void Head::setPosition(double pan, double tilt) {
  const HeadModel& h = r_->model_.head;
  r_->pending_.head_mode = HeadMode::kPosition;
  r_->pending_.pan = std::clamp(pan, h.pan.min_rad, h.pan.max_rad);
  r_->pending_.tilt = std::clamp(tilt, h.tilt.min_rad, h.tilt.max_rad);
  r_->commanded();
}
double Head::pan() const { return r_->state_.pan_rad; }
double Head::tilt() const { return r_->state_.tilt_rad; }
Pose Head::bMc() const { return headCameraPose(r_->model_.head, pan(), tilt()); }
const HeadModel& Head::model() const { return r_->model_.head; }

void Arm::setVelocity(ArmFrame frame, const Twist& v) {
  r_->arm_twist_ = std::make_pair(frame, v);
  r_->commanded();
}
void Arm::setJointVelocity(const Eigen::VectorXd& qdot) {
  r_->arm_twist_.reset();
  if (qdot.size() != r_->kin_.dof()) {
    // A wrong-sized command is a bug in the caller; it becomes a non-finite command -> kError.
    r_->pending_.arm_qdot_radps.setConstant(std::nan(""));
  } else {
    r_->pending_.arm_qdot_radps = qdot;
  }
  r_->commanded();
}
const Eigen::VectorXd& Arm::q() const { return r_->state_.arm_q_rad; }
Pose Arm::bMe() const { return r_->kin_.forward(q()); }
const ArmKinematics& Arm::kinematics() const { return r_->kin_; }

void Gripper::open() {
  r_->pending_.gripper = GripperCommand::kOpen;
  r_->commanded();
}
void Gripper::close() {
  r_->pending_.gripper = GripperCommand::kClose;
  r_->commanded();
}
GripperPhase Gripper::phase() const { return r_->state_.gripper; }

const StereoRig& StereoCamera::rig() const { return r_->cam_->rig(); }
const Pose& StereoCamera::tMc() const { return r_->model_.head.tMc; }
Pose StereoCamera::bMc() const { return r_->head_.bMc(); }
ReturnType StereoCamera::grab(Seconds time, std::optional<StereoFrame>* frame) {
  frame->reset();
  if (r_->lifecycle_ != Lifecycle::kActive) return ReturnType::kError;
  const ReturnType res = r_->cam_->grab(time, frame);
  if (res != ReturnType::kOk) {
    frame->reset();
    r_->stop();
    return res;
  }
  if (*frame) {
    CaptureState& c = (*frame)->capture;
    const CaptureState known = r_->captureAt((*frame)->stamp);
    if (!c.head) c.head = known.head;
    if (!c.wMb_odom) c.wMb_odom = known.wMb_odom;
    if (!c.bMc) c.bMc = headCameraPose(r_->model_.head, c.head->pan_rad, c.head->tilt_rad);
  }
  return ReturnType::kOk;
}

// ---- Robot -------------------------------------------------------------------------------------

Robot::Robot(const EnonModel& model, std::unique_ptr<RobotHardware> hardware,
             std::unique_ptr<StereoSource> camera)
    : model_(model),
      kin_(model.arm),
      hw_(std::move(hardware)),
      cam_(std::move(camera)),
      watchdog_(model.watchdog_period_s) {
  model_.check();
  pending_ = RobotCommand::zero(kin_.dof());
  sent_ = pending_;
  state_.arm_q_rad = Eigen::VectorXd::Zero(kin_.dof());
  state_.arm_qdot_radps = Eigen::VectorXd::Zero(kin_.dof());
}

Robot::~Robot() {
  if (lifecycle_ == Lifecycle::kActive) deactivate();
}

void Robot::replaceCamera(std::unique_ptr<StereoSource> camera) {
  if (!camera) throw std::invalid_argument("Robot::replaceCamera: no camera");
  if (lifecycle_ != Lifecycle::kUnconfigured)
    throw std::logic_error("Robot::replaceCamera: the robot is already configured");
  cam_ = std::move(camera);
}

ReturnType Robot::configure() {
  if (lifecycle_ != Lifecycle::kUnconfigured) return ReturnType::kError;
  const ReturnType r = hw_->configure();
  if (r == ReturnType::kOk) lifecycle_ = Lifecycle::kInactive;
  return r;
}

ReturnType Robot::activate() {
  if (lifecycle_ != Lifecycle::kInactive) return ReturnType::kError;
  const ReturnType r = hw_->activate();
  if (r != ReturnType::kOk) return r;
  lifecycle_ = Lifecycle::kActive;
  watchdog_.reset();
  history_.clear();
  pending_ = RobotCommand::zero(kin_.dof());
  arm_twist_.reset();
  fresh_ = false;
  return ReturnType::kOk;
}

ReturnType Robot::deactivate() {
  if (lifecycle_ != Lifecycle::kActive) return ReturnType::kError;
  stop();
  lifecycle_ = Lifecycle::kInactive;
  return hw_->deactivate();
}

void Robot::stop() {
  pending_ = RobotCommand::zero(kin_.dof());
  arm_twist_.reset();
  fresh_ = false;
  sent_ = pending_;
  if (lifecycle_ == Lifecycle::kActive)
    hw_->write(last_time_, last_period_, sent_, model_.watchdog_period_s);
}

ReturnType Robot::read(Seconds time, Seconds period) {
  if (lifecycle_ != Lifecycle::kActive) return ReturnType::kError;
  last_time_ = time;
  last_period_ = period;
  const bool tripped = state_.watchdog_tripped;
  const ReturnType r = hw_->read(time, period, &state_);
  state_.watchdog_tripped = tripped;
  if (r != ReturnType::kOk) {
    stop();
    return r;
  }
  if (!history_.empty() && history_.back().t >= time) history_.clear();  // time went back: restart
  history_.push_back({time, state_.wMb_odom, state_.pan_rad, state_.tilt_rad});
  while (history_.size() > 2 && history_.front().t < time - 2.0) history_.pop_front();
  // No write() for a while: the layer still zeroes every actuator.
  if (!fresh_ && watchdog_.expired(time) && !state_.watchdog_tripped) {
    state_.watchdog_tripped = true;
    stop();
  }
  return ReturnType::kOk;
}

CaptureState Robot::captureAt(Seconds t) const {
  CaptureState c;
  Sample x{t, state_.wMb_odom, state_.pan_rad, state_.tilt_rad};
  if (!history_.empty()) {
    if (t <= history_.front().t) {
      x = history_.front();
    } else if (t >= history_.back().t) {
      x = history_.back();
    } else {
      const auto b = std::lower_bound(history_.begin(), history_.end(), t,
                                      [](const Sample& s, Seconds v) { return s.t < v; });
      const auto a = b - 1;
      const double s = (t - a->t) / (b->t - a->t);
      x.wMb_odom = interpolate(a->wMb_odom, b->wMb_odom, s);
      x.pan = (1 - s) * a->pan + s * b->pan;
      x.tilt = (1 - s) * a->tilt + s * b->tilt;
    }
  }
  c.head = HeadJoints{x.pan, x.tilt};
  c.wMb_odom = x.wMb_odom;
  return c;
}

ReturnType Robot::write(Seconds time, Seconds period) {
  if (lifecycle_ != Lifecycle::kActive) return ReturnType::kError;
  last_time_ = time;
  last_period_ = period;
  if (fresh_) {
    watchdog_.feed(time);
    fresh_ = false;
    state_.watchdog_tripped = false;
  }
  RobotCommand cmd = pending_;
  pending_.gripper = GripperCommand::kNone;  // one-shot
  if (watchdog_.expired(time)) {
    state_.watchdog_tripped = true;
    const GripperCommand g = cmd.gripper;
    cmd = RobotCommand::zero(kin_.dof());
    cmd.gripper = g;
    arm_twist_.reset();
    pending_ = RobotCommand::zero(kin_.dof());
  } else if (arm_twist_) {
    const auto& [frame, twist] = *arm_twist_;
    const Pose bMe = kin_.forward(state_.arm_q_rad);
    const Twist bVe = frame == ArmFrame::kBase ? twist : rotateTwist(bMe.R, twist);
    const Eigen::VectorXd qdot =
        dampedLeastSquares(kin_.jacobian(state_.arm_q_rad), bVe.vector(), model_.arm.dls_damping);
    cmd.arm_qdot_radps = qdot;
  }
  if (!cmd.isFinite()) {
    stop();
    return ReturnType::kError;
  }
  cmd.arm_qdot_radps = limitJointVelocity(model_.arm, state_.arm_q_rad, cmd.arm_qdot_radps,
                                          period > 0 ? period : model_.control_period_s);
  sent_ = cmd;
  // The device drops the command itself at the watchdog deadline, even if write() stops coming.
  const Seconds valid_for = std::max(0.0, watchdog_.deadline() - time);
  const ReturnType r = hw_->write(time, period, cmd, valid_for);
  if (r != ReturnType::kOk) {
    stop();
    return r;
  }
  return ReturnType::kOk;
}

}  // namespace refgrasp::robot
