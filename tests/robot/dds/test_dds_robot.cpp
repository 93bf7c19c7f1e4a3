// The "dds" backend against the driver node serving the simulated enon over the bus (both in this
// process, on a private domain, in real time): commands arrive, state comes back, frames are
// paired, and the watchdog holds on both sides.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "common/subprocess.h"
#include "common/temp_dir.h"
#include "core/error.h"
#include "dds_test_util.h"
#include "robot/backend.h"
#include "robot/backends.h"
#include "robot/dds/convert.h"
#include "robot/dds/dds_robot.h"
#include "robot/dds/driver_node.h"
#include "robot/dds/robot_topics.h"
#include "robot/dds/transport.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"

using namespace refgrasp;
using refgrasp::robot::ReturnType;
using nlohmann::json;

namespace {

const std::string kSource = REFGRASP_SOURCE_DIR;

double now() {
  static const auto t0 = std::chrono::steady_clock::now();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// The enon model; tests that are not about the watchdog give it a long period, so a loaded
/// machine (ctest -j, other builds) that stalls a thread for a moment does not trip it.
robot::EnonModel testModel(double watchdog_s) {
  robot::EnonModel m = robot::loadEnonModel(kSource + "/config/enon.yaml");
  if (watchdog_s > 0) m.watchdog_period_s = watchdog_s;
  return m;
}

/// The simulated enon served on the bus by a driver node stepping in real time on its own thread;
/// with camera_rate_hz < 0 it has no camera (rendering at 48 Hz would load the machine).
class SimOnBus {
 public:
  SimOnBus(int domain, const std::string& ns, const robot::EnonModel& model,
           double camera_rate_hz = -1)
      : model_(model),
        sim_(model_, sim::loadScenario(kSource + "/config/scenarios/table_single.yaml")),
        cam_(camera_rate_hz >= 0 ? sim_.makeCamera() : nullptr) {
    dds::DriverNodeOptions o;
    o.domain = domain;
    o.ns = ns;
    o.camera_rate_hz = std::max(0.0, camera_rate_hz);
    node_ = std::make_unique<dds::RobotDriverNode>(model_, sim_, cam_.get(), o);
    thread_ = std::thread([this] { dds::runRealTime(*node_, model_.control_period_s, stop_); });
  }
  ~SimOnBus() { halt(); }
  /// Stops the node (it stops publishing); afterwards the simulator may be inspected.
  void halt() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  const robot::EnonModel& model() const { return model_; }
  sim::SimEnon& sim() { return sim_; }
  dds::DriverNodeStats stats() const { return node_->stats(); }

 private:
  robot::EnonModel model_;
  sim::SimEnon sim_;
  std::unique_ptr<robot::StereoSource> cam_;
  std::unique_ptr<dds::RobotDriverNode> node_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

class DdsRobot : public ::testing::Test {
 protected:
  void SetUp() override {
    refgrasp::testing::useLoopbackDds();
    robot::registerBuiltinBackends();
    domain_ = refgrasp::testing::privateDomain();
    ns_ = refgrasp::testing::privateNamespace("enon");
  }
  robot::BackendConfig config() const {
    return {"dds", {{"domain", std::to_string(domain_)}, {"ns", ns_}}, "test"};
  }
  /// One control cycle of `r` at the caller's clock; `command` sets the commands.
  template <class F>
  ReturnType cycle(robot::Robot& r, double* last, F command) {
    const double t = now(), dt = t - *last;
    *last = t;
    ReturnType rr = r.read(t, dt);
    if (rr != ReturnType::kOk) return rr;
    command(r);
    return r.write(t, dt);
  }
  void sleepCycle(double period) { std::this_thread::sleep_for(std::chrono::duration<double>(period)); }

  int domain_ = 0;
  std::string ns_;
};

}  // namespace

TEST_F(DdsRobot, CommandsReachTheSimulatedEnonAndItsStateComesBack) {
  SimOnBus bus(domain_, ns_, testModel(1.0));
  auto r = robot::makeRobot(bus.model(), config());
  ASSERT_EQ(r->configure(), ReturnType::kOk);
  ASSERT_EQ(r->activate(), ReturnType::kOk);
  const double dt = bus.model().control_period_s;
  const int dof = r->arm().kinematics().dof();
  Eigen::VectorXd qd = Eigen::VectorXd::Zero(dof);
  qd[0] = 0.2;
  double last = now();
  // 1 s of commands, then zero for 1.2 s.
  double first_cmd = -1, last_cmd = -1;
  while (true) {
    const double t = now();
    const bool moving = first_cmd < 0 || t - first_cmd < 1.0;
    ASSERT_EQ(cycle(*r, &last,
                    [&](robot::Robot& rb) {
                      if (moving) {
                        rb.base().setVelocity(0.2, 0.0);
                        rb.head().setVelocity(0.3, 0.0);
                        rb.arm().setJointVelocity(qd);
                      } else {
                        rb.base().setVelocity(0, 0);
                        rb.head().setVelocity(0, 0);
                        rb.arm().setJointVelocity(Eigen::VectorXd::Zero(dof));
                      }
                    }),
              ReturnType::kOk);
    if (moving) {
      if (first_cmd < 0) first_cmd = t;
      last_cmd = t;
    }
    if (t - first_cmd > 2.2) break;
    sleepCycle(dt);
  }
  const robot::RobotState seen = r->state();
  r->deactivate();
  bus.halt();
  const double T = last_cmd - first_cmd + dt;  // the last command holds for one period
  const double x = bus.sim().trueBasePose().x_m;
  // Delivery latency shifts start and end alike; a loaded machine adds jitter: 6 periods.
  EXPECT_NEAR(x, 0.2 * T, 0.2 * 6 * dt) << "T = " << T;
  EXPECT_NEAR(bus.sim().trueBasePose().y_m, 0.0, 1e-9);
  // The three parts moved for the same time: their ratios are those of the commands.
  EXPECT_NEAR(bus.sim().pan() / x, 0.3 / 0.2, 0.03 * 1.5);
  EXPECT_NEAR(bus.sim().q()[0] / x, 1.0, 0.03);
  // What came back over the bus is the simulator's state (it stood still for the last second).
  EXPECT_NEAR(seen.pan_rad, bus.sim().pan(), 1e-9);
  EXPECT_NEAR(seen.arm_q_rad[0], bus.sim().q()[0], 1e-9);
  EXPECT_NEAR(seen.wMb_odom.t.x(), bus.sim().odometryPose().x_m, 1e-9);
  EXPECT_NEAR(seen.wMb_odom.t.y(), bus.sim().odometryPose().y_m, 1e-9);
  EXPECT_EQ(seen.gripper, robot::GripperPhase::kOpen);
  EXPECT_GT(bus.stats().commands, 20);
  EXPECT_EQ(bus.stats().bad_commands, 0);
}

TEST_F(DdsRobot, GripperAndHeadPositionCommands) {
  SimOnBus bus(domain_, ns_, testModel(1.0));
  auto r = robot::makeRobot(bus.model(), config());
  ASSERT_EQ(r->configure(), ReturnType::kOk);
  ASSERT_EQ(r->activate(), ReturnType::kOk);
  const double dt = bus.model().control_period_s;
  double last = now();
  bool closing_seen = false;
  const double t0 = now();
  bool closed = false;
  while (now() - t0 < 8 && !(closed && std::abs(r->state().pan_rad + 0.4) < 1e-6)) {
    const bool first = now() - t0 < dt;
    ASSERT_EQ(cycle(*r, &last,
                    [&](robot::Robot& rb) {
                      if (first) rb.gripper().close();
                      rb.head().setPosition(-0.4, 0.2);
                    }),
              ReturnType::kOk);
    closing_seen = closing_seen || r->state().gripper == robot::GripperPhase::kClosing;
    closed = r->state().gripper == robot::GripperPhase::kClosedEmpty;
    sleepCycle(dt);
  }
  EXPECT_TRUE(closing_seen);
  EXPECT_EQ(r->state().gripper, robot::GripperPhase::kClosedEmpty);  // nothing within reach
  EXPECT_NEAR(r->state().pan_rad, -0.4, 1e-6);
  EXPECT_NEAR(r->state().tilt_rad, 0.2, 1e-6);
}

// The HAL-side watchdog: no state for longer than the watchdog period is an error and zero commands.
TEST_F(DdsRobot, SilentRobotIsAnErrorAndZeroCommands) {
  auto bus = std::make_unique<SimOnBus>(domain_, ns_, testModel(0));
  std::mutex mu;
  std::vector<std::string> log;
  dds::DdsRobotOptions o;
  o.domain = domain_;
  o.ns = ns_;
  auto r = dds::makeDdsRobot(bus->model(), o, [&](const std::string& s) {
    std::lock_guard<std::mutex> l(mu);
    log.push_back(s);
  });
  ASSERT_EQ(r->configure(), ReturnType::kOk);
  ASSERT_EQ(r->activate(), ReturnType::kOk);
  dds::Participant spy_pp(domain_);
  dds::Reader<dds::msg::Twist> spy(spy_pp, dds::ddsTopicName(ns_ + "/cmd_vel"), dds::QosProfile::reliable(10));
  ASSERT_TRUE(spy.waitForMatch(1, 5));
  const double dt = bus->model().control_period_s;
  double last = now();
  int ok = 0;
  for (int i = 0; i < 20; ++i) {
    ok += cycle(*r, &last, [](robot::Robot& rb) { rb.base().setVelocity(0.3, 0.1); }) == ReturnType::kOk;
    sleepCycle(dt);
  }
  ASSERT_GE(ok, 10);  // a loaded machine may stall the node for a watchdog period now and then
  bus->halt();  // the robot goes silent
  const double silent = now();
  ReturnType rr = ReturnType::kOk;
  while (rr == ReturnType::kOk && now() - silent < 2.0) {
    rr = cycle(*r, &last, [](robot::Robot& rb) { rb.base().setVelocity(0.3, 0.1); });
    sleepCycle(dt);
  }
  const double took = now() - silent;
  EXPECT_EQ(rr, ReturnType::kError);
  const double wd = bus->model().watchdog_period_s;
  EXPECT_GT(took, wd - 2 * dt);
  EXPECT_LT(took, wd + 0.25);  // a few periods, plus slack for a loaded machine
  EXPECT_EQ(r->lastCommand().base_v_mps, 0.0);
  // On the bus: the last command the robot would get is zero.
  dds::Sample<dds::msg::Twist> tw;
  ASSERT_TRUE(refgrasp::testing::waitUntil([&] { return spy.takeNewest(&tw) > 0; }, 2));
  while (spy.takeNewest(&tw) > 0) {
  }
  EXPECT_EQ(tw->linear.x, 0.0);
  EXPECT_EQ(tw->angular.z, 0.0);
  std::lock_guard<std::mutex> l(mu);
  ASSERT_FALSE(log.empty());
  EXPECT_NE(log.back().find("no robot state for"), std::string::npos) << log.back();
}

// The driver-side watchdog: a controller that goes silent (here a bare cmd_vel writer, as a ROS
// teleop node that dies) stops the robot within the watchdog period.
TEST_F(DdsRobot, SilentControllerStopsTheRobot) {
  SimOnBus bus(domain_, ns_, testModel(0));
  dds::Participant pp(domain_);
  dds::Writer<dds::msg::Twist> cmd(pp, dds::ddsTopicName(ns_ + "/cmd_vel"), dds::QosProfile::reliable(1));
  dds::Reader<dds::msg::Odometry> odom(pp, dds::ddsTopicName(ns_ + "/odom"), dds::QosProfile::reliable(10));
  dds::Sample<dds::msg::Odometry> od;
  auto x = [&] {
    while (odom.takeNewest(&od) > 0) {
    }
    return od->pose.pose.position.x;
  };
  dds::msg::Twist tw{};
  tw.linear.x = 0.3;
  // Drive until the robot moves (discovery may take a while on a loaded machine), then 0.3 s more.
  double moving_since = -1;
  const double t0 = now();
  while (now() - t0 < 10 && (moving_since < 0 || now() - moving_since < 0.3)) {
    cmd.write(tw);
    if (moving_since < 0 && x() > 0.005) moving_since = now();
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_GT(moving_since, 0) << "the robot never moved";
  const double x0 = x();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const double x1 = x();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const double x2 = x();
  EXPECT_NEAR(x2, x1, 1e-9) << "the robot kept moving after its controller went silent";
  // It went on for about the watchdog period after the last command (x0 may lag behind by the
  // odometry's transport and a loaded machine's scheduling: 0.15 s of slack).
  EXPECT_LT(x1 - x0, 0.3 * (bus.model().watchdog_period_s + 0.15));
}

TEST_F(DdsRobot, StereoFramesArePairedAndOnTheCallersClock) {
  SimOnBus bus(domain_, ns_, testModel(1.0), 10);
  auto r = robot::makeRobot(bus.model(), config());
  ASSERT_EQ(r->configure(), ReturnType::kOk);
  ASSERT_EQ(r->activate(), ReturnType::kOk);
  // The caller's clock is 1000 s ahead of the robot's: stamps must be mapped, not passed on.
  const double kAhead = 1000;
  auto clock = [&] { return now() + kAhead; };
  double last = clock();
  std::vector<robot::StereoFrame> frames;
  int seen = 0;
  const double t0 = now();
  while (frames.size() < 6 && now() - t0 < 10) {
    const double t = clock();
    ASSERT_EQ(r->read(t, t - last), ReturnType::kOk);
    last = t;
    std::optional<robot::StereoFrame> f;
    ASSERT_EQ(r->camera().grab(t, &f), ReturnType::kOk);
    if (f && ++seen > 1) {  // the first frame waits for the renderer's caches: skip it
      // Captured in the past, recently (rendering and transport; slack for a loaded machine).
      EXPECT_LT(f->stamp, clock() + 0.01);
      EXPECT_GT(f->stamp, clock() - 0.5) << "frame stamp not on the caller's clock";
      frames.push_back(std::move(*f));
    }
    sleepCycle(bus.model().control_period_s);
  }
  ASSERT_EQ(frames.size(), 6u);
  const double frame_period = 1.0 / bus.model().head.frame_rate_hz;
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].left.size(), cv::Size(640, 480));
    EXPECT_EQ(frames[i].left.type(), CV_8UC1);
    EXPECT_EQ(frames[i].right.size(), cv::Size(640, 480));
    EXPECT_GT(cv::norm(frames[i].left, frames[i].right, cv::NORM_L1), 0);
    ASSERT_TRUE(frames[i].capture.bMc.has_value());  // the HAL filled the camera pose at capture
    if (i > 0) {
      // Published at 10 Hz at most, captured on the camera's 48 Hz grid.
      const double d = frames[i].stamp - frames[i - 1].stamp;
      EXPECT_GT(d, 0.1 - frame_period - 1e-6);
      EXPECT_NEAR(d / frame_period, std::round(d / frame_period), 1e-3);
      EXPECT_EQ(frames[i].index, frames[i - 1].index + 1);
    }
  }
}

