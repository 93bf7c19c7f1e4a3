// The search plan (servo/search_plan.h): the sweep's looks, each direction once, base turns and
// viewpoint moves, and the search by belief over the room's tables; on the simulated enon
// through the grasp controller with the oracle.
#include <gtest/gtest.h>

#include <cmath>

#include "grasp_run.h"
#include "servo/search_plan.h"

using namespace refgrasp;
using refgrasp::testing::GraspRun;
using refgrasp::testing::loadTarget;
using refgrasp::testing::runGrasp;
using refgrasp::testing::Target;

namespace {

robot::EnonModel enon() { return robot::loadEnonModel(refgrasp::testing::kSourceDir + "/config/enon.yaml"); }

std::string scenarioPath(const std::string& name) {
  return refgrasp::testing::kSourceDir + "/config/scenarios/" + name + ".yaml";
}

/// Runs the search only (the run stops when the search phase ends); counts looks and turns.
struct SearchRun {
  bool found = false;
  std::string outcome;
  int looks = 0, turns = 0, moves = 0;
  double time_s = 0;
  std::vector<double> look_bearings;  ///< odometry heading + pan at each look
};

/// The sweep (GraspOptions::belief_search false), unless `o` says otherwise.
servo::GraspOptions sweep() {
  servo::GraspOptions o;
  o.belief_search = false;
  return o;
}

SearchRun runSearch(const Target& target, servo::GraspOptions o = sweep()) {
  servo::OracleEstimator oracle(target.object);
  SearchRun sr;
  std::string last;
  const auto hook = [&](const servo::GraspStep& s, const sim::SimEnon&) {
    const servo::GraspIteration& it = s.it;
    if (it.phase != servo::GraspPhase::kSearch) {
      sr.time_s = it.t;
      return false;
    }
    if (it.detail != last) {
      if (it.detail == "look") {
        ++sr.looks;
        const double heading = std::atan2(it.state.wMb_odom.R(1, 0), it.state.wMb_odom.R(0, 0));
        sr.look_bearings.push_back(heading + it.state.pan_rad);
      }
      if (it.detail == "turn_base") ++sr.turns;
      if (it.detail == "move_base") ++sr.moves;
      last = it.detail;
    }
    return true;
  };
  const GraspRun r = runGrasp(target, oracle, o, 120, false, hook);
  sr.outcome = r.report.phases.count("search") ? r.report.phases.at("search").outcome : "";
  sr.found = sr.outcome == "found";
  if (sr.time_s == 0) sr.time_s = r.sim_time_s;
  return sr;
}

}  // namespace

// The BB2's ~66 deg view less 2 x 0.12 rad of overlap spaces the looks 0.785 rad apart over the
// head's +-1.57 rad: five looks, straight ahead first, nearest first (left on a tie).
TEST(SearchPlan, LooksAreSpacedByTheFieldOfViewAndTakenNearestFirst) {
  const robot::EnonModel m = enon();
  const servo::SearchPlan plan(m, m.head.rig.left);
  const double hfov = 2 * std::atan2(0.5 * m.head.rig.left.width, m.head.rig.left.fx);
  EXPECT_NEAR(plan.coverHalfWidth(), 0.5 * hfov - 0.12, 1e-12);
  const std::vector<double> want{0, 0.785, 1.57, -0.785, -1.57};
  const std::vector<double> got = plan.panGrid();
  ASSERT_EQ(got.size(), want.size());
  for (size_t i = 0; i < want.size(); ++i) EXPECT_NEAR(got[i], want[i], 1e-9) << i;
  servo::SearchPlanOptions o;
  o.edge_margin_rad = 0.6;
  EXPECT_THROW(servo::SearchPlan(m, m.head.rig.left, o), std::invalid_argument);
}

// table_single: the target is 40 deg to the left, outside the first view: found on the second
// look, in under 2 s.
TEST(SearchPlan, FindsATargetOutsideTheFirstViewOnTheSecondLook) {
  const SearchRun s = runSearch(loadTarget(scenarioPath("table_single")));
  EXPECT_TRUE(s.found) << s.outcome;
  EXPECT_EQ(s.looks, 2);
  EXPECT_EQ(s.turns, 0);
  EXPECT_LT(s.time_s, 2.0);
}

