// The grasp controller in-process on the simulated enon with the oracle estimator (ground truth,
// no rendering): a whole grasp, the safety rules on every iteration, and the failure paths
// (target lost mid-approach, exceptions in each phase, robot and camera errors) injected through
// test doubles of the estimator and of the robot hardware.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <stdexcept>

#include "common/format.h"
#include "grasp_run.h"
#include "robot/hal.h"
#include "servo/vision_estimator.h"

using namespace refgrasp;
using robot::ReturnType;
using refgrasp::testing::GraspRun;
using refgrasp::testing::isStopped;
using refgrasp::testing::loadTarget;
using refgrasp::testing::runGrasp;
using refgrasp::testing::Target;

namespace {

std::string scenarioPath(const std::string& name) {
  return refgrasp::testing::kSourceDir + "/config/scenarios/" + name + ".yaml";
}

/// The oracle, and a fault injected when `when` says so: lost (the target vanishes) or an
/// exception from observe().
struct FaultyEstimator : servo::TargetEstimator {
  servo::OracleEstimator inner;
  std::function<bool(const robot::StereoFrame&)> when;
  enum class Fault { kLost, kThrow, kTilted } fault = Fault::kLost;
  int faults = 0;
  FaultyEstimator(const detector::ObjectModel& o, Fault f) : inner(o), fault(f) {}
  servo::TargetObservation observe(const robot::StereoFrame& frame, const StereoRig& rig,
                                   const std::optional<Pose>& prior) override {
    if (when && when(frame)) {
      ++faults;
      if (fault == Fault::kThrow) throw std::runtime_error("injected estimator failure");
      if (fault == Fault::kTilted) {  // a confirmed pose 70 deg off about the face's x axis
        servo::TargetObservation o = inner.observe(frame, rig, prior);
        if (o.cMo) o.cMo = *o.cMo * Pose(axisAngle(Eigen::Vector3d::UnitX(), 70 * M_PI / 180), Eigen::Vector3d::Zero());
        return o;
      }
      servo::TargetObservation o;
      o.status = servo::TargetStatus::kLost;
      return o;
    }
    return inner.observe(frame, rig, prior);
  }
  void reset() override { inner.reset(); }
  std::string name() const override { return "faulty"; }
};

}  // namespace

// A whole grasp on table_single with the ground truth: every phase converges, the target is
// held at the end, no collision, no joint on a limit, and no motion on an unconfirmed target.
TEST(GraspController, OracleGraspsTheTargetOnTableSingle) {
  const Target target = loadTarget(scenarioPath("table_single"));
  servo::OracleEstimator oracle(target.object);
  const GraspRun r = runGrasp(target, oracle, {}, 60, /*render=*/false);
  EXPECT_TRUE(r.report.success) << r.report.failure << " " << r.error;
  EXPECT_TRUE(r.holding_target);
  EXPECT_TRUE(r.collisions.empty()) << r.collisions.front().message();
  EXPECT_TRUE(r.violations.empty()) << r.violations.front();
  EXPECT_GT(r.min_joint_margin_rad, 0.01);
  for (const char* phase : {"search", "approach", "align", "grasp"}) {
    ASSERT_EQ(r.report.phases.count(phase), 1u) << phase;
    EXPECT_GT(r.report.phases.at(phase).time_s, 0) << phase;
  }
  EXPECT_EQ(r.report.phases.at("search").outcome, "found");
  EXPECT_EQ(r.report.phases.at("approach").outcome, "converged");
  EXPECT_EQ(r.report.phases.at("align").outcome, "converged");
  EXPECT_EQ(r.report.phases.at("grasp").outcome, "holding");
  // Closed on the grasp frame: the controller's estimate and the simulator agree within mm.
  EXPECT_LT(r.report.close_position_error_m, 0.005);
  EXPECT_LT(r.report.close_rotation_error_rad, 2 * M_PI / 180);
  ASSERT_TRUE(r.final_grasp_error.has_value());
  EXPECT_LT(r.final_grasp_error->position_m, 0.005);
  EXPECT_LT(r.final_grasp_error->rotation_rad, 2 * M_PI / 180);
  EXPECT_LT(r.sim_time_s, 30);
}

