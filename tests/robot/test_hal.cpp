// The HAL layer on its own: lifecycle, watchdog, stop on every error path, arm DLS commands,
// and the one-line ConfigErrors of a bad enon.yaml.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "robot/hal.h"
#include "robot_test_util.h"

using namespace refgrasp;
using namespace refgrasp::robot;

namespace {

// Device double: records what the layer sends, returns a scripted state and status.
struct FakeHardware : RobotHardware {
  std::vector<std::pair<Seconds, RobotCommand>> writes;
  ReturnType read_status = ReturnType::kOk, write_status = ReturnType::kOk;
  Eigen::VectorXd q;
  explicit FakeHardware(int dof) : q(Eigen::VectorXd::Constant(dof, 0.4)) {}
  ReturnType configure() override { return ReturnType::kOk; }
  ReturnType activate() override { return ReturnType::kOk; }
  ReturnType deactivate() override { return ReturnType::kOk; }
  double pan_rate = 0;  ///< scripted head motion: pan = pan_rate * time
  ReturnType read(Seconds time, Seconds, RobotState* s) override {
    s->stamp = time;
    s->pan_rad = pan_rate * time;
    s->wMb_odom = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.5 * time, 0, 0));
    s->arm_q_rad = q;
    s->arm_qdot_radps = Eigen::VectorXd::Zero(q.size());
    return read_status;
  }
  ReturnType write(Seconds time, Seconds, const RobotCommand& c, Seconds) override {
    writes.emplace_back(time, c);
    return write_status;
  }
};

struct FakeCamera : StereoSource {
  StereoRig rig_;
  ReturnType status = ReturnType::kOk;
  std::optional<StereoFrame> next;  ///< delivered by the next grab (capture state left empty)
  const StereoRig& rig() const override { return rig_; }
  ReturnType grab(Seconds, std::optional<StereoFrame>* f) override {
    *f = next;
    next.reset();
    return status;
  }
};

bool isZeroMotion(const RobotCommand& c) {
  return c.base_v_mps == 0 && c.base_w_radps == 0 && c.head_mode == HeadMode::kVelocity &&
         c.pan == 0 && c.tilt == 0 && c.arm_qdot_radps.isZero(0);
}

struct HalFixture : ::testing::Test {
  EnonModel model = testing_util::enonModel();
  FakeHardware* hw = nullptr;
  FakeCamera* cam = nullptr;
  std::unique_ptr<Robot> robot;
  void SetUp() override {
    auto h = std::make_unique<FakeHardware>(model.arm.dof());
    auto c = std::make_unique<FakeCamera>();
    hw = h.get();
    cam = c.get();
    robot = std::make_unique<Robot>(model, std::move(h), std::move(c));
  }
  void activate() {
    ASSERT_EQ(robot->configure(), ReturnType::kOk);
    ASSERT_EQ(robot->activate(), ReturnType::kOk);
  }
  void commandEverything() {
    robot->base().setVelocity(0.5, 0.2);
    robot->head().setVelocity(0.3, -0.2);
    robot->arm().setJointVelocity(Eigen::VectorXd::Constant(model.arm.dof(), 0.1));
  }
};

}  // namespace

TEST_F(HalFixture, NothingIsSentBeforeActivation) {
  robot->base().setVelocity(0.5, 0);
  EXPECT_EQ(robot->write(0, 0.02), ReturnType::kError);
  ASSERT_EQ(robot->configure(), ReturnType::kOk);
  EXPECT_EQ(robot->write(0, 0.02), ReturnType::kError);
  EXPECT_TRUE(hw->writes.empty());
  ASSERT_EQ(robot->activate(), ReturnType::kOk);
  EXPECT_EQ(robot->lifecycle(), Lifecycle::kActive);
  // Activation drops commands set while inactive.
  EXPECT_EQ(robot->write(0, 0.02), ReturnType::kOk);
  EXPECT_TRUE(isZeroMotion(hw->writes.back().second));
}

