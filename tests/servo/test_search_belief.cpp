// The search's belief (servo/search_belief.h): its prior over the room's surfaces, what a missed
// look explains (field of view, range, facing, occlusion), where the next look is taken from, and
// when the search is over. Geometry is in closed form: a 10 x 10 m room, tables against its walls.
#include <gtest/gtest.h>

#include <cmath>

#include "robot/enon_model.h"
#include "robot/kinematics.h"
#include "servo/search_belief.h"

using namespace refgrasp;
using servo::BeliefSearch;
using servo::BeliefSearchOptions;
using servo::RoomFixture;
using servo::RoomMap;

namespace {

const std::string kSourceDir = REFGRASP_SOURCE_DIR;

robot::EnonModel enon() { return robot::loadEnonModel(kSourceDir + "/config/enon.yaml"); }

Pose base(double x, double y, double heading) { return robot::PlanarPose{x, y, heading}.toPose(); }

RoomFixture table(const std::string& name, double x, double y, double yaw, double depth = 0.7,
                  double width = 1.2, double height = 0.72) {
  RoomFixture f;
  f.name = name;
  f.surface = true;
  f.height_m = height;
  f.footprint.centre = {x, y};
  f.footprint.half_m = {depth / 2, width / 2};
  f.footprint.yaw_rad = yaw;
  return f;
}

/// A 10 x 10 m room centred on the origin: table A against the east wall (its objects face
/// west, into the room), table B against the west wall (facing east).
RoomMap room() {
  RoomMap m;
  m.inside.centre = {0, 0};
  m.inside.half_m = {5, 5};
  m.fixtures.push_back(table("A", 4.4, 0, 0));
  m.fixtures.push_back(table("B", -4.4, 0, M_PI));
  return m;
}

/// Unexplained mass on the cells within `r` of (x, y), normalised by the prior of those cells.
double massNear(const BeliefSearch& b, double x, double y, double r, double* prior_out = nullptr) {
  const auto snap = b.snapshot();
  double sum = 0;
  for (int row = 0; row < snap->rows; ++row)
    for (int c = 0; c < snap->cols; ++c)
      if ((snap->centre(c, row) - Eigen::Vector2d(x, y)).norm() <= r)
        sum += snap->p[static_cast<size_t>(row * snap->cols + c)];
  if (prior_out) *prior_out = sum;
  return sum * b.unexplained();  // p is normalised: back to the fraction of the prior
}

/// The largest pd over the belief's cells of a look from the left camera at wMc.
double bestPd(const BeliefSearch& b, const Pose& wMc) {
  double best = 0;
  for (int i = 0; i < b.cells(); ++i) best = std::max(best, b.detectProbability(wMc, i));
  return best;
}

/// The left camera of the enon at base pose (x, y, heading) with the head at (pan, tilt).
Pose camera(const robot::EnonModel& m, double x, double y, double heading, double pan, double tilt) {
  return base(x, y, heading) * robot::headCameraPose(m.head, pan, tilt);
}

}  // namespace

TEST(SearchBelief, ThePriorSpreadsEvenlyOverTheTablesTopsAtTheirHeight) {
  const robot::EnonModel m = enon();
  BeliefSearch b(m, m.head.rig.left, room(), BeliefSearchOptions());
  b.reset(base(0, 0, 0));
  const auto snap = b.snapshot();
  double sum = 0, on_a = 0;
  int cells = 0;
  for (int r = 0; r < snap->rows; ++r)
    for (int c = 0; c < snap->cols; ++c) {
      const size_t i = static_cast<size_t>(r * snap->cols + c);
      if (snap->p[i] <= 0) continue;
      ++cells;
      sum += snap->p[i];
      const Eigen::Vector2d x = snap->centre(c, r);
      EXPECT_TRUE(std::abs(std::abs(x.x()) - 4.4) <= 0.35 + 1e-9 && std::abs(x.y()) <= 0.6 + 1e-9)
          << "mass off the tables at " << x.transpose();
      EXPECT_NEAR(snap->height_m[i], 0.72, 1e-6);
      if (x.x() > 0) on_a += snap->p[i];
    }
  EXPECT_NEAR(sum, 1.0, 1e-5);
  EXPECT_NEAR(on_a, 0.5, 1e-5);  // two equal tables
  // 0.7 x 1.2 m each (0.84 m^2, 21 cells of 0.2 m) less the cells whose centre is within 5 cm of
  // an edge, for every alignment of the grid: 3 x 5 to 4 x 6 per table.
  EXPECT_GE(cells, 2 * 3 * 5);
  EXPECT_LE(cells, 2 * 4 * 6);
  EXPECT_NEAR(b.unexplained(), 1.0, 1e-12);
}