// room_aerial_across: a 12 cm tall box 12 cm behind a table's edge, turned 20 deg. From the base
// pose whose arm reaches the pre-grasp pose, a base share of the last 12 cm puts the body against
// the table (before these rules: a collision with table_1 on every seed, oracle and vision). By
// default the base stays in the final approach and the arm slides the gripper on; with the base
// taking its share (final_approach_base), the map's guard stops it with its body
// fixture_clearance_m from the table and the arm reaches the rest, the log saying where.
TEST(GraspController, TheBaseStopsAtATableAndTheArmReachesTheRest) {
  const Target target = loadTarget(scenarioPath("room_aerial_across"));
  const robot::EnonModel model = robot::loadEnonModel(refgrasp::testing::kSourceDir + "/config/enon.yaml");
  for (const bool base_in_final_approach : {false, true}) {
    SCOPED_TRACE(base_in_final_approach ? "final_approach_base" : "defaults");
    servo::OracleEstimator oracle(target.object);
    servo::GraspOptions options;
    options.final_approach_base = base_in_final_approach;
    const servo::Footprint* table = nullptr;
    const servo::GraspOptions with_room = grasp_app::withRoom(options, target.scenario, target.extent_o);
    for (const servo::RoomFixture& f : with_room.room.fixtures)
      if (f.name == "table_1") table = &f.footprint;
    ASSERT_NE(table, nullptr);
    double nearest = 1e9, final_approach_advance = 0;
    std::optional<Pose> reach_start;
    std::string held;
    const GraspRun r = runGrasp(target, oracle, options, 90, /*render=*/false,
                                [&](const servo::GraspStep& s, const sim::SimEnon& sim) {
                                  const Pose wMb = sim.wMb();
                                  nearest = std::min(nearest, table->distance(wMb.t.head<2>()));
                                  if (s.it.event.rfind("base held", 0) == 0) held = s.it.event;
                                  if (s.it.phase == servo::GraspPhase::kGrasp && s.it.detail == "reach") {
                                    if (!reach_start) reach_start = wMb;
                                    final_approach_advance = std::max(
                                        final_approach_advance, (reach_start->inverse() * wMb).t.x());
                                  }
                                  return true;
                                });
    EXPECT_TRUE(r.report.success) << r.report.failure << " " << r.error;
    EXPECT_TRUE(r.holding_target);
    EXPECT_TRUE(r.collisions.empty()) << r.collisions.front().message();
    EXPECT_TRUE(r.violations.empty()) << r.violations.front();
    EXPECT_EQ(r.report.phases.at("grasp").outcome, "holding");
    const double clearance = nearest - model.base.body_radius_m;
    std::printf("%s: the body's nearest approach to table_1 %.4f m, the base's advance in the final "
                "approach %.4f m, grasp phase %.2f s\n", base_in_final_approach ? "final_approach_base" : "defaults",
                clearance, final_approach_advance, r.report.phases.at("grasp").time_s);
    ASSERT_TRUE(reach_start.has_value());
    if (!base_in_final_approach) {
      EXPECT_LT(final_approach_advance, 0.001);
      EXPECT_TRUE(held.empty()) << held;
      EXPECT_GT(clearance, 0.05);
    } else {
      EXPECT_GT(final_approach_advance, 0.03);
      EXPECT_EQ(held, "base held: its body would come within 0.020 m of table_1");
      EXPECT_GT(clearance, options.fixture_clearance_m - 0.005);  // odometry drift: a few mm
      EXPECT_LT(clearance, options.fixture_clearance_m + 0.02);   // the guard, not the plan, held it
    }
  }
}

