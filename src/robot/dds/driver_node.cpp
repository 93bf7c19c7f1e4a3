#include "robot/dds/driver_node.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <mutex>
#include <thread>

#include "core/error.h"
#include "robot/dds/convert.h"
#include "robot/dds/robot_topics.h"
#include "robot/dds/transport.h"

namespace refgrasp::dds {

using robot::ReturnType;

void DriverNodeOptions::check() const {
  checkDomainAndNamespace(domain, ns, "DriverNodeOptions");
  refgrasp::check(std::isfinite(camera_rate_hz) && camera_rate_hz >= 0,
                  "DriverNodeOptions.camera_rate_hz", "must be >= 0");
}

struct RobotDriverNode::Impl {
  Impl(const robot::EnonModel& m, robot::RobotHardware& h, robot::StereoSource* c,
       const DriverNodeOptions& o)
      : model(m), hw(h), cam(c), opt((o.check(), o)), topics(o.ns), arm_names(armJointNames(m)),
        pp(o.domain),
        cmd_vel(pp, ddsTopicName(topics.cmd_vel), QosProfile::reliable(1)),
        head(pp, ddsTopicName(topics.head_command), QosProfile::reliable(1)),
        arm(pp, ddsTopicName(topics.arm_command), QosProfile::reliable(1)),
        gripper(pp, ddsTopicName(topics.gripper_command), QosProfile::reliable(10)),
        joint_states(pp, ddsTopicName(topics.joint_states), QosProfile::reliable(10)),
        odom(pp, ddsTopicName(topics.odom), QosProfile::reliable(10)),
        left(pp, ddsTopicName(topics.left_image), QosProfile::sensorData()),
        right(pp, ddsTopicName(topics.right_image), QosProfile::sensorData()),
        left_info(pp, ddsTopicName(topics.left_info), QosProfile::reliable(1)),
        right_info(pp, ddsTopicName(topics.right_info), QosProfile::reliable(1)) {
    state.arm_q_rad = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(arm_names.size()));
    state.arm_qdot_radps = state.arm_q_rad;
    arm_qdot = state.arm_q_rad;
  }

  /// Until when (robot time) a command part written `age` seconds ago holds: the watchdog period
  /// (a trajectory's time_from_start if shorter) from its writing; before `now` when it is older.
  Seconds validity(Seconds now, Seconds age, Seconds time_from_start) const {
    const Seconds wd = model.watchdog_period_s;
    return now - age + (time_from_start > 0 ? std::min(time_from_start, wd) : wd);
  }

  /// How long ago (s) the sample with source timestamp `source_ns` was written; 0 when the writer's
  /// clock is ahead of ours. Its arrival cannot stand for its writing: a driver that stalled (a
  /// loaded machine, a stopped process) finds commands written long before in its reader.
  static Seconds age(int64_t source_ns) {
    return std::max<Seconds>(0.0, static_cast<double>(dds_time() - source_ns) * 1e-9);
  }