TEST(SearchBelief, AMissExplainsWhatTheCameraWouldHaveSeenAndNothingElse) {
  const robot::EnonModel m = enon();
  BeliefSearch b(m, m.head.rig.left, room(), BeliefSearchOptions());
  b.reset(base(2.5, 0, 0));
  // Facing table A, 1.55 m in front of its front edge, tilted down onto it.
  b.miss(camera(m, 2.5, 0, 0, 0, 0.35));
  double prior_a = 0;
  const double left_a = massNear(b, 4.4, 0, 0.8, &prior_a);
  const double left_b = massNear(b, -4.4, 0, 0.8);
  // Table B is behind the camera: untouched (half of the prior).
  EXPECT_NEAR(left_b, 0.5, 1e-6);  // the snapshot holds floats
  // Table A, 1.5-2.2 m away: a 0.18 m target 40-60 px, pd 0.35-0.75, and the facings seen from
  // the front (96 % of the prior's): about half of it explained.
  EXPECT_LT(left_a, 0.5 * 0.6) << left_a;
  EXPECT_GT(left_a, 0.5 * 0.25) << left_a;
}

TEST(SearchBelief, ALookFromTheSideOfATableAgainstAWallExplainsLittleThere) {
  const robot::EnonModel m = enon();
  BeliefSearch b(m, m.head.rig.left, room(), BeliefSearchOptions());
  b.reset(base(0, 0, 0));
  // From 1.6 m north of table A's middle, looking south along the wall: the objects there face
  // the room, west most likely; only those turned north-west (28 % of the prior) and north (2 %)
  // face this camera.
  const double side = bestPd(b, camera(m, 4.4, 1.9, -M_PI / 2, 0, 0.35));
  // The same distance from the front: west, north-west and south-west, 96 % of the prior.
  const double front = bestPd(b, camera(m, 2.6, 0, 0, 0, 0.35));
  EXPECT_GT(front, 0.6);
  EXPECT_LT(side, 0.4 * front);
}

TEST(SearchBelief, AFixtureBetweenTheCameraAndATableHidesIt) {
  const robot::EnonModel m = enon();
  RoomMap map = room();
  // A 1.6 m high cupboard 1 m in front of table A.
  RoomFixture cupboard = table("cupboard", 3.0, 0, 0, 0.4, 1.6, 1.6);
  cupboard.surface = false;
  map.fixtures.push_back(cupboard);
  BeliefSearch b(m, m.head.rig.left, map, BeliefSearchOptions());
  b.reset(base(0, 0, 0));
  const Pose cam = camera(m, 1.8, 0, 0, 0, 0.2);
  EXPECT_EQ(bestPd(b, cam), 0.0);
  // Without it the same look sees table A.
  BeliefSearch open(m, m.head.rig.left, room(), BeliefSearchOptions());
  open.reset(base(0, 0, 0));
  EXPECT_GT(bestPd(open, cam), 0.2);
}