// room_hotel_corner (odometry noise): the base pose whose arm reaches the pre-grasp pose would put
// the body within fixture_clearance_m of the table in the robot's map; the goal is moved back along
// its heading until clear (before: the guard held the base 1 cm short of it and the approach timed
// out on seed 0; before the guard, the base share of the final approach hit the table on seeds 3,
// 4, 6, 7 and 8). Every seed here: approach converged, grasped, no collision, and the body's true
// distance to the table stays above the clearance less the odometry's drift.
TEST(GraspController, AnApproachGoalAtATableIsMovedBackClearOfIt) {
  const robot::EnonModel model = robot::loadEnonModel(refgrasp::testing::kSourceDir + "/config/enon.yaml");
  for (const uint64_t seed : {0, 3, 4}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const Target target = loadTarget(scenarioPath("room_hotel_corner"), seed);
    servo::OracleEstimator oracle(target.object);
    const servo::GraspOptions options;
    const servo::GraspOptions with_room = grasp_app::withRoom(options, target.scenario, target.extent_o);
    const servo::Footprint* table = nullptr;
    for (const servo::RoomFixture& f : with_room.room.fixtures)
      if (f.name == "table_1") table = &f.footprint;
    ASSERT_NE(table, nullptr);
    double nearest = 1e9;
    const GraspRun r = runGrasp(target, oracle, options, 90, /*render=*/false,
                                [&](const servo::GraspStep&, const sim::SimEnon& sim) {
                                  nearest = std::min(nearest, table->distance(sim.wMb().t.head<2>()));
                                  return true;
                                });
    EXPECT_TRUE(r.report.success) << r.report.failure << " " << r.error;
    EXPECT_TRUE(r.collisions.empty()) << r.collisions.front().message();
    EXPECT_TRUE(r.violations.empty()) << r.violations.front();
    ASSERT_EQ(r.report.phases.count("approach"), 1u);
    EXPECT_EQ(r.report.phases.at("approach").outcome, "converged");
    const double clearance = nearest - model.base.body_radius_m;
    std::printf("seed %d: the body's nearest true approach to table_1 %.4f m\n", static_cast<int>(seed), clearance);
    EXPECT_GT(clearance, 0.0);
  }
}

// The target vanishes mid-approach: the robot is stopped in the very period the estimator says
// so (zero base, arm and head commands, and the simulated base stops), it holds still while
// the target stays lost, and after reacquire_timeout_s it searches again, finds the target and
// grasps it.
TEST(GraspController, LosingTheTargetMidApproachStopsTheRobotWithinOnePeriod) {
  const Target target = loadTarget(scenarioPath("table_single"));
  FaultyEstimator est(target.object, FaultyEstimator::Fault::kLost);
  Seconds lose_from = -1, lose_until = -1;
  bool approaching = false;
  est.when = [&](const robot::StereoFrame& f) {
    return lose_from >= 0 && f.stamp >= lose_from && f.stamp < lose_until;
  };
  Seconds lost_at = -1;
  int stopped_steps = 0, moving_while_lost = 0;
  servo::GraspOptions o;
  const auto hook = [&](const servo::GraspStep& s, const sim::SimEnon& sim) {
    const servo::GraspIteration& it = s.it;
    if (!approaching && it.phase == servo::GraspPhase::kApproach && it.detail == "along_line") {
      approaching = true;  // mid-approach, the base driving: the target goes for 1 s
      lose_from = it.t;
      lose_until = it.t + 1.0;
    }
    if (lost_at < 0 && it.observed == servo::TargetStatus::kLost && approaching) {
      lost_at = it.t;
      EXPECT_TRUE(isStopped(it.command)) << "t=" << it.t;
      EXPECT_EQ(it.command.head_mode, robot::HeadMode::kVelocity);
    }
    if (lost_at >= 0 && it.t < lose_until) {
      ++stopped_steps;
      if (!isStopped(it.command)) ++moving_while_lost;
      // One period after the loss the simulated base has stopped (no command latency here).
      if (it.t > lost_at + 1e-9) {
        EXPECT_EQ(it.state.base_v_mps, 0) << "t=" << it.t;
        EXPECT_EQ(it.state.base_w_radps, 0) << "t=" << it.t;
      }
    }
    (void)sim;
    return true;
  };
  const GraspRun r = runGrasp(target, est, o, 60, false, hook);
  ASSERT_GE(lost_at, 0);
  EXPECT_GT(stopped_steps, 10);
  EXPECT_EQ(moving_while_lost, 0);
  EXPECT_TRUE(r.violations.empty()) << r.violations.front();
  EXPECT_TRUE(r.report.success) << r.report.failure;  // it comes back and grasps
}