TEST_F(HalFixture, WatchdogZeroesEveryActuatorAfterTheTimeout) {
  activate();
  const double dt = 0.02;
  commandEverything();
  ASSERT_EQ(robot->read(0, dt), ReturnType::kOk);
  ASSERT_EQ(robot->write(0, dt), ReturnType::kOk);
  EXPECT_NEAR(hw->writes.back().second.base_v_mps, 0.5, 1e-12);
  // The loop keeps running but nobody sets a command any more.
  for (int k = 1; k <= 20; ++k) {
    const double t = k * dt;
    ASSERT_EQ(robot->read(t, dt), ReturnType::kOk);
    ASSERT_EQ(robot->write(t, dt), ReturnType::kOk);
    const RobotCommand& sent = hw->writes.back().second;
    if (std::abs(t - model.watchdog_period_s) < 1e-9) continue;  // the boundary itself
    if (t < model.watchdog_period_s) {
      EXPECT_NEAR(sent.base_v_mps, 0.5, 1e-12) << "t=" << t;
      EXPECT_NEAR(sent.pan, 0.3, 1e-12);
      EXPECT_FALSE(robot->state().watchdog_tripped);
    } else {
      EXPECT_TRUE(isZeroMotion(sent)) << "t=" << t;
      EXPECT_TRUE(robot->state().watchdog_tripped);
    }
  }
  // A new command re-arms it.
  robot->base().setVelocity(0.1, 0);
  ASSERT_EQ(robot->write(0.5, dt), ReturnType::kOk);
  EXPECT_NEAR(hw->writes.back().second.base_v_mps, 0.1, 1e-12);
  EXPECT_FALSE(robot->state().watchdog_tripped);
}

TEST_F(HalFixture, WatchdogStopsEvenWhenWriteIsNoLongerCalled) {
  activate();
  commandEverything();
  ASSERT_EQ(robot->write(0, 0.02), ReturnType::kOk);
  const size_t before = hw->writes.size();
  ASSERT_EQ(robot->read(0.1, 0.1), ReturnType::kOk);
  EXPECT_EQ(hw->writes.size(), before);  // still within the period
  ASSERT_EQ(robot->read(0.25, 0.15), ReturnType::kOk);
  ASSERT_GT(hw->writes.size(), before);
  EXPECT_TRUE(isZeroMotion(hw->writes.back().second));
  EXPECT_TRUE(robot->state().watchdog_tripped);
}

TEST_F(HalFixture, NonFiniteCommandIsAnErrorAndStops) {
  activate();
  commandEverything();
  ASSERT_EQ(robot->write(0, 0.02), ReturnType::kOk);
  robot->base().setVelocity(std::nan(""), 0);
  EXPECT_EQ(robot->write(0.02, 0.02), ReturnType::kError);
  EXPECT_TRUE(isZeroMotion(hw->writes.back().second));
  // A wrong-sized joint command is a caller bug: same treatment.
  commandEverything();
  robot->arm().setJointVelocity(Eigen::VectorXd::Zero(2));
  EXPECT_EQ(robot->write(0.04, 0.02), ReturnType::kError);
  EXPECT_TRUE(isZeroMotion(hw->writes.back().second));
}

TEST_F(HalFixture, DeviceErrorsStopTheRobot) {
  activate();
  commandEverything();
  ASSERT_EQ(robot->write(0, 0.02), ReturnType::kOk);
  hw->read_status = ReturnType::kError;
  EXPECT_EQ(robot->read(0.02, 0.02), ReturnType::kError);
  EXPECT_TRUE(isZeroMotion(hw->writes.back().second));

  hw->read_status = ReturnType::kOk;
  commandEverything();
  hw->write_status = ReturnType::kError;
  const size_t n = hw->writes.size();
  EXPECT_EQ(robot->write(0.04, 0.02), ReturnType::kError);
  ASSERT_EQ(hw->writes.size(), n + 2);  // the failed command, then the stop
  EXPECT_TRUE(isZeroMotion(hw->writes.back().second));

  hw->write_status = ReturnType::kOk;
  commandEverything();
  ASSERT_EQ(robot->write(0.06, 0.02), ReturnType::kOk);
  cam->status = ReturnType::kError;
  std::optional<StereoFrame> frame;
  EXPECT_EQ(robot->camera().grab(0.06, &frame), ReturnType::kError);
  EXPECT_FALSE(frame.has_value());
  EXPECT_TRUE(isZeroMotion(hw->writes.back().second));
}