TEST(SearchBelief, TheNextLookDrivesCloserAlongAFreePathToTheTableBehind) {
  const robot::EnonModel m = enon();
  RoomMap map = room();
  map.fixtures.erase(map.fixtures.begin());  // table B only, behind the robot
  // A free-standing sofa between the robot and table B (nothing stands on it).
  RoomFixture sofa = table("sofa", -1.5, 0, 0, 0.8, 1.6, 0.72);
  sofa.surface = false;
  map.fixtures.push_back(sofa);
  BeliefSearch b(m, m.head.rig.left, map, BeliefSearchOptions());
  b.reset(base(1.0, 0, 0));
  const servo::PlannedLook look = b.next(base(1.0, 0, 0), 0, 0.7, 0.9);
  ASSERT_TRUE(look.ok);
  ASSERT_FALSE(look.path.empty()) << "a look from 5 m at an 18 cm target explains little";
  const Eigen::Vector2d end = look.path.back();
  // Closer: the target would be 44 px or more (1.8 m or nearer).
  EXPECT_LT(look.range_m, 2.2);
  EXPECT_LT(end.x(), -1.5);
  // The bearing points at table B (west, within the field of view's half).
  EXPECT_LT(std::abs(std::remainder(look.heading_rad + look.pan_rad - M_PI, 2 * M_PI)), 0.6);
  // Every waypoint is clear, and so is every leg between them.
  Eigen::Vector2d at(1.0, 0);
  for (const Eigen::Vector2d& p : look.path) {
    EXPECT_TRUE(b.free(p)) << p.transpose();
    EXPECT_TRUE(b.freeSegment(at, p)) << at.transpose() << " -> " << p.transpose();
    for (const RoomFixture& f : map.fixtures)
      for (int k = 0; k <= 20; ++k)
        EXPECT_FALSE(f.footprint.contains(at + (p - at) * k / 20.0, m.base.body_radius_m))
            << "the base would touch " << f.name;
    at = p;
  }
}

TEST(SearchBelief, ACandidateThatDidNotConfirmIsLookedAtNext) {
  const robot::EnonModel m = enon();
  BeliefSearch b(m, m.head.rig.left, room(), BeliefSearchOptions());
  // Half-way, facing table A: A first (no turn).
  b.reset(base(0, 0, 0));
  const servo::PlannedLook first = b.next(base(0, 0, 0), 0, 0.7, 0.9);
  ASSERT_TRUE(first.ok);
  EXPECT_LT(std::abs(std::remainder(first.heading_rad + first.pan_rad, 2 * M_PI)), 0.6);
  // A candidate on table B that did not confirm: B first.
  b.candidate({-4.2, 0.2});
  const servo::PlannedLook next = b.next(base(0, 0, 0), 0, 0.7, 0.9);
  ASSERT_TRUE(next.ok);
  EXPECT_LT(std::abs(std::remainder(next.heading_rad + next.pan_rad - M_PI, 2 * M_PI)), 0.6);
}

TEST(SearchBelief, RepeatingALookFromTheSameViewExplainsLittleMore) {
  const robot::EnonModel m = enon();
  BeliefSearch b(m, m.head.rig.left, room(), BeliefSearchOptions());
  b.reset(base(0, 0, 0));
  const Pose far = camera(m, 1.0, 0, 0, 0, 0.15);  // table A 3.1-3.8 m away: pd small
  b.miss(far);
  const double after_one = massNear(b, 4.4, 0, 0.8);
  b.miss(far);
  const double after_two = massNear(b, 4.4, 0, 0.8);
  // The first look explains its pd; the second only 30 % of it (repeat_discount 0.7).
  const double first = 0.5 - after_one, second = after_one - after_two;
  EXPECT_GT(first, 0);
  EXPECT_NEAR(second / after_one, 0.3 * first / 0.5, 0.02);
}

TEST(SearchBelief, RepeatsOfOneViewStopAddingOnceTheyReachPdOverTheDiscount) {
  const robot::EnonModel m = enon();
  BeliefSearch b(m, m.head.rig.left, room(), BeliefSearchOptions());
  b.reset(base(0, 0, 0));
  const Pose far = camera(m, 1.0, 0, 0, 0, 0.15);  // table A 3.1-3.8 m away: pd small
  for (int k = 0; k < 10; ++k) b.miss(far);
  const double after_ten = massNear(b, 4.4, 0, 0.8);
  for (int k = 0; k < 40; ++k) b.miss(far);
  const double after_fifty = massNear(b, 4.4, 0, 0.8);
  // Together the repeats explain at most pd / repeat_discount of each state: forty more add
  // under 1 % of what the first ten explained (each repeat adding 30 % of pd, they would explain
  // most of what is left).
  EXPECT_GT(0.5 - after_ten, 0.02);
  EXPECT_LT(after_ten - after_fifty, 0.01 * (0.5 - after_ten)) << after_ten << " " << after_fifty;
}