// Lost for longer than reacquire_timeout_s: back to the search (phase outcome "lost"), which
// looks first where the target was last seen, with the head only (the base, next to the table
// with the arm out, neither turns nor drives), finds it again, and the run still grasps it.
TEST(GraspController, ATargetLostForLongReturnsToTheSearch) {
  const Target target = loadTarget(scenarioPath("table_single"));
  FaultyEstimator est(target.object, FaultyEstimator::Fault::kLost);
  Seconds lose_from = -1;
  bool searching_again = false;  // the target comes back once the controller searches again
  est.when = [&](const robot::StereoFrame& f) {
    return lose_from >= 0 && f.stamp >= lose_from && !searching_again;
  };
  servo::GraspOptions o;
  o.reacquire_timeout_s = 1.0;
  const auto hook = [&](const servo::GraspStep& s, const sim::SimEnon&) {
    if (lose_from < 0 && s.it.phase == servo::GraspPhase::kAlign) lose_from = s.it.t;
    if (lose_from >= 0 && s.it.phase == servo::GraspPhase::kSearch) searching_again = true;
    if (s.it.phase == servo::GraspPhase::kSearch && lose_from >= 0) {
      EXPECT_EQ(s.it.command.base_v_mps, 0);  // the search after the loss: head only
      EXPECT_EQ(s.it.command.base_w_radps, 0);
    }
    return true;
  };
  const GraspRun r = runGrasp(target, est, o, 60, false, hook);
  EXPECT_EQ(r.report.searches, 2);
  EXPECT_EQ(r.report.phases.at("align").outcome, "converged");  // the second time
  EXPECT_TRUE(r.violations.empty()) << r.violations.front();
  EXPECT_TRUE(r.report.success) << r.report.failure;
}

// An exception from the estimator in any phase (and in each step of the grasp) stops every
// actuator at once: step() returns kError with one line, the command written is zero, the
// simulated robot stands still afterwards, and later steps keep it stopped with the same error.
TEST(GraspController, AnExceptionInAnyPhaseStopsTheRobot) {
  const Target target = loadTarget(scenarioPath("table_single"));
  for (const std::string phase : {"search", "approach", "align", "grasp"}) {
    FaultyEstimator est(target.object, FaultyEstimator::Fault::kThrow);
    servo::GraspPhase current = servo::GraspPhase::kDone;  // set by the first step
    Seconds started = -1;
    est.when = [&](const robot::StereoFrame& f) {
      // Half a second into the phase (the search: its second look).
      return toString(current) == phase && started >= 0 && f.stamp > started + 0.5;
    };
    servo::GraspStep failed;
    const auto hook = [&](const servo::GraspStep& s, const sim::SimEnon&) {
      if (s.it.phase != current) {
        current = s.it.phase;
        started = s.it.t;
      }
      if (s.status == ReturnType::kError) {
        failed = s;
        return false;
      }
      return true;
    };
    const GraspRun r = runGrasp(target, est, {}, 60, false, hook);
    ASSERT_EQ(failed.status, ReturnType::kError) << phase;
    EXPECT_EQ(est.faults, 1) << phase;
    EXPECT_NE(failed.error.find("injected estimator failure"), std::string::npos) << failed.error;
    EXPECT_EQ(failed.error.find('\n'), std::string::npos);
    EXPECT_TRUE(isStopped(failed.it.command)) << phase;
    EXPECT_EQ(r.report.phases.at(phase).outcome, "error") << phase;
    EXPECT_FALSE(r.report.success);
  }
}