// A device that does not report the capture state: the layer interpolates head joints, bMc and
// odometry at the frame's capture time from the states it read, not the state at grab time.
TEST_F(HalFixture, FramesCarryTheCameraPoseAtCaptureTime) {
  activate();
  hw->pan_rate = 0.4;
  for (int k = 0; k <= 10; ++k) ASSERT_EQ(robot->read(0.02 * k, 0.02), ReturnType::kOk);
  StereoFrame f;
  f.stamp = 0.07;  // between the reads at 0.06 and 0.08, grabbed at 0.20
  f.index = 3;
  cam->next = f;
  std::optional<StereoFrame> got;
  ASSERT_EQ(robot->camera().grab(0.2, &got), ReturnType::kOk);
  ASSERT_TRUE(got && got->capture.head && got->capture.bMc && got->capture.wMb_odom);
  EXPECT_NEAR(got->capture.head->pan_rad, 0.4 * 0.07, 1e-12);
  EXPECT_NEAR(robot->state().pan_rad, 0.4 * 0.2, 1e-12);
  EXPECT_NEAR(got->capture.wMb_odom->t.x(), 0.5 * 0.07, 1e-12);
  const Pose bMc = headCameraPose(model.head, 0.4 * 0.07, 0.0);
  EXPECT_LT(translationError(*got->capture.bMc, bMc), 1e-12);
  EXPECT_LT(rotationError(*got->capture.bMc, bMc), 1e-12);
  EXPECT_GT(rotationError(*got->capture.bMc, robot->head().bMc()), 0.05);  // head moved since
  EXPECT_EQ(got->frameStamp().index, 3);

  // A device that reports the head joints at capture is believed; before the first read and
  // after the last one the state is held.
  f.stamp = 5.0;
  f.capture.head = HeadJoints{-0.3, 0.1};
  cam->next = f;
  ASSERT_EQ(robot->camera().grab(0.2, &got), ReturnType::kOk);
  EXPECT_EQ(got->capture.head->pan_rad, -0.3);
  EXPECT_LT(rotationError(*got->capture.bMc, headCameraPose(model.head, -0.3, 0.1)), 1e-12);
  EXPECT_NEAR(got->capture.wMb_odom->t.x(), 0.5 * 0.2, 1e-12);
}

TEST_F(HalFixture, DeactivateStops) {
  activate();
  commandEverything();
  ASSERT_EQ(robot->write(0, 0.02), ReturnType::kOk);
  EXPECT_EQ(robot->deactivate(), ReturnType::kOk);
  EXPECT_TRUE(isZeroMotion(hw->writes.back().second));
  EXPECT_EQ(robot->lifecycle(), Lifecycle::kInactive);
}

TEST_F(HalFixture, LimitsAreAppliedInTheLayer) {
  activate();
  robot->base().setVelocity(3.0, 0);  // 10.8 km/h asked
  robot->head().setVelocity(9.0, -9.0);
  ASSERT_EQ(robot->write(0, 0.02), ReturnType::kOk);
  const RobotCommand& c = hw->writes.back().second;
  EXPECT_NEAR(c.base_v_mps, model.base.max_linear_speed_mps, 1e-12);
  EXPECT_NEAR(c.pan, model.head.pan.max_speed_radps, 1e-12);
  EXPECT_NEAR(c.tilt, -model.head.tilt.max_speed_radps, 1e-12);
  robot->head().setPosition(5.0, -5.0);
  ASSERT_EQ(robot->write(0.02, 0.02), ReturnType::kOk);
  EXPECT_EQ(hw->writes.back().second.head_mode, HeadMode::kPosition);
  EXPECT_NEAR(hw->writes.back().second.pan, model.head.pan.max_rad, 1e-12);
  EXPECT_NEAR(hw->writes.back().second.tilt, model.head.tilt.min_rad, 1e-12);
}

