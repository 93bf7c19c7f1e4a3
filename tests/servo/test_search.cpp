// The search controller in-process on the simulated enon: it finds the target outside the initial
// view with stop-and-look sweeps, stops the robot when found, and stops it on every error path.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "detector/detector.h"
#include "robot/enon_model.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"
#include "servo/search.h"

using namespace refgrasp;
using robot::ReturnType;

namespace {

const std::string kSource = REFGRASP_SOURCE_DIR;

bool stopped(const robot::RobotCommand& c) {
  return c.base_v_mps == 0 && c.base_w_radps == 0 && c.arm_qdot_radps.isZero(0) &&
         (c.head_mode == robot::HeadMode::kVelocity ? c.pan == 0 && c.tilt == 0 : true);
}

struct World {
  robot::EnonModel model = robot::loadEnonModel(kSource + "/config/enon.yaml");
  sim::Scenario scenario;
  int target = -1;
  detector::Detector det;
  int id = -1;
  explicit World(const std::string& name)
      : scenario(sim::loadScenario(kSource + "/config/scenarios/" + name + ".yaml")) {
    for (size_t i = 0; i < scenario.world.objects.size(); ++i)
      if (scenario.world.objects[i].is_target) target = static_cast<int>(i);
    id = det.addObject(detector::loadObjectDefinition(scenario.world.objects[target].definition));
  }
};

// A camera that works for `good` grabs, then fails (a device error) or delivers a wrong-sized
// frame (the detector rejects it).
struct FlakyCamera : robot::StereoSource {
  std::unique_ptr<robot::StereoSource> inner;
  int good = 0;
  bool wrong_size = false;
  const StereoRig& rig() const override { return inner->rig(); }
  ReturnType grab(Seconds t, std::optional<robot::StereoFrame>* f) override {
    const ReturnType r = inner->grab(t, f);
    if (good-- > 0 || r != ReturnType::kOk) return r;
    if (!wrong_size) return ReturnType::kError;
    if (*f) (*f)->left = cv::Mat(240, 320, CV_8UC1, cv::Scalar(0));
    return ReturnType::kOk;
  }
};

}  // namespace

TEST(Search, PanOrderIsStraightThenAlternatelyLeftAndRight) {
  World w("table_single");
  auto robot = sim::makeSimRobot(w.model, w.scenario);
  servo::SearchOptions o;
  o.pan_step_rad = 0.5;
  const servo::SearchController s(*robot, w.det, w.id, o);
  const std::vector<double> want{0, 0.5, -0.5, 1.0, -1.0, 1.5, -1.5};  // limits are +-1.57
  ASSERT_EQ(s.pans().size(), want.size());
  for (size_t i = 0; i < want.size(); ++i) EXPECT_NEAR(s.pans()[i], want[i], 1e-12);
  o.pan_step_rad = 0;
  EXPECT_THROW(servo::SearchController(*robot, w.det, w.id, o), std::invalid_argument);
  EXPECT_THROW(servo::SearchController(*robot, w.det, 5, {}), std::invalid_argument);
}

// table_single: the target is 40 deg to the left, outside the initial view. Found on the look
// towards +0.45 rad (the second), pose within 1 % of the distance and 2 deg of the truth, and the
// robot is stopped from the step that found it on.
TEST(Search, FindsTheTargetOutsideTheInitialViewAndStops) {
  World w("table_single");
  auto robot = sim::makeSimRobot(w.model, w.scenario);
  auto& simenon = dynamic_cast<sim::SimEnon&>(robot->hardware());
  ASSERT_EQ(robot->configure(), ReturnType::kOk);
  ASSERT_EQ(robot->activate(), ReturnType::kOk);
  servo::SearchController search(*robot, w.det, w.id);
  const double dt = w.model.control_period_s;
  std::optional<servo::SearchLook> found;
  int looks = 0;
  for (double t = 0; t < 30 && !found; t += dt) {
    const servo::SearchStep s = search.step(t, dt);
    ASSERT_EQ(s.status, ReturnType::kOk) << s.error;
    if (s.look) {
      ++looks;
      EXPECT_EQ(s.look->number, looks);
      ASSERT_TRUE(s.look->frame.capture.bMc.has_value());
      EXPECT_GE(s.look->frame.stamp, t - 0.1);
      if (s.look->found()) found = s.look;
    }
  }
  ASSERT_TRUE(found.has_value());
  EXPECT_EQ(search.phase(), servo::SearchPhase::kFound);
  EXPECT_EQ(looks, 2);
  ASSERT_NE(simenon.lastFrame(), nullptr);
  const Pose truth = simenon.lastFrame()->left_cMo.at(w.target);
  const Pose& lMo = *found->detection.fused.lMo;
  EXPECT_LT(translationError(lMo, truth), 0.01 * truth.t.norm());
  EXPECT_LT(rotationError(lMo, truth), 2 * M_PI / 180);
  EXPECT_TRUE(stopped(robot->lastCommand()));
  const servo::SearchStep after = search.step(30, dt);  // a finished search only holds still
  EXPECT_EQ(after.status, ReturnType::kOk);
  EXPECT_TRUE(stopped(robot->lastCommand()));
}

TEST(Search, ErrorsStopTheRobotWithOneLine) {
  for (const bool wrong_size : {false, true}) {
    World w("table_single");
    auto hw = std::make_unique<sim::SimEnon>(w.model, w.scenario);
    auto cam = std::make_unique<FlakyCamera>();
    cam->inner = hw->makeCamera();
    cam->good = 20;
    cam->wrong_size = wrong_size;
    robot::Robot robot(w.model, std::move(hw), std::move(cam));
    ASSERT_EQ(robot.configure(), ReturnType::kOk);
    ASSERT_EQ(robot.activate(), ReturnType::kOk);
    servo::SearchOptions o;
    o.settle_s = 0;
    servo::SearchController search(robot, w.det, w.id, o);
    const double dt = w.model.control_period_s;
    servo::SearchStep s;
    double t = 0;
    for (; t < 10 && s.status == ReturnType::kOk; t += dt) s = search.step(t, dt);
    ASSERT_EQ(s.status, ReturnType::kError) << "wrong_size " << wrong_size;
    EXPECT_EQ(s.phase, servo::SearchPhase::kError);
    EXPECT_EQ(s.error.find('\n'), std::string::npos);
    EXPECT_NE(s.error.find(wrong_size ? "differs from the camera" : "camera failed"),
              std::string::npos)
        << s.error;
    EXPECT_TRUE(stopped(robot.lastCommand()));
    EXPECT_EQ(search.step(t, dt).error, s.error);  // stays stopped, same error
    EXPECT_TRUE(stopped(robot.lastCommand()));
  }
}