namespace {

/// Hardware that fails (kError or an exception) from a given time on.
struct FailingHardware : robot::RobotHardware {
  std::unique_ptr<sim::SimEnon> inner;
  Seconds fail_at = 1e9;
  bool throws = false;
  robot::ReturnType configure() override { return inner->configure(); }
  robot::ReturnType activate() override { return inner->activate(); }
  robot::ReturnType deactivate() override { return inner->deactivate(); }
  robot::ReturnType read(Seconds t, Seconds p, robot::RobotState* s) override {
    const ReturnType r = inner->read(t, p, s);
    if (t < fail_at) return r;
    if (throws) throw std::runtime_error("injected hardware exception");
    return ReturnType::kError;
  }
  robot::ReturnType write(Seconds t, Seconds p, const robot::RobotCommand& c, Seconds v) override {
    return inner->write(t, p, c, v);
  }
};

}  // namespace

// A robot read that fails or throws mid-approach stops the robot: kError with one line naming
// it, the zero command reaches the simulated enon, and it stands still from then on.
TEST(GraspController, RobotErrorsAndExceptionsStopTheRobot) {
  const Target target = loadTarget(scenarioPath("table_single"));
  const robot::EnonModel model = robot::loadEnonModel(refgrasp::testing::kSourceDir + "/config/enon.yaml");
  for (const bool throws : {false, true}) {
    auto hw = std::make_unique<FailingHardware>();
    hw->inner = std::make_unique<sim::SimEnon>(model, target.scenario);
    hw->inner->setRenderImages(false);
    hw->throws = throws;
    sim::SimEnon* sim = hw->inner.get();
    auto cam = sim->makeCamera();
    FailingHardware* failing = hw.get();
    robot::Robot robot(model, std::move(hw), std::move(cam));
    ASSERT_EQ(robot.configure(), ReturnType::kOk);
    ASSERT_EQ(robot.activate(), ReturnType::kOk);
    servo::OracleEstimator oracle(target.object);
    servo::GraspController ctl(robot, oracle, target.world().oMg, target.extent_o);
    const double dt = model.control_period_s;
    servo::GraspStep s;
    double t = 0;
    for (; t < 30 && s.status == ReturnType::kOk; t += dt) {
      if (failing->fail_at > 1e8 && ctl.phase() == servo::GraspPhase::kApproach)
        failing->fail_at = t + 1.0;  // the base is driving by then
      s = ctl.step(t, dt);
    }
    ASSERT_EQ(s.status, ReturnType::kError);
    EXPECT_NE(s.error.find(throws ? "injected hardware exception" : "robot read failed"),
              std::string::npos) << s.error;
    EXPECT_TRUE(isStopped(robot.lastCommand()));
    const robot::PlanarPose p0 = sim->trueBasePose();
    for (int k = 0; k < 10; ++k, t += dt) {
      const servo::GraspStep again = ctl.step(t, dt);
      EXPECT_EQ(again.status, ReturnType::kError);
      EXPECT_EQ(again.error, s.error);
    }
    robot::RobotState st;
    sim->read(t, dt, &st);
    EXPECT_NEAR(sim->trueBasePose().x_m, p0.x_m, 1e-9);
    EXPECT_NEAR(sim->trueBasePose().y_m, p0.y_m, 1e-9);
    EXPECT_EQ(st.base_v_mps, 0);
  }
}