TEST_F(DdsRobot, NoDriverIsAnErrorAtActivate) {
  const robot::EnonModel model = robot::loadEnonModel(kSource + "/config/enon.yaml");
  std::vector<std::string> log;
  dds::DdsRobotOptions o;
  o.domain = domain_;
  o.ns = ns_;
  o.connect_timeout_s = 0.3;
  auto r = dds::makeDdsRobot(model, o, [&](const std::string& s) { log.push_back(s); });
  ASSERT_EQ(r->configure(), ReturnType::kOk);
  const double t0 = now();
  EXPECT_EQ(r->activate(), ReturnType::kError);
  EXPECT_LT(now() - t0, 1.0);
  ASSERT_EQ(log.size(), 1u);
  EXPECT_NE(log[0].find("no " + ns_ + "/joint_states on domain " + std::to_string(domain_)),
            std::string::npos)
      << log[0];
  EXPECT_EQ(log[0].find('\n'), std::string::npos);
}

TEST_F(DdsRobot, FactoryRejectsBadSettings) {
  const robot::EnonModel model = robot::loadEnonModel(kSource + "/config/enon.yaml");
  auto expectError = [&](std::map<std::string, std::string> params, const std::string& field) {
    try {
      robot::makeRobot(model, {"dds", params, "robot.yaml"});
      ADD_FAILURE() << "no error for " << field;
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.file(), "robot.yaml");
      EXPECT_EQ(e.field(), field) << e.what();
    }
  };
  expectError({{"domain", "abc"}}, "domain");
  expectError({{"domain", "3x"}}, "domain");
  expectError({{"domain", "233"}}, "domain");
  expectError({{"ns", "enon"}}, "ns");
  expectError({{"ns", "/en on"}}, "ns");
  expectError({{"connect_timeout_s", "-1"}}, "connect_timeout_s");
  EXPECT_NE(robot::makeRobot(model, {"dds", {{"domain", "7"}, {"ns", "/x"}}, "robot.yaml"}), nullptr);
  const auto names = robot::backendNames();
  EXPECT_NE(std::find(names.begin(), names.end(), "dds"), names.end());
}