  void takeCommands(Seconds now) {
    std::vector<int64_t> src;
    auto samples = cmd_vel.takeAll(&src);
    for (size_t k = 0; k < samples.size(); ++k) {
      const auto& s = samples[k];
      ++stats.commands;
      const double v = s->linear.x, w = s->angular.z;
      if (!std::isfinite(v) || !std::isfinite(w)) {
        ++stats.bad_commands;
        continue;
      }
      base_v = v;
      base_w = w;
      base_until = validity(now, age(src[k]), 0);
    }
    auto heads = head.takeAll(&src);
    for (size_t k = 0; k < heads.size(); ++k) {
      const auto& s = heads[k];
      ++stats.commands;
      const msg::JointTrajectory& t = *s;
      if (t.points._length < 1) {
        ++stats.bad_commands;
        continue;
      }
      const msg::JointTrajectoryPoint& pt = t.points._buffer[0];
      const bool pos = pt.positions._length > 0;
      const dds_sequence_double& vals = pos ? pt.positions : pt.velocities;
      const int ip = indexOf(t.joint_names, kHeadPanJoint), it = indexOf(t.joint_names, kHeadTiltJoint);
      const double p = at(vals, ip, NAN), q = at(vals, it, NAN);
      if (ip < 0 || it < 0 || !std::isfinite(p) || !std::isfinite(q)) {
        ++stats.bad_commands;
        continue;
      }
      head_mode = pos ? robot::HeadMode::kPosition : robot::HeadMode::kVelocity;
      head_pan = p;
      head_tilt = q;
      head_until = validity(now, age(src[k]), pos ? 0 : fromRosDuration(pt.time_from_start));
    }
    auto arms = arm.takeAll(&src);
    for (size_t k = 0; k < arms.size(); ++k) {
      const auto& s = arms[k];
      ++stats.commands;
      const msg::JointTrajectory& t = *s;
      if (t.points._length < 1 || t.points._buffer[0].velocities._length != t.joint_names._length) {
        ++stats.bad_commands;
        continue;
      }
      const msg::JointTrajectoryPoint& pt = t.points._buffer[0];
      Eigen::VectorXd qd = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(arm_names.size()));
      bool ok = true;
      for (size_t k = 0; k < arm_names.size(); ++k) {
        const int i = indexOf(t.joint_names, arm_names[k]);
        qd[static_cast<Eigen::Index>(k)] = at(pt.velocities, i, 0.0);
        ok = ok && std::isfinite(qd[static_cast<Eigen::Index>(k)]);
      }
      if (!ok) {
        ++stats.bad_commands;
        continue;
      }
      arm_qdot = qd;
      arm_until = validity(now, age(src[k]), fromRosDuration(pt.time_from_start));
    }
    for (auto& s : gripper.takeAll()) {
      ++stats.commands;
      const msg::JointTrajectory& t = *s;
      const int i = indexOf(t.joint_names, kGripperJoint);
      if (t.points._length < 1 || i < 0 || !std::isfinite(at(t.points._buffer[0].positions, i, NAN))) {
        ++stats.bad_commands;
        continue;
      }
      gripper_cmd = at(t.points._buffer[0].positions, i) > 0.5 ? robot::GripperCommand::kOpen
                                                                : robot::GripperCommand::kClose;
    }
  }

  robot::RobotCommand mergedCommand(Seconds now, Seconds* valid_for) {
    robot::RobotCommand c = robot::RobotCommand::zero(static_cast<int>(arm_names.size()));
    Seconds until = now;
    if (now <= base_until) {
      c.base_v_mps = base_v;
      c.base_w_radps = base_w;
      until = std::max(until, base_until);
    }
    if (now <= head_until) {
      c.head_mode = head_mode;
      c.pan = head_pan;
      c.tilt = head_tilt;
      until = std::max(until, head_until);
    }
    if (now <= arm_until) {
      c.arm_qdot_radps = arm_qdot;
      until = std::max(until, arm_until);
    }
    c.gripper = gripper_cmd;
    gripper_cmd = robot::GripperCommand::kNone;
    *valid_for = until - now;
    return c;
  }

  void publishState(Seconds now) {
    JointStateOut js(now);
    js.add(kHeadPanJoint, state.pan_rad, state.pan_radps);
    js.add(kHeadTiltJoint, state.tilt_rad, state.tilt_radps);
    for (size_t k = 0; k < arm_names.size(); ++k) {
      const auto i = static_cast<Eigen::Index>(k);
      js.add(arm_names[k], i < state.arm_q_rad.size() ? state.arm_q_rad[i] : 0.0,
             i < state.arm_qdot_radps.size() ? state.arm_qdot_radps[i] : 0.0);
    }
    const GripperJoint g = encodeGripper(state.gripper);
    js.add(kGripperJoint, g.position, g.velocity, g.effort);
    joint_states.write(js.msg());

    const std::string odom_frame = kOdomFrame, base_frame = kBaseFrame;
    msg::Odometry od{};
    od.header = makeHeader(now, odom_frame);
    od.child_frame_id = const_cast<char*>(base_frame.c_str());
    od.pose.pose = toRosPose(state.wMb_odom);
    od.twist.twist.linear.x = state.base_v_mps;
    od.twist.twist.angular.z = state.base_w_radps;
    odom.write(od);
  }

  void publishFrame(const robot::StereoFrame& f) {
    const StereoRig& rig = cam->rig();
    ImageOut l(f.left, f.stamp, kLeftOpticalFrame), r(f.right, f.stamp, kRightOpticalFrame);
    CameraInfoOut li(rig.left, f.stamp, kLeftOpticalFrame),
        ri(rig.right, f.stamp, kRightOpticalFrame, rig.baseline());
    left_info.write(li.msg());
    right_info.write(ri.msg());
    left.write(l.msg());
    right.write(r.msg());
    ++stats.frames_published;
  }

  robot::EnonModel model;
  robot::RobotHardware& hw;
  robot::StereoSource* cam;
  DriverNodeOptions opt;
  RobotTopics topics;
  std::vector<std::string> arm_names;

  Participant pp;
  Reader<msg::Twist> cmd_vel;
  Reader<msg::JointTrajectory> head, arm, gripper;
  Writer<msg::JointState> joint_states;
  Writer<msg::Odometry> odom;
  Writer<msg::Image> left, right;
  Writer<msg::CameraInfo> left_info, right_info;

  robot::RobotState state;
  mutable std::mutex stats_mu;  ///< guards stats (read by other threads)
  DriverNodeStats stats;
  double base_v = 0, base_w = 0;
  robot::HeadMode head_mode = robot::HeadMode::kVelocity;
  double head_pan = 0, head_tilt = 0;
  Eigen::VectorXd arm_qdot;
  Seconds base_until = -1, head_until = -1, arm_until = -1;
  robot::GripperCommand gripper_cmd = robot::GripperCommand::kNone;
  Seconds last_time = 0, next_frame = -1e300;
  bool started = false;
};