// The object's extent from each definition form (what the head centres and the pre-grasp
// clearance is measured from): a plane's pattern, a cylinder's solid, a box of five faces.
TEST(GraspController, TheObjectExtentOfEachDefinitionForm) {
  const Target plane = loadTarget(scenarioPath("table_single"));
  const auto& q = plane.object.target->corners_o;
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(plane.extent_o.min_o[i], std::min({q[0][i], q[1][i], q[2][i], q[3][i]}), 1e-12);
    EXPECT_NEAR(plane.extent_o.max_o[i], std::max({q[0][i], q[1][i], q[2][i], q[3][i]}), 1e-12);
  }
  EXPECT_NEAR(plane.extent_o.depthBehind(plane.world().oMg), 0.0, 1e-12);  // behind the pattern: outside

  const Target can = loadTarget(scenarioPath("can_table"));  // r 0.033, label 0.115 high
  EXPECT_LT((can.extent_o.min_o - Eigen::Vector3d(-0.033, -0.0575, 0)).norm(), 1e-9);
  EXPECT_LT((can.extent_o.max_o - Eigen::Vector3d(0.033, 0.0575, 0.066)).norm(), 1e-9);
  EXPECT_LT((can.extent_o.centre() - Eigen::Vector3d(0, 0, 0.033)).norm(), 1e-9);  // on the axis
  EXPECT_NEAR(can.extent_o.depthBehind(can.world().oMg), 0.033, 1e-9);  // axis to label surface

  // 0.1744 x 0.12 x 0.16 m, its frame the front face's; grasped from the back (z_g = -z_o),
  // 4 cm inside it.
  const Target box = loadTarget(scenarioPath("box_cookie_turned"));
  EXPECT_LT((box.extent_o.min_o - Eigen::Vector3d(-0.0872, -0.06, 0)).norm(), 1e-4);
  EXPECT_LT((box.extent_o.max_o - Eigen::Vector3d(0.0872, 0.06, 0.16)).norm(), 1e-4);
  EXPECT_NEAR(box.extent_o.depthBehind(box.world().oMg), 0.04, 1e-4);
  const robot::EnonModel model = robot::loadEnonModel(refgrasp::testing::kSourceDir + "/config/enon.yaml");
  auto robot = sim::makeSimRobot(model, box.scenario);
  servo::OracleEstimator oracle(box.object);
  servo::GraspOptions o;
  o.pregrasp_clearance_m = 0.1;
  EXPECT_NEAR(servo::GraspController(*robot, oracle, box.world().oMg, box.extent_o, o).pregraspDistance(), 0.14, 1e-4);
  o.pregrasp_clearance_m = 0.02;  // the options' distance when it is the larger
  EXPECT_NEAR(servo::GraspController(*robot, oracle, box.world().oMg, box.extent_o, o).pregraspDistance(), 0.12, 1e-12);

  detector::ObjectModel flat2d;
  flat2d.name = "flat2d";
  EXPECT_THROW(servo::objectExtent(flat2d), std::invalid_argument);
}

