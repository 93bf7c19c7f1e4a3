#include "robot/dds/dds_robot.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <map>
#include <optional>
#include <sstream>
#include <thread>
#include <type_traits>
#include <vector>

#include "core/error.h"
#include "robot/dds/convert.h"
#include "robot/dds/robot_topics.h"
#include "robot/dds/transport.h"

namespace refgrasp::dds {

using robot::ReturnType;

void DdsRobotOptions::check() const {
  checkDomainAndNamespace(domain, ns, "DdsRobotOptions");
  refgrasp::check(std::isfinite(connect_timeout_s) && connect_timeout_s > 0,
                  "DdsRobotOptions.connect_timeout_s", "must be positive");
}

namespace {

double steadyNow() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

/// Endpoints and the state shared by the hardware and the camera of one robot. All calls come
/// from the control thread (the HAL is single-threaded).
struct Link {
  Link(const robot::EnonModel& m, const DdsRobotOptions& o, LogSink l)
      : model(m), opt(o), topics(o.ns), arm_names(armJointNames(m)), log(std::move(l)) {}

  /// Cyclone holds the deletion of a reliable writer that has unacknowledged data for up to its
  /// WriterLingerDuration (1 s by default) and deletes one entity at a time. A robot that died
  /// or froze never acknowledges the last commands of any command writer, so deleting them one
  /// after the other would keep the caller from exiting for one linger per writer: they are
  /// deleted side by side (one linger at most), before the participant.
  ~Link() {
    std::vector<std::thread> closing;
    closing.emplace_back([this] { cmd_vel.reset(); });
    for (auto* w : {&head, &arm, &gripper}) closing.emplace_back([w] { w->reset(); });
    for (std::thread& t : closing) t.join();
  }

  bool open() {
    if (pp) return true;
    try {
      pp = std::make_unique<Participant>(opt.domain);
      const QosProfile cmd = QosProfile::reliable(1), state = QosProfile::reliable(10);
      cmd_vel = std::make_unique<Writer<msg::Twist>>(*pp, ddsTopicName(topics.cmd_vel), cmd);
      head = std::make_unique<Writer<msg::JointTrajectory>>(*pp, ddsTopicName(topics.head_command), cmd);
      arm = std::make_unique<Writer<msg::JointTrajectory>>(*pp, ddsTopicName(topics.arm_command), cmd);
      gripper = std::make_unique<Writer<msg::JointTrajectory>>(
          *pp, ddsTopicName(topics.gripper_command), QosProfile::reliable(10));
      joint_states = std::make_unique<Reader<msg::JointState>>(*pp, ddsTopicName(topics.joint_states), state);
      odom = std::make_unique<Reader<msg::Odometry>>(*pp, ddsTopicName(topics.odom), state);
      left = std::make_unique<Reader<msg::Image>>(*pp, ddsTopicName(topics.left_image),
                                                  QosProfile::sensorData());
      right = std::make_unique<Reader<msg::Image>>(*pp, ddsTopicName(topics.right_image),
                                                   QosProfile::sensorData());
    } catch (const DdsError& e) {
      fail(std::string("dds robot: ") + e.what());
      return false;
    }
    return true;
  }

  /// An error: the hardware's lastError() (the caller reports it: one line), and the log sink
  /// when one was given (once; repeated identical errors stay quiet until another or a success).
  void fail(const std::string& s) {
    if (log && s != last_error) log(s);
    last_error = s;
  }
  void clearError() { last_error.clear(); }
  /// A problem the run survives (a skipped camera frame): the log sink, else stderr.
  void warn(const std::string& s) {
    if (log) log(s);
    else std::fprintf(stderr, "%s\n", s.c_str());
  }

  /// Takes the newest robot state; the age (s, steady clock) of the older of joint_states / odom.
  double pollState() {
    Sample<msg::JointState> js;
    if (joint_states->takeNewest(&js) > 0) {
      js_sample = std::move(js);
      js_rx = steadyNow();
    }
    Sample<msg::Odometry> od;
    if (odom->takeNewest(&od) > 0) {
      odom_sample = std::move(od);
      odom_rx = steadyNow();
    }
    if (!js_sample || !odom_sample) return INFINITY;
    return steadyNow() - std::min(js_rx, odom_rx);
  }

