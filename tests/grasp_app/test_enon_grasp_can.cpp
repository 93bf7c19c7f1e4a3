// A can grasped from the side (config/scenarios/can_table.yaml) with the simulator's ground truth:
// in process through the grasp controller, with the safety rules checked on every iteration, and
// through enon_grasp's session as its command line runs it.
#include <gtest/gtest.h>

#include <cmath>

#include "grasp/enon_grasp.h"
#include "servo/grasp_run.h"

using namespace refgrasp;
using refgrasp::testing::GraspRun;
using refgrasp::testing::loadTarget;
using refgrasp::testing::runGrasp;
using refgrasp::testing::Target;

namespace {

const std::string kCanTable = std::string(REFGRASP_SOURCE_DIR) + "/config/scenarios/can_table.yaml";

}  // namespace

// Every phase converges, the can is held at the end with the fingers on its diameter, no
// collision, no motion on an unconfirmed target.
TEST(EnonGraspCan, TheOracleGraspsTheCanFromTheSide) {
  const Target target = loadTarget(kCanTable);
  ASSERT_TRUE(target.object.isCylinder());
  servo::OracleEstimator oracle(target.object);
  double gap_at_end = -1;
  const GraspRun r = runGrasp(target, oracle, {}, 60, /*render=*/false,
                              [&](const servo::GraspStep&, const sim::SimEnon& sim) {
                                gap_at_end = sim.fingerGap();
                                return true;
                              });
  EXPECT_TRUE(r.report.success) << r.report.failure << " " << r.error;
  EXPECT_TRUE(r.holding_target);
  EXPECT_TRUE(r.collisions.empty()) << r.collisions.front().message();
  EXPECT_TRUE(r.violations.empty()) << r.violations.front();
  EXPECT_GT(r.min_joint_margin_rad, 0.01);
  EXPECT_EQ(r.report.phases.at("search").outcome, "found");
  EXPECT_EQ(r.report.phases.at("approach").outcome, "converged");
  EXPECT_EQ(r.report.phases.at("align").outcome, "converged");
  EXPECT_EQ(r.report.phases.at("grasp").outcome, "holding");
  ASSERT_TRUE(r.final_grasp_error.has_value());
  EXPECT_LT(r.final_grasp_error->position_m, 0.005);
  EXPECT_LT(r.final_grasp_error->rotation_rad, 2 * M_PI / 180);
  // The fingers closed across the can: 2 r apart, plus its height times the tilt of x_e out of
  // the horizontal (the extent of a cylinder along a direction, 2 r cos a + h sin a; the tilt a
  // is within the final rotation error).
  const double tilt_bound = r.final_grasp_error->rotation_rad;
  std::printf("finger gap %.7f m, final rotation error %.2e rad\n", gap_at_end, tilt_bound);
  EXPECT_GE(gap_at_end, 2 * 0.033 * std::cos(tilt_bound) - 1e-9);
  EXPECT_LE(gap_at_end, 2 * 0.033 + 0.122 * std::sin(tilt_bound) + 1e-9);
  EXPECT_LT(r.sim_time_s, 40);
}

// The session enon_grasp --oracle runs: exit 0, no collision, the summary line's success.
TEST(EnonGraspCan, TheOracleSessionSucceedsWithoutCollision) {
  grasp_app::EnonGraspOptions o;
  o.scenario = kCanTable;
  o.enon = std::string(REFGRASP_SOURCE_DIR) + "/config/enon.yaml";
  o.oracle = true;
  const grasp_app::EnonGraspResult r = grasp_app::runEnonGraspSession(o, nullptr);
  EXPECT_EQ(r.exit_code, grasp_app::kExitGrasped) << r.error;
  EXPECT_EQ(r.collisions, 0);
  EXPECT_NE(r.summary.find("\"success\":true"), std::string::npos) << r.summary;
  EXPECT_GE(r.final_position_mm, 0);
  EXPECT_LT(r.final_position_mm, 5.0);
}