// Bad options are refused at construction, one line naming the field.
TEST(GraspController, BadOptionsThrowNamingTheField) {
  const Target target = loadTarget(scenarioPath("table_single"));
  const robot::EnonModel model = robot::loadEnonModel(refgrasp::testing::kSourceDir + "/config/enon.yaml");
  auto robot = sim::makeSimRobot(model, target.scenario);
  servo::OracleEstimator oracle(target.object);
  const auto expectThrow = [&](servo::GraspOptions o, const std::string& field) {
    try {
      servo::GraspController c(*robot, oracle, target.world().oMg, target.extent_o, o);
      ADD_FAILURE() << "accepted bad " << field;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  servo::GraspOptions o;
  o.pregrasp_distance_m = -1;
  expectThrow(o, "GraspOptions.pregrasp_distance_m");
  o = {};
  o.pregrasp_clearance_m = -0.01;
  expectThrow(o, "GraspOptions.pregrasp_clearance_m");
  o = {};
  o.frame_period_s = std::nan("");
  expectThrow(o, "GraspOptions.frame_period_s");
  o = {};
  o.arm.base_weight = -1;
  expectThrow(o, "ArmAlignOptions.base_weight");
  o = {};
  o.search.max_viewpoints = -1;
  expectThrow(o, "SearchPlanOptions.max_viewpoints");
  o = {};
  o.head.gain.at_zero = 0;
  expectThrow(o, "HeadPointingOptions.gain.at_zero");
  o = {};
  o.unreachable_patience_s = std::nan("");
  expectThrow(o, "GraspOptions.unreachable_patience_s");
  o = {};
  o.fixture_clearance_m = std::nan("");
  expectThrow(o, "GraspOptions.fixture_clearance_m");
  o = {};
  o.fixture_clearance_m = -0.01;
  expectThrow(o, "GraspOptions.fixture_clearance_m");
}

namespace {

/// A camera that works for `good` grabs, then fails (a device error) or delivers a wrong-sized
/// frame.
struct FlakyCamera : robot::StereoSource {
  std::unique_ptr<robot::StereoSource> inner;
  int good = 0;
  bool wrong_size = false;
  const StereoRig& rig() const override { return inner->rig(); }
  ReturnType grab(Seconds t, std::optional<robot::StereoFrame>* f) override {
    const ReturnType r = inner->grab(t, f);
    if (!*f || good-- > 0 || r != ReturnType::kOk) return r;
    if (!wrong_size) return ReturnType::kError;
    (*f)->left = cv::Mat(240, 320, CV_8UC1, cv::Scalar(0));
    (*f)->right = (*f)->left;
    return ReturnType::kOk;
  }
};

}  // namespace

// A camera error, and a frame the vision cannot use (the wrong size), mid-approach: kError with
// one line ("camera failed" / the frame's problem), the robot stopped, and it stays stopped.
TEST(GraspController, CameraErrorsAndUnusableFramesStopTheRobot) {
  const Target target = loadTarget(scenarioPath("table_single"));
  const robot::EnonModel model = robot::loadEnonModel(refgrasp::testing::kSourceDir + "/config/enon.yaml");
  for (const bool wrong_size : {false, true}) {
    auto hw = std::make_unique<sim::SimEnon>(model, target.scenario);
    auto cam = std::make_unique<FlakyCamera>();
    cam->inner = hw->makeCamera();
    cam->good = 12;  // the search's looks and the start of the approach
    cam->wrong_size = wrong_size;
    robot::Robot robot(model, std::move(hw), std::move(cam));
    ASSERT_EQ(robot.configure(), ReturnType::kOk);
    ASSERT_EQ(robot.activate(), ReturnType::kOk);
    detector::Detector det;
    servo::VisionEstimator vision(det, det.addObject(target.object));
    servo::GraspController ctl(robot, vision, target.world().oMg, target.extent_o);
    const double dt = model.control_period_s;
    servo::GraspStep s;
    double t = 0;
    for (; t < 30 && s.status == ReturnType::kOk; t += dt) s = ctl.step(t, dt);
    ASSERT_EQ(s.status, ReturnType::kError) << "wrong_size " << wrong_size;
    EXPECT_EQ(s.error.find('\n'), std::string::npos);
    EXPECT_NE(s.error.find(wrong_size ? "the camera calibration is 640x480" : "camera failed"),
              std::string::npos)
        << s.error;
    EXPECT_TRUE(isStopped(robot.lastCommand()));
    EXPECT_EQ(ctl.step(t, dt).error, s.error);
    EXPECT_TRUE(isStopped(robot.lastCommand()));
  }
}

// A far estimate is not judged: on photo_fruits_far (the photograph 2.2 m from the start) the
// estimates are tilted 70 deg (no arm configuration reaches that pre-grasp pose) while the base is
// more than 1.8 m from the target. Instead of ending "unreachable" where it stands, the base
// drives towards the target (detail "closer", confirmed frames only) and the estimates made from
// there, right again, lead to the grasp.
TEST(GraspController, AnUnreachableEstimateFromAfarDrivesCloserBeforeItIsJudged) {
  const Target target = loadTarget(scenarioPath("photo_fruits_far"));
  FaultyEstimator est(target.object, FaultyEstimator::Fault::kTilted);
  est.when = [&](const robot::StereoFrame& f) {
    if (f.truth.empty() || !f.capture.wMb_odom || !f.capture.bMc) return false;
    const Pose wMo = *f.capture.wMb_odom * *f.capture.bMc * f.truth.front().cMo;
    return (wMo.t - f.capture.wMb_odom->t).head<2>().norm() > 1.8;
  };
  int closer = 0;
  double first_range = -1, last_range = -1;
  const auto hook = [&](const servo::GraspStep& s, const sim::SimEnon&) {
    const servo::GraspIteration& it = s.it;
    if (it.detail == "closer" && it.wMo) {
      ++closer;
      const double range = (it.wMo->t - it.state.wMb_odom.t).head<2>().norm();
      if (first_range < 0) first_range = range;
      last_range = range;
    }
    return true;
  };
  servo::GraspOptions o;
  const GraspRun r = runGrasp(target, est, o, 60, false, hook);
  SCOPED_TRACE(refgrasp::testing::formatted("%d steps closer, %.2f -> %.2f m, %d tilted estimates, outcome %s",
                                            closer, first_range, last_range, est.faults,
                                            r.report.success ? "grasped" : r.report.failure.c_str()));
  EXPECT_GT(est.faults, 0);
  EXPECT_GT(closer, 5);
  EXPECT_GT(first_range, o.reestimate_range_m);
  EXPECT_LT(last_range, first_range - 0.2);
  EXPECT_TRUE(r.violations.empty()) << r.violations.front();
  EXPECT_TRUE(r.collisions.empty()) << r.collisions.front().message();
  EXPECT_TRUE(r.report.success) << r.report.failure;
}

// One poor estimate must not end the run: the estimates that confirm the target and start the
// approach are tilted 70 deg (no arm configuration reaches that pre-grasp pose) until 0.5 s into
// the approach; the robot holds still meanwhile (no target-driven motion towards an unreachable
// goal), then approaches with the right estimates and grasps. Tilted for good, the approach
// ends "unreachable" after unreachable_patience_s, the robot stopped.
TEST(GraspController, AnUnreachableEstimateEndsTheRunOnlyWhenItPersists) {
  const Target target = loadTarget(scenarioPath("table_single"));
  for (const bool for_good : {false, true}) {
    FaultyEstimator est(target.object, FaultyEstimator::Fault::kTilted);
    Seconds approach_at = -1;
    est.when = [&](const robot::StereoFrame& f) {
      return for_good || approach_at < 0 || f.stamp < approach_at + 0.5;
    };
    int waiting = 0, moving_while_waiting = 0;
    const auto hook = [&](const servo::GraspStep& s, const sim::SimEnon&) {
      const servo::GraspIteration& it = s.it;
      if (approach_at < 0 && it.phase == servo::GraspPhase::kApproach) approach_at = it.t;
      if (it.detail == "unreachable") {
        ++waiting;
        if (!isStopped(it.command)) ++moving_while_waiting;
      }
      return true;
    };
    servo::GraspOptions o;
    const GraspRun r = runGrasp(target, est, o, 60, false, hook);
    SCOPED_TRACE(refgrasp::testing::formatted("%s: %d steps waiting for a reachable estimate, outcome %s",
                                              for_good ? "tilted for good" : "tilted 0.5 s", waiting,
                                              r.report.success ? "grasped" : r.report.failure.c_str()));
    ASSERT_GT(approach_at, 0);
    EXPECT_GT(waiting, 5);
    EXPECT_EQ(moving_while_waiting, 0);
    EXPECT_TRUE(r.violations.empty()) << r.violations.front();
    if (for_good) {
      EXPECT_FALSE(r.report.success);
      EXPECT_EQ(r.report.phases.at("approach").outcome, "unreachable");
      EXPECT_GE(r.report.phases.at("approach").time_s, o.unreachable_patience_s);
      EXPECT_LT(r.report.phases.at("approach").time_s, o.unreachable_patience_s + 0.2);
    } else {
      EXPECT_TRUE(r.report.success) << r.report.failure;
    }
  }
}