  bool sendZero(Seconds time) {
    robot::RobotCommand z = robot::RobotCommand::zero(static_cast<int>(arm_names.size()));
    return sendCommand(time, z, model.watchdog_period_s);
  }

  bool sendCommand(Seconds time, const robot::RobotCommand& c, Seconds valid_for) {
    const Seconds stamp = time - offset;  // on the robot's clock
    msg::Twist tw{};
    tw.linear.x = c.base_v_mps;
    tw.angular.z = c.base_w_radps;
    bool ok = cmd_vel->write(tw);
    const bool pos = c.head_mode == robot::HeadMode::kPosition;
    TrajectoryOut h(stamp, {kHeadPanJoint, kHeadTiltJoint},
                    pos ? TrajectoryOut::Kind::kPositions : TrajectoryOut::Kind::kVelocities,
                    {c.pan, c.tilt}, pos ? 0.0 : valid_for);
    ok = head->write(h.msg()) && ok;
    std::vector<double> qdot(arm_names.size(), 0.0);
    for (size_t i = 0; i < qdot.size() && static_cast<Eigen::Index>(i) < c.arm_qdot_radps.size(); ++i)
      qdot[i] = c.arm_qdot_radps[static_cast<Eigen::Index>(i)];
    TrajectoryOut a(stamp, arm_names, TrajectoryOut::Kind::kVelocities, qdot, valid_for);
    ok = arm->write(a.msg()) && ok;
    if (c.gripper != robot::GripperCommand::kNone) {
      TrajectoryOut g(stamp, {kGripperJoint}, TrajectoryOut::Kind::kPositions,
                      {c.gripper == robot::GripperCommand::kOpen ? 1.0 : 0.0}, 0.0);
      ok = gripper->write(g.msg()) && ok;
    }
    return ok;
  }

  robot::EnonModel model;
  DdsRobotOptions opt;
  RobotTopics topics;
  std::vector<std::string> arm_names;
  LogSink log;
  std::string last_error;

  std::unique_ptr<Participant> pp;
  std::unique_ptr<Writer<msg::Twist>> cmd_vel;
  std::unique_ptr<Writer<msg::JointTrajectory>> head, arm, gripper;
  std::unique_ptr<Reader<msg::JointState>> joint_states;
  std::unique_ptr<Reader<msg::Odometry>> odom;
  std::unique_ptr<Reader<msg::Image>> left, right;

  std::optional<Sample<msg::JointState>> js_sample;
  std::optional<Sample<msg::Odometry>> odom_sample;
  double js_rx = 0, odom_rx = 0;
  bool offset_set = false;
  double offset = 0;  ///< caller time - robot stamp
  bool active = false;
};

class DdsHardware : public robot::RobotHardware {
 public:
  explicit DdsHardware(std::shared_ptr<Link> link) : l_(std::move(link)) {}

  ReturnType configure() override { return l_->open() ? ReturnType::kOk : ReturnType::kError; }
  std::string lastError() const override { return l_->last_error; }