RobotDriverNode::RobotDriverNode(const robot::EnonModel& model, robot::RobotHardware& hardware,
                                 robot::StereoSource* camera, const DriverNodeOptions& options)
    : p_(std::make_unique<Impl>(model, hardware, camera, options)) {}

RobotDriverNode::~RobotDriverNode() {
  if (p_->started) stop(p_->last_time);
}

ReturnType RobotDriverNode::start() {
  ReturnType r = p_->hw.configure();
  if (r == ReturnType::kOk) r = p_->hw.activate();
  p_->started = r == ReturnType::kOk;
  if (p_->started && p_->cam) {
    // A first frame now, before any state goes out: a camera's first grab may be slow (the
    // simulator builds its render caches), and a control cycle must never wait for it.
    std::optional<robot::StereoFrame> f;
    if (p_->cam->grab(0, &f) == ReturnType::kOk && f) p_->publishFrame(*f);
  }
  return r;
}

ReturnType RobotDriverNode::step(Seconds time) {
  Impl& p = *p_;
  if (!p.started) return ReturnType::kError;
  std::lock_guard<std::mutex> lock(p.stats_mu);
  const Seconds period = std::max(0.0, time - p.last_time);
  p.last_time = time;
  ++p.stats.steps;
  ReturnType result = p.hw.read(time, period, &p.state);
  if (result == ReturnType::kOk) p.publishState(time);
  else ++p.stats.hardware_errors;

  p.takeCommands(time);
  Seconds valid_for = 0;
  const robot::RobotCommand cmd = p.mergedCommand(time, &valid_for);
  if (p.hw.write(time, period, cmd, valid_for) != ReturnType::kOk) {
    ++p.stats.hardware_errors;
    result = ReturnType::kError;
  }

  if (p.cam && time >= p.next_frame) {
    std::optional<robot::StereoFrame> f;
    const ReturnType g = p.cam->grab(time, &f);
    if (g == ReturnType::kError) {
      ++p.stats.hardware_errors;
      result = ReturnType::kError;
    } else if (f) {
      p.publishFrame(*f);
      if (p.opt.camera_rate_hz > 0) p.next_frame = time + 1.0 / p.opt.camera_rate_hz - 1e-6;
    }
  }
  return result;
}

void RobotDriverNode::stop(Seconds time) {
  Impl& p = *p_;
  if (!p.started) return;
  p.hw.write(time, 0, robot::RobotCommand::zero(static_cast<int>(p.arm_names.size())),
             p.model.watchdog_period_s);
  p.hw.deactivate();
  p.started = false;
}

DriverNodeStats RobotDriverNode::stats() const {
  std::lock_guard<std::mutex> lock(p_->stats_mu);
  return p_->stats;
}
const robot::RobotState& RobotDriverNode::state() const { return p_->state; }

ReturnType runRealTime(RobotDriverNode& node, double period_s, const std::atomic<bool>& stop,
                       double duration_s) {
  if (node.start() != ReturnType::kOk) return ReturnType::kError;
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  auto next = t0;
  Seconds t = 0;
  while (!stop.load()) {
    t = std::chrono::duration<double>(clock::now() - t0).count();
    if (duration_s > 0 && t >= duration_s) break;
    node.step(t);
    next += std::chrono::duration_cast<clock::duration>(std::chrono::duration<double>(period_s));
    const auto now = clock::now();
    if (next < now) next = now;  // overran: no catch-up burst
    std::this_thread::sleep_until(next);
  }
  node.stop(t);
  return ReturnType::kOk;
}

}  // namespace refgrasp::dds