TEST_F(DdsRobot, MalformedCommandsAreIgnoredByTheDriver) {
  SimOnBus bus(domain_, ns_, testModel(1.0));
  dds::Participant pp(domain_);
  dds::Writer<dds::msg::Twist> cmd(pp, dds::ddsTopicName(ns_ + "/cmd_vel"), dds::QosProfile::reliable(1));
  dds::Writer<dds::msg::JointTrajectory> arm(pp, dds::ddsTopicName(ns_ + "/arm/command"),
                                             dds::QosProfile::reliable(1));
  dds::msg::Twist tw{};
  tw.linear.x = std::nan("");
  // velocities for 1 joint of 2 named: malformed
  dds::TrajectoryOut bad(0, {"shoulder_pitch", "elbow_pitch"}, dds::TrajectoryOut::Kind::kVelocities, {0.5}, 0.2);
  const double t0 = now();
  while (bus.stats().bad_commands < 10 && now() - t0 < 10) {
    cmd.write(tw);
    arm.write(bad.msg());
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  bus.halt();
  EXPECT_GE(bus.stats().bad_commands, 10);
  EXPECT_EQ(bus.sim().trueBasePose().x_m, 0.0);
  EXPECT_EQ(bus.sim().q()[0], 0.0);
}

// A ROS 2 teleop node (the plain-C probe) drives the simulated enon; a ROS 2 listener decodes its
// joint_states and odom.
TEST_F(DdsRobot, RosNodesDriveAndListenToTheSimulatedEnon) {
  SimOnBus bus(domain_, ns_, testModel(0));
  const auto dir = refgrasp::testing::tempDir("refgrasp_dds_robot");
  using refgrasp::testing::Subprocess;
  Subprocess js({refgrasp::testing::probePath(), "--domain", std::to_string(domain_), "echo",
                 "rt" + ns_ + "/joint_states", "sensor_msgs::msg::dds_::JointState_", "--count", "1"},
                dir, "js");
  ASSERT_EQ(js.wait(10), 0) << js.err();
  const json j = json::parse(js.out());
  ASSERT_TRUE(j["ok"].get<bool>());
  std::vector<std::string> want = {"head_pan", "head_tilt"};
  for (const auto& n : dds::armJointNames(bus.model())) want.push_back(n);
  want.push_back("gripper");
  EXPECT_EQ(j["msg"]["name"], json(want));
  EXPECT_EQ(j["msg"]["position"].back(), 1.0);  // gripper open

  Subprocess teleop({refgrasp::testing::probePath(), "--domain", std::to_string(domain_), "pub-twist",
                     "rt" + ns_ + "/cmd_vel", "0.25", "0.0", "--count", "50", "--rate", "50"},
                    dir, "teleop");
  ASSERT_EQ(teleop.wait(10), 0) << teleop.err();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  Subprocess od({refgrasp::testing::probePath(), "--domain", std::to_string(domain_), "echo",
                 "rt" + ns_ + "/odom", "nav_msgs::msg::dds_::Odometry_", "--count", "1"},
                dir, "odom");
  ASSERT_EQ(od.wait(10), 0) << od.err();
  const json o = json::parse(od.out());
  ASSERT_TRUE(o["ok"].get<bool>());
  EXPECT_EQ(o["msg"]["header"]["frame_id"], "odom");
  EXPECT_EQ(o["msg"]["child_frame_id"], "base_link");
  // 0.25 m/s for as long as the commands spanned (the first ones may go before the driver has
  // discovered the probe) plus at most the driver's command lifetime and a state period.
  const double span = json::parse(teleop.out())["first_to_last_s"].get<double>();
  const double x = o["msg"]["pose"]["pose"]["position"]["x"].get<double>();
  EXPECT_GT(x, 0.25 * 0.3);
  EXPECT_LT(x, 0.25 * (span + bus.model().watchdog_period_s + 0.05)) << "span " << span;
  EXPECT_DOUBLE_EQ(o["msg"]["twist"]["twist"]["linear"]["x"].get<double>(), 0.0);
}