// The robot starts facing away from the table and looks all around before moving
// (move_before_turning = false): the five head positions see nothing, the base turns once (by
// the smallest angle that brings every unseen direction within the head's reach, ~127 deg, not a
// full half turn) and the target is found without looking at any direction twice.
TEST(SearchPlan, TurnsTheBaseOnceWhenTheHeadCannotSeeTheTarget) {
  Target t = loadTarget(scenarioPath("table_single"));
  t.scenario.start_theta_rad = M_PI;  // the table behind the robot
  servo::GraspOptions o = sweep();
  o.search.move_before_turning = false;
  const SearchRun s = runSearch(t, o);
  EXPECT_TRUE(s.found) << s.outcome;
  EXPECT_EQ(s.turns, 1);
  EXPECT_GE(s.looks, 6);
  EXPECT_LE(s.looks, 8);
  const robot::EnonModel m = enon();
  const servo::SearchPlan plan(m, m.head.rig.left);
  for (size_t i = 0; i < s.look_bearings.size(); ++i)
    for (size_t j = 0; j < i; ++j)
      EXPECT_GT(std::abs(std::remainder(s.look_bearings[i] - s.look_bearings[j], 2 * M_PI)),
                plan.coverHalfWidth())
          << "looks " << j << " and " << i << " overlap by more than half a view";
}

// The target is too far to be seen from the start (3.4 m: its face under 32 px): the head's
// five looks see nothing, then the base drives to another viewpoint (0.8 m along the start
// heading) before looking behind, and finds it there.
TEST(SearchPlan, MovesToAnotherViewpointWhenTheHeadSeesNothing) {
  Target t = loadTarget(scenarioPath("table_single"));
  t.scenario.start_x_m = -2.0;
  t.scenario.start_y_m = 0.4;
  const SearchRun s = runSearch(t);
  EXPECT_TRUE(s.found) << s.outcome;
  EXPECT_EQ(s.moves, 1);
  EXPECT_LE(s.turns, 1);  // at most the (null) turn to the start heading before driving
  EXPECT_GE(s.looks, 6);
}

// With no viewpoint to drive to it looks all around once and gives up: outcome not_found.
TEST(SearchPlan, GivesUpWhenEveryDirectionOfEveryViewpointWasSeen) {
  Target t = loadTarget(scenarioPath("table_single"));
  t.scenario.start_x_m = -2.0;
  t.scenario.start_y_m = 0.4;
  servo::GraspOptions o = sweep();
  o.search.max_viewpoints = 0;
  servo::OracleEstimator oracle(t.object);
  const GraspRun r = runGrasp(t, oracle, o, 120, false);
  EXPECT_FALSE(r.report.success);
  EXPECT_EQ(r.report.phases.at("search").outcome, "not_found");
  EXPECT_TRUE(r.violations.empty()) << r.violations.front();
}

// The search by belief on the same set-ups: the table behind the robot is looked at first
// (one turn, no look elsewhere), sooner than the sweep finds it.
TEST(SearchPlan, ByBeliefTheTableBehindIsLookedAtFirst) {
  Target t = loadTarget(scenarioPath("table_single"));
  t.scenario.start_theta_rad = M_PI;
  servo::GraspOptions o = sweep();
  o.search.move_before_turning = false;
  const SearchRun swept = runSearch(t, o);
  const SearchRun s = runSearch(t, servo::GraspOptions());
  EXPECT_TRUE(s.found) << s.outcome;
  EXPECT_LE(s.looks, 2);
  EXPECT_LT(s.time_s, 0.6 * swept.time_s) << "belief " << s.time_s << " s, sweep " << swept.time_s << " s";
}

// Where the sweep gives up (the target too far to see, no viewpoint left), the search by belief
// drives closer along a free path and finds it; nothing moves on an unconfirmed target.
TEST(SearchPlan, ByBeliefASearchDoesNotGiveUpWhileATableWasNotSeenWell) {
  Target t = loadTarget(scenarioPath("table_single"));
  t.scenario.start_x_m = -2.0;
  t.scenario.start_y_m = 0.4;
  servo::GraspOptions o;
  o.search.max_viewpoints = 0;
  servo::OracleEstimator oracle(t.object);
  const GraspRun r = runGrasp(t, oracle, o, 120, false);
  EXPECT_EQ(r.report.phases.at("search").outcome, "found");
  EXPECT_TRUE(r.report.success) << r.report.failure;
  EXPECT_TRUE(r.collisions.empty());
  EXPECT_TRUE(r.violations.empty()) << r.violations.front();
}