TEST(SearchBelief, TheSearchIsOverOnlyWhenEveryTableWasSeenWellFromItsFront) {
  const robot::EnonModel m = enon();
  BeliefSearchOptions o;
  o.stop_mass = 0.35;
  BeliefSearch b(m, m.head.rig.left, room(), o);
  b.reset(base(0, 0, 0));
  EXPECT_FALSE(b.done());
  // Table A from 1.35-2.05 m in front, three times: most of its half of the prior explained,
  // table B's half untouched.
  for (int k = 0; k < 3; ++k) b.miss(camera(m, 2.7, 0, 0, 0, 0.4));
  EXPECT_GT(b.unexplained(), 0.5);
  EXPECT_LT(b.unexplained(), 0.5 + 0.2);
  EXPECT_FALSE(b.done()) << "table B not seen yet";
  for (int k = 0; k < 3; ++k) b.miss(camera(m, -2.7, 0, M_PI, 0, 0.4));
  EXPECT_LT(b.unexplained(), 0.35);
  EXPECT_TRUE(b.done());
}

TEST(SearchBelief, AnUnknownRoomSpreadsThePriorOverARingAroundTheStart) {
  const robot::EnonModel m = enon();
  BeliefSearchOptions o;
  BeliefSearch b(m, m.head.rig.left, RoomMap(), o, {0.8});
  b.reset(base(0, 0, 0));
  const auto snap = b.snapshot();
  for (int r = 0; r < snap->rows; ++r)
    for (int c = 0; c < snap->cols; ++c) {
      const double d = snap->centre(c, r).norm();
      const float p = snap->p[static_cast<size_t>(r * snap->cols + c)];
      if (d < o.min_range_m - 1e-9 || d > o.unknown_range_m + 1e-9) EXPECT_EQ(p, 0.f);
      if (d > o.min_range_m + 1e-9 && d < o.unknown_range_m - 1e-9) EXPECT_GT(p, 0.f);
    }
  // Viewpoints: only the start heading's line (no map: nothing else is known to be free).
  ASSERT_EQ(b.viewpoints().size(), 1u);
  EXPECT_NEAR((b.viewpoints()[0] - Eigen::Vector2d(0.8, 0)).norm(), 0, 1e-12);
}

// A footprint's distance (the grasp's fixture guard uses it): 0 inside, to the nearest edge
// or corner outside, in the footprint's own axes when it is turned.
TEST(SearchMap, AFootprintsDistanceIsToItsNearestEdgeOrCorner) {
  servo::Footprint f;
  f.centre = Eigen::Vector2d(1, 2);
  f.half_m = Eigen::Vector2d(0.35, 0.6);
  EXPECT_EQ(f.distance(Eigen::Vector2d(1.1, 2.3)), 0.0);
  EXPECT_NEAR(f.distance(Eigen::Vector2d(0.4, 2.0)), 0.25, 1e-12);       // in front of the x edge
  EXPECT_NEAR(f.distance(Eigen::Vector2d(1.0, 2.9)), 0.3, 1e-12);        // beyond the y edge
  EXPECT_NEAR(f.distance(Eigen::Vector2d(1.65, 2.0 - 1.0)), 0.5, 1e-12);  // off a corner: 0.3, 0.4
  f.yaw_rad = M_PI / 2;  // turned: its x along the world's y
  EXPECT_NEAR(f.distance(Eigen::Vector2d(1.0, 2.0 - 0.55)), 0.2, 1e-12);
  EXPECT_NEAR(f.distance(Eigen::Vector2d(1.0 + 0.9, 2.0)), 0.3, 1e-12);
  EXPECT_TRUE(f.contains(Eigen::Vector2d(1.0 + 0.9, 2.0), 0.31));
  EXPECT_FALSE(f.contains(Eigen::Vector2d(1.0 + 0.9, 2.0), 0.29));
}

TEST(SearchBelief, BadOptionsNameTheField) {
  const robot::EnonModel m = enon();
  BeliefSearchOptions o;
  o.detect_slope_px = 0;
  try {
    BeliefSearch b(m, m.head.rig.left, room(), o);
    FAIL() << "accepted a zero slope";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("BeliefSearchOptions.detect_slope_px"), std::string::npos) << e.what();
  }
  o = BeliefSearchOptions();
  o.facing_none_rad = 0.5;  // below facing_full_rad
  EXPECT_THROW(BeliefSearch(m, m.head.rig.left, room(), o), std::invalid_argument);
}