TEST_F(HalFixture, CartesianArmCommandsGoThroughDampedLeastSquares) {
  activate();
  ASSERT_EQ(robot->read(0, 0.02), ReturnType::kOk);  // q = 0.4 everywhere
  const ArmKinematics& kin = robot->arm().kinematics();
  const Eigen::VectorXd q = hw->q;
  const Jacobian J = kin.jacobian(q);
  // A twist the arm can produce exactly: J * qdot*.
  Eigen::VectorXd qdot_true(5);
  qdot_true << 0.05, -0.03, 0.04, 0.06, -0.02;
  const Twist bVe = Twist::fromVector(J * qdot_true);
  robot->arm().setVelocity(ArmFrame::kBase, bVe);
  ASSERT_EQ(robot->write(0, 0.02), ReturnType::kOk);
  const Eigen::VectorXd qdot_b = hw->writes.back().second.arm_qdot_radps;
  const double rel = (J * qdot_b - bVe.vector()).norm() / bVe.vector().norm();
  std::printf("DLS tracking error of a feasible twist: %.3f %%\n", 100 * rel);
  EXPECT_LT(rel, 0.05);
  // The same motion expressed in the gripper frame gives the same joint rates.
  const Pose bMe = kin.forward(q);
  Twist eVe;
  eVe.v = bMe.R.transpose() * bVe.v;
  eVe.w = bMe.R.transpose() * bVe.w;
  robot->arm().setVelocity(ArmFrame::kEndEffector, eVe);
  ASSERT_EQ(robot->write(0.02, 0.02), ReturnType::kOk);
  EXPECT_NEAR((hw->writes.back().second.arm_qdot_radps - qdot_b).norm(), 0, 1e-12);
  // A huge twist is scaled into the joint speed limits, direction kept.
  robot->arm().setVelocity(ArmFrame::kBase, Twist::fromVector(100 * bVe.vector()));
  ASSERT_EQ(robot->write(0.04, 0.02), ReturnType::kOk);
  const Eigen::VectorXd big = hw->writes.back().second.arm_qdot_radps;
  double worst = 0;
  for (int i = 0; i < 5; ++i)
    worst = std::max(worst, std::abs(big[i]) / model.arm.joints[static_cast<size_t>(i)].limits.max_speed_radps);
  EXPECT_NEAR(worst, 1.0, 1e-12);
  EXPECT_NEAR(big.normalized().dot(qdot_b.normalized()), 1.0, 1e-9);
}

TEST(RobotState, CsvRowMatchesHeader) {
  RobotState s;
  s.arm_q_rad = Eigen::VectorXd::Zero(5);
  s.arm_qdot_radps = Eigen::VectorXd::Zero(5);
  s.wMb_odom = Pose(axisAngle({0, 0, 1}, 0.25), Eigen::Vector3d(1, 2, 0));
  const std::string header = RobotState::csvHeader(5), row = s.csvRow();
  EXPECT_EQ(std::count(header.begin(), header.end(), ','), std::count(row.begin(), row.end(), ','));
  EXPECT_NE(row.find(",0.25,"), std::string::npos);
}

// ---- bad enon.yaml ---------------------------------------------------------------------------