  ReturnType activate() override {
    if (!l_->pp) return ReturnType::kError;
    const double end = steadyNow() + l_->opt.connect_timeout_s;
    while (!std::isfinite(l_->pollState())) {
      if (steadyNow() > end) {
        l_->fail("dds robot: no " + std::string(!l_->js_sample ? l_->topics.joint_states
                                                                  : l_->topics.odom) +
                   " on domain " + std::to_string(l_->opt.domain) + " within " +
                   std::to_string(l_->opt.connect_timeout_s) + " s: is the robot driver running?");
        return ReturnType::kError;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    l_->offset_set = false;
    l_->active = true;
    l_->clearError();
    return ReturnType::kOk;
  }

  ReturnType deactivate() override {
    if (l_->active) l_->sendZero(last_time_);
    l_->active = false;
    return ReturnType::kOk;
  }

  ReturnType read(Seconds time, Seconds /*period*/, robot::RobotState* s) override {
    last_time_ = time;
    if (!l_->active) return ReturnType::kError;
    const double age = l_->pollState();
    if (!stateFresh(age)) return ReturnType::kError;
    const msg::JointState& js = **l_->js_sample;
    const msg::Odometry& od = **l_->odom_sample;
    if (!l_->offset_set) {
      l_->offset = time - fromRosTime(js.header.stamp) - (steadyNow() - l_->js_rx);
      l_->offset_set = true;
    }
    auto joint = [&](const std::string& name, double* q, double* qd) {
      const int i = indexOf(js.name, name);
      if (i < 0) return false;
      *q = at(js.position, i);
      *qd = at(js.velocity, i);
      return true;
    };
    bool ok = joint(kHeadPanJoint, &s->pan_rad, &s->pan_radps) &&
              joint(kHeadTiltJoint, &s->tilt_rad, &s->tilt_radps);
    const auto n = static_cast<Eigen::Index>(l_->arm_names.size());
    s->arm_q_rad.resize(n);
    s->arm_qdot_radps.resize(n);
    for (Eigen::Index k = 0; ok && k < n; ++k)
      ok = joint(l_->arm_names[static_cast<size_t>(k)], &s->arm_q_rad[k], &s->arm_qdot_radps[k]);
    const int g = indexOf(js.name, kGripperJoint);
    if (!ok || g < 0) {
      l_->fail("dds robot: " + l_->topics.joint_states +
                 " lacks a joint of the model (head_pan, head_tilt, arm joints, gripper)");
      l_->sendZero(time);
      return ReturnType::kError;
    }
    s->gripper = decodeGripper({at(js.position, g), at(js.velocity, g), at(js.effort, g)});
    s->held_object.clear();  // the simulator's ground truth; not on the bus
    s->stamp = fromRosTime(js.header.stamp) + l_->offset;
    s->wMb_odom = fromRosPose(od.pose.pose);
    s->base_v_mps = od.twist.twist.linear.x;
    s->base_w_radps = od.twist.twist.angular.z;
    if (!s->wMb_odom.isFinite() || !s->arm_q_rad.allFinite() || !std::isfinite(s->pan_rad) ||
        !std::isfinite(s->tilt_rad)) {
      l_->fail("dds robot: non-finite robot state");
      l_->sendZero(time);
      return ReturnType::kError;
    }
    l_->clearError();
    return ReturnType::kOk;
  }

  ReturnType write(Seconds time, Seconds /*period*/, const robot::RobotCommand& cmd,
                   Seconds valid_for_s) override {
    last_time_ = time;
    if (!l_->active) return ReturnType::kError;
    const double age = l_->pollState();
    if (!stateFresh(age)) return ReturnType::kError;
    if (!cmd.isFinite() || cmd.arm_qdot_radps.size() != static_cast<Eigen::Index>(l_->arm_names.size())) {
      l_->fail("dds robot: non-finite or wrong-sized command: sending zero");
      l_->sendZero(time);
      return ReturnType::kError;
    }
    if (!l_->sendCommand(time, cmd, valid_for_s)) {
      l_->fail("dds robot: cannot write commands");
      return ReturnType::kError;
    }
    return ReturnType::kOk;
  }

 private:
  /// The watchdog rule: a state older than the watchdog period is an error and zero commands.
  bool stateFresh(double age) {
    if (age <= l_->model.watchdog_period_s) return true;
    char buf[200];
    if (std::isfinite(age))
      std::snprintf(buf, sizeof buf, "dds robot: no robot state for %.2f s (watchdog %.2f s): stopping",
                    age, l_->model.watchdog_period_s);
    else
      std::snprintf(buf, sizeof buf, "dds robot: no robot state yet: stopping");
    l_->fail(buf);
    l_->sendZero(last_time_);
    return false;
  }

  std::shared_ptr<Link> l_;
  Seconds last_time_ = 0;
};

class DdsStereo : public robot::StereoSource {
 public:
  explicit DdsStereo(std::shared_ptr<Link> link) : l_(std::move(link)) {}
  const StereoRig& rig() const override { return l_->model.head.rig; }

  ReturnType grab(Seconds /*time*/, std::optional<robot::StereoFrame>* frame) override {
    frame->reset();
    if (!l_->active || !l_->left) return ReturnType::kError;
    collect(*l_->left, &left_);
    collect(*l_->right, &right_);
    // Newest stamp both eyes have, newer than the last pair returned.
    for (auto it = left_.rbegin(); it != left_.rend(); ++it) {
      const auto r = right_.find(it->first);
      if (r == right_.end() || it->first <= last_stamp_) continue;
      if (!l_->offset_set) return ReturnType::kOk;  // no state read yet: no clock
      const GrayImage gl = toGray(**it->second), gr = toGray(**r->second);
      last_stamp_ = it->first;
      if (!gl.ok() || !gr.ok()) {
        l_->warn("dds robot: camera frame skipped: " + (gl.ok() ? gr.error : gl.error));
        return ReturnType::kOk;
      }
      robot::StereoFrame f;
      // The samples die with the maps: copy (the only copy after DDS deserialisation).
      f.left = gl.copied ? gl.gray : gl.gray.clone();
      f.right = gr.copied ? gr.gray : gr.gray.clone();
      f.stamp = static_cast<double>(it->first) * 1e-9 + l_->offset;
      f.index = index_++;
      *frame = std::move(f);
      prune();
      return ReturnType::kOk;
    }
    prune();
    return ReturnType::kOk;
  }

 private:
  using Frames = std::map<int64_t, std::shared_ptr<Sample<msg::Image>>>;  // by stamp (ns)

  static void collect(const Reader<msg::Image>& r, Frames* into) {
    for (auto& s : r.takeAll()) {
      const int64_t ns = static_cast<int64_t>(s->header.stamp.sec) * 1000000000LL + s->header.stamp.nanosec;
      (*into)[ns] = std::make_shared<Sample<msg::Image>>(std::move(s));
    }
  }
  void prune() {
    for (Frames* f : {&left_, &right_}) {
      while (f->size() > 4) f->erase(f->begin());
      while (!f->empty() && f->begin()->first <= last_stamp_) f->erase(f->begin());
    }
  }

  std::shared_ptr<Link> l_;
  Frames left_, right_;
  int64_t last_stamp_ = INT64_MIN;
  int64_t index_ = 0;
};

/// A numeric backend setting: `def` when absent, ConfigError naming the source and key when malformed.
template <class T>
T numberParam(const robot::BackendConfig& c, const robot::EnonModel& m, const std::string& key, T def) {
  const auto it = c.params.find(key);
  if (it == c.params.end()) return def;
  std::istringstream in(it->second);
  T v{};
  if (in >> v && in.peek() == std::char_traits<char>::eof()) return v;
  throw ConfigError(c.source.empty() ? m.path : c.source, key,
                    "'" + it->second + "' is not " +
                        (std::is_integral<T>::value ? "an integer" : "a number"));
}

}  // namespace

std::unique_ptr<robot::Robot> makeDdsRobot(const robot::EnonModel& model,
                                           const DdsRobotOptions& options, LogSink log) {
  options.check();
  auto link = std::make_shared<Link>(model, options, std::move(log));
  return std::make_unique<robot::Robot>(model, std::make_unique<DdsHardware>(link),
                                        std::make_unique<DdsStereo>(link));
}

void registerDdsBackend() {
  robot::registerBackend("dds", [](const robot::EnonModel& model, const robot::BackendConfig& c) {
    DdsRobotOptions o;
    o.domain = numberParam(c, model, "domain", o.domain);
    const auto ns = c.params.find("ns");
    if (ns != c.params.end()) o.ns = ns->second;
    o.connect_timeout_s = numberParam(c, model, "connect_timeout_s", o.connect_timeout_s);
    const std::string src = c.source.empty() ? model.path : c.source;
    if (o.domain < 0 || o.domain > kMaxDomainId)
      throw ConfigError(src, "domain", "must be in [0, " + std::to_string(kMaxDomainId) + "]");
    if (const std::string p = rosNameProblem(o.ns, true); !p.empty()) throw ConfigError(src, "ns", p);
    if (!(o.connect_timeout_s > 0) || !std::isfinite(o.connect_timeout_s))
      throw ConfigError(src, "connect_timeout_s", "must be positive");
    return makeDdsRobot(model, o);
  });
}

}  // namespace refgrasp::dds