namespace {

std::string shippedEnonText() {
  std::ifstream in(testing_util::enonPath());
  std::stringstream ss;
  ss << in.rdbuf();
  std::string text = ss.str();
  // Point the rig at the shipped one so the copy can live in a temporary directory.
  const std::string rig = "stereo_rig: cameras/bb2_rig.yaml";
  const size_t at = text.find(rig);
  if (at != std::string::npos) {
    const std::string abs =
        (std::filesystem::path(testing_util::enonPath()).parent_path() / "cameras/bb2_rig.yaml").string();
    text.replace(at, rig.size(), "stereo_rig: " + abs);
  }
  return text;
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

// Loads `text` as an enon file; returns the ConfigError message ("" if it loaded).
std::string loadError(const std::string& name, const std::string& text) {
  const std::string path = testing_util::writeTempFile(name, text);
  try {
    loadEnonModel(path);
  } catch (const ConfigError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    EXPECT_EQ(msg.rfind(path, 0), 0u) << msg;  // starts with the file name
    return msg;
  }
  return "";
}

}  // namespace

TEST(EnonYaml, ShippedModelLoadsAndCopyLoads) {
  const EnonModel m = testing_util::enonModel();
  EXPECT_EQ(m.arm.dof(), 5);
  EXPECT_EQ(m.head.rig.left.width, 640);
  EXPECT_NEAR(m.head.rig.baseline(), 0.12, 1e-9);
  EXPECT_EQ(loadError("enon_ok.yaml", shippedEnonText()), "");
}

TEST(EnonYaml, BadFilesGiveOneLineErrorsNamingFileAndField) {
  const std::string ok = shippedEnonText();
  try {
    loadEnonModel("/nonexistent/enon.yaml");
    ADD_FAILURE() << "missing file accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/enon.yaml: file not found"), std::string::npos);
  }
  EXPECT_NE(loadError("e1.yaml", "base: [1, 2\n  x: {").find("invalid YAML"), std::string::npos);
  // A DH row without d_m.
  EXPECT_NE(loadError("e2.yaml", replaced(ok, "d_m: 0.25, ", "")).find("arm.joints[2].d_m: missing"),
            std::string::npos);
  // Joint limits min > max.
  EXPECT_NE(loadError("e3.yaml", replaced(ok, "min_rad: 0.0, max_rad: 2.30", "min_rad: 2.5, max_rad: 2.30"))
                .find("arm.joints[3].limits: min_rad > max_rad"),
            std::string::npos);
  EXPECT_NE(loadError("e4.yaml", replaced(ok, "pan:  {min_rad: -1.57", "pan:  {min_rad: 2.0"))
                .find("head.pan: min_rad > max_rad"),
            std::string::npos);
  // NaN.
  EXPECT_NE(loadError("e5.yaml", replaced(ok, "track_width_m: 0.40", "track_width_m: .nan"))
                .find("base.track_width_m: must be finite"),
            std::string::npos);
  // Non-positive watchdog period.
  EXPECT_NE(loadError("e6.yaml", replaced(ok, "watchdog_period_s: 0.2", "watchdog_period_s: 0"))
                .find("watchdog_period_s: must be positive"),
            std::string::npos);
  EXPECT_NE(loadError("e7.yaml", replaced(ok, "watchdog_period_s: 0.2", "watchdog_period_s: -1"))
                .find("watchdog_period_s: must be positive"),
            std::string::npos);
  // Missing section, wrong type, non-positive speed limit, unknown arm side, missing rig file.
  EXPECT_NE(loadError("e8.yaml", replaced(ok, "gripper:\n", "grabber:\n")).find("gripper.close_time_s: missing"),
            std::string::npos);
  EXPECT_NE(loadError("e9.yaml", replaced(ok, "alpha_rad: 0.0,", "alpha_rad: ninety,"))
                .find("arm.joints[4].alpha_rad: expected a number"),
            std::string::npos);
  EXPECT_NE(loadError("e10.yaml", replaced(ok, "max_speed_radps: 1.5}}", "max_speed_radps: 0}}"))
                .find("arm.joints[4].limits.max_speed_radps: must be positive"),
            std::string::npos);
  EXPECT_NE(loadError("e11.yaml", replaced(ok, "side: right", "side: middle")).find("arm.side"),
            std::string::npos);
  const std::string rig_err = loadError("e12.yaml", replaced(ok, "bb2_rig.yaml", "no_such_rig.yaml"));
  EXPECT_NE(rig_err.find("no_such_rig.yaml"), std::string::npos) << rig_err;
  EXPECT_NE(loadError("e13.yaml", replaced(ok, "joints:\n", "joints: []\n  unused:\n"))
                .find("arm.joints"),
            std::string::npos);
}

TEST(EnonYaml, BadCollisionGeometryGivesOneLineErrors) {
  const std::string ok = shippedEnonText();
  const EnonModel m = testing_util::enonModel();
  EXPECT_EQ(m.base.body_radius_m, 0.25);
  EXPECT_EQ(m.arm.forearm.to_frame, 5);
  EXPECT_GT(m.gripper.open_width_m, 0.22);  // the widest evaluation box, with margin
  EXPECT_NE(loadError("g1.yaml", replaced(ok, "body: {radius_m: 0.25, height_m: 1.30}", ""))
                .find("base.body.radius_m: missing"),
            std::string::npos);
  EXPECT_NE(loadError("g2.yaml", replaced(ok, "body: {radius_m: 0.25,", "body: {radius_m: -0.25,"))
                .find("base.body.radius_m: must be positive"),
            std::string::npos);
  EXPECT_NE(loadError("g3.yaml", replaced(ok, "forearm: {from_frame: 3, to_frame: 5,", "forearm: {from_frame: 3, to_frame: 6,"))
                .find("arm.forearm.to_frame: expected a DH frame 4..5 (after from_frame)"),
            std::string::npos);
  EXPECT_NE(loadError("g4.yaml", replaced(ok, "upper_arm: {from_frame: 0, to_frame: 3,", "upper_arm: {from_frame: 3, to_frame: 3,"))
                .find("arm.upper_arm.to_frame: expected a DH frame 4..5"),
            std::string::npos);
  EXPECT_NE(loadError("g5.yaml", replaced(ok, "upper_arm: {from_frame: 0,", "upper_arm: {from_frame: 0.5,"))
                .find("arm.upper_arm.from_frame: expected an integer"),
            std::string::npos);
  EXPECT_NE(loadError("g6.yaml", replaced(ok, "radius_m: 0.03}", "radius_m: 0}"))
                .find("arm.forearm.radius_m: must be positive"),
            std::string::npos);
  EXPECT_NE(loadError("g7.yaml", replaced(ok, "open_width_m: 0.28", "open_width_m: wide"))
                .find("gripper.open_width_m: expected a number"),
            std::string::npos);
  EXPECT_NE(loadError("g8.yaml", replaced(ok, "finger_radius_m: 0.012", "finger_radius_m: .inf"))
                .find("gripper.finger_radius_m: must be finite"),
            std::string::npos);
  EXPECT_NE(loadError("g9.yaml", replaced(ok, "finger_length_m: 0.115", "finger_length_m: 0.08"))
                .find("gripper.finger_length_m: must exceed palm_offset_m"),
            std::string::npos);
  EXPECT_NE(loadError("g10.yaml", replaced(ok, "  palm_radius_m: 0.02", "")).find("gripper.palm_radius_m: missing"),
            std::string::npos);
  // Models built in code are checked too.
  EnonModel bad = m;
  bad.gripper.palm_offset_m = bad.gripper.finger_length_m;
  EXPECT_THROW(bad.check(), std::invalid_argument);
  bad = m;
  bad.arm.upper_arm.to_frame = 9;
  EXPECT_THROW(bad.check(), std::invalid_argument);
}

// Robot::replaceCamera: another camera before configure() (enon_grasp --camera), refused after.
TEST_F(HalFixture, TheCameraIsReplacedOnlyBeforeConfiguration) {
  auto other = std::make_unique<FakeCamera>();
  FakeCamera* second = other.get();
  second->next = StereoFrame();
  second->next->left = cv::Mat(4, 4, CV_8UC1, cv::Scalar(7));
  second->next->stamp = 0.0;
  EXPECT_THROW(robot->replaceCamera(nullptr), std::invalid_argument);
  robot->replaceCamera(std::move(other));
  activate();
  ASSERT_EQ(robot->read(0, 0.02), ReturnType::kOk);
  std::optional<StereoFrame> f;
  ASSERT_EQ(robot->camera().grab(0, &f), ReturnType::kOk);
  ASSERT_TRUE(f.has_value());
  EXPECT_EQ(f->left.at<uint8_t>(0, 0), 7);  // from the new camera
  EXPECT_TRUE(f->capture.bMc.has_value());   // filled by the layer as for the old one
  EXPECT_THROW(robot->replaceCamera(std::make_unique<FakeCamera>()), std::logic_error);
}
