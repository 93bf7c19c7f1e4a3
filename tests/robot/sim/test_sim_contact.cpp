// The simulated enon says no: collisions stop the robot (link and object named), a grasp holds
// only within the gripper's tolerance and opening, heavy objects slip, and frames without images
// carry the same ground truth as rendered ones.
#include <gtest/gtest.h>

#include <cmath>

#include "common/format.h"
#include "core/error.h"
#include "robot/backend.h"
#include "robot/backends.h"
#include "robot/hal.h"
#include "robot/kinematics.h"
#include "robot/sim/sim_enon.h"
#include "sim_test_util.h"

using namespace refgrasp;
using namespace refgrasp::robot;
using refgrasp::sim::Scenario;
using refgrasp::sim::SimEnon;
using refgrasp::sim::SimObject;

namespace {

const std::string kTableSingle = std::string(REFGRASP_SOURCE_DIR) + "/config/scenarios/table_single.yaml";

// Joints that put the gripper frame at bMt (base frame): damped least squares iterations from q.
Eigen::VectorXd solveIk(const ArmKinematics& kin, const Pose& bMt, Eigen::VectorXd q) {
  for (int it = 0; it < 300; ++it) {
    const Pose e = kin.forward(q);
    Eigen::Matrix<double, 6, 1> v;
    v << bMt.t - e.t, Pose(bMt.R * e.R.transpose(), Eigen::Vector3d::Zero()).rotationVector();
    q += dampedLeastSquares(kin.jacobian(q), v, 1e-3);
  }
  return q;
}

// A solid item in code: a box of `size` (width x_o, height y_o, depth z_o) with the scenario
// convention (front face at z_o = 0), grasp frame at its centre.
SimObject boxItem(const std::string& name, const Pose& wMo, const Eigen::Vector3d& size) {
  SimObject o;
  o.name = name;
  o.wMo = wMo;
  o.oMg = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, size.z() / 2));
  o.solids.push_back({o.oMg, size / 2});
  return o;
}

// An upright object facing -x_w (x_o = -y_w, y_o = -z_w, z_o = +x_w) with its front face centre at p.
Pose facingRobot(const Eigen::Vector3d& p) {
  Eigen::Matrix3d R;
  R << Eigen::Vector3d(0, -1, 0), Eigen::Vector3d(0, 0, -1), Eigen::Vector3d(1, 0, 0);
  return Pose(R, p);
}

Scenario bare() {
  Scenario sc;
  sc.path = "contact_test.yaml";
  sc.seed = 5;
  return sc;
}

// The arm stretched forward, horizontal, fingers side by side (x_e horizontal): the solution of
// the IK for e 0.55 m ahead of the shoulder at its height, z_e forward.
Eigen::VectorXd armForward(const EnonModel& m) {
  const ArmKinematics kin(m.arm);
  Eigen::Matrix3d R;
  R << Eigen::Vector3d(0, -1, 0), Eigen::Vector3d(0, 0, -1), Eigen::Vector3d(1, 0, 0);
  const Pose bMt(R, m.arm.bM0.t + Eigen::Vector3d(0.549, 0, 0));
  Eigen::VectorXd q0(5);
  q0 << 1.5, 0.0, 0.0, 0.1, 0.0;
  return solveIk(kin, bMt, q0);
}

// Cycles until the robot stops with an error (at most n); returns the time of the failing read or
// write (-1: none) and prints the error.
double runUntilError(testing_util::SimRig& r, int n, const std::function<void(double)>& command) {
  for (int k = 0; k < n; ++k) {
    const double t = k * r.dt;
    if (r.robot->read(t, r.dt) != ReturnType::kOk || (command(t), r.robot->write(t, r.dt)) != ReturnType::kOk) {
      std::printf("%s\n", r.sim->lastError().c_str());
      return t;
    }
  }
  return -1;
}

// The base driven straight ahead at v until the robot stops (at most 4 s).
double driveUntilError(testing_util::SimRig& r, double v) {
  return runUntilError(r, 200, [&](double) { r.robot->base().setVelocity(v, 0); });
}

// The robot is stopped for good: no motion over one more second of commands, every command refused.
void expectStoppedForGood(testing_util::SimRig& r, double t) {
  const PlanarPose base = r.sim->trueBasePose();
  const Eigen::VectorXd q = r.sim->q();
  const size_t n = r.sim->collisions().size();
  for (int k = 1; k <= 50; ++k) {
    EXPECT_EQ(r.robot->read(t + k * r.dt, r.dt), ReturnType::kError);
    r.robot->base().setVelocity(0.3, 0.2);
    r.robot->arm().setJointVelocity(Eigen::VectorXd::Constant(5, 0.3));
    EXPECT_EQ(r.robot->write(t + k * r.dt, r.dt), ReturnType::kError);
  }
  EXPECT_EQ(r.sim->trueBasePose().x_m, base.x_m);
  EXPECT_EQ(r.sim->trueBasePose().theta_rad, base.theta_rad);
  EXPECT_EQ(r.sim->q(), q);
  EXPECT_EQ(r.robot->state().base_v_mps, 0);
  EXPECT_TRUE(r.robot->state().arm_qdot_radps.isZero(0));
  EXPECT_EQ(r.sim->collisions().size(), n);
  EXPECT_EQ(r.sim->lastError(), r.sim->collisions().front().message());
}

// The stretched arm (armForward) on a base at the origin, facing a box item (front face centre
// `ahead` m in front of e, at its height) of `size`.
std::unique_ptr<testing_util::SimRig> facingABox(const EnonModel& m, const std::string& name, double ahead,
                                                 const Eigen::Vector3d& size, bool target) {
  Scenario sc = bare();
  const Eigen::VectorXd q = armForward(m);
  SimObject o = boxItem(name, facingRobot(ArmKinematics(m.arm).forward(q).t + Eigen::Vector3d(ahead, 0, 0)), size);
  o.is_target = target;
  sc.world.objects.push_back(o);
  auto r = std::make_unique<testing_util::SimRig>(sc, m);
  r->sim->setJointPositions(q);
  return r;
}

bool hasContact(const SimEnon& sim, const std::string& link, const std::string& object) {
  for (const auto& c : sim.collisions())
    if (c.link == link && c.object == object) return true;
  return false;
}

// The arm at q in a world of `item` alone; the gripper closes where it is (0.6 s > close_time_s).
std::unique_ptr<testing_util::SimRig> closeOn(const EnonModel& m, const SimObject& item, const Eigen::VectorXd& q) {
  Scenario sc = bare();
  sc.world.objects.push_back(item);
  auto r = std::make_unique<testing_util::SimRig>(sc, m);
  r->sim->setJointPositions(q);
  EXPECT_FALSE(r->sim->collided()) << r->sim->lastError();
  r->run(30, [&](double tt) {
    if (tt == 0) r->robot->gripper().close();
  });
  EXPECT_FALSE(r->sim->collided()) << r->sim->lastError();
  return r;
}

}  // namespace

TEST(SimContact, ArmLoweredOntoATableStopsWithTheForearmNamed) {
  // A table 0.95 m high, its edge 0.30 m ahead of the shoulder: the stretched arm lowered about
  // the shoulder touches it first with the forearm (thickest link over the table).
  const EnonModel m = testing_util::enonModel();
  Scenario sc = bare();
  SimObject table;
  table.name = "table";
  table.kind = sim::ObjectKind::kTable;
  table.wMo = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.30 + 0.5, -0.2, 0.95));
  table.solids.push_back({Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, -0.475)),
                          Eigen::Vector3d(0.5, 0.5, 0.475)});
  sc.world.objects.push_back(table);
  testing_util::SimRig r(sc, m);
  r.sim->setJointPositions(armForward(m));
  ASSERT_FALSE(r.sim->collided()) << r.sim->lastError();
  Eigen::VectorXd down = Eigen::VectorXd::Zero(5);
  down[0] = -0.3;  // shoulder pitch: lower the arm
  const double t = runUntilError(r, 100, [&](double) { r.robot->arm().setJointVelocity(down); });
  ASSERT_GT(t, 0) << "no collision";
  ASSERT_FALSE(r.sim->collisions().empty());
  const sim::Collision& c = r.sim->collisions().front();
  EXPECT_EQ(c.link, "forearm");
  EXPECT_EQ(c.object, "table");
  EXPECT_GT(c.depth_m, 0);
  EXPECT_LE(c.depth_m, 0.002 + 1e-9);  // at most one sub-step of motion
  // The forearm's far end (the wrist, 0.45 m from the shoulder) touches when its underside has
  // come down 0.05 m; one sub-step moves the fingertips 2 mm (0.0035 rad).
  const double wrist = m.arm.joints[2].d_m + m.arm.joints[4].d_m;
  EXPECT_NEAR(r.sim->q()[0], armForward(m)[0] - std::asin((0.05 - m.arm.forearm.radius_m) / wrist), 0.004);
  EXPECT_NE(r.sim->lastError().find("collision at t="), std::string::npos);
  EXPECT_NE(r.sim->lastError().find(": forearm with table ("), std::string::npos);
  EXPECT_EQ(r.robot->hardware().lastError(), r.sim->lastError());  // through the HAL
  expectStoppedForGood(r, t);
}

TEST(SimContact, HandDrivenIntoAWideBoxStopsOnTheFingertips) {
  // The base drives the stretched arm towards a box 0.40 m wide (wider than the opening) at the
  // hand's height: both fingertips touch its front face first.
  const EnonModel m = testing_util::enonModel();
  auto rig = facingABox(m, "wide_box", 0.20, {0.40, 0.20, 0.10}, false);
  testing_util::SimRig& r = *rig;
  const double gap = 0.20 - (m.gripper.finger_length_m - m.gripper.palm_offset_m) - m.gripper.finger_radius_m;
  const sim::Proximity near = r.sim->nearest();
  EXPECT_NEAR(near.distance_m, gap, 1e-9);
  EXPECT_EQ(near.object, "wide_box");
  EXPECT_EQ(near.link.rfind("finger_x", 0), 0u) << near.link;
  const double t = driveUntilError(r, 0.3);
  ASSERT_GT(t, 0) << "no collision";
  // Fingertips (0.03 m past e, radius 0.012) reach the face after 0.20 - 0.042 m.
  EXPECT_NEAR(r.sim->trueBasePose().x_m, gap, 0.0021);
  EXPECT_LT(r.sim->nearest().distance_m, 0);
  EXPECT_TRUE(hasContact(*r.sim, "finger_x+", "wide_box"));
  EXPECT_TRUE(hasContact(*r.sim, "finger_x-", "wide_box"));
  EXPECT_EQ(r.sim->collisions().size(), 2u);
  expectStoppedForGood(r, t);
}

TEST(SimContact, PalmHittingTheTargetsFrontFaceIsACollision) {
  // A 0.20 m box passes between the open fingers; driven on, the palm meets its front face.
  const EnonModel m = testing_util::enonModel();
  auto rig = facingABox(m, "target", 0.10, {0.20, 0.20, 0.07}, true);
  testing_util::SimRig& r = *rig;
  const double t = driveUntilError(r, 0.2);
  ASSERT_GT(t, 0) << "no collision";
  ASSERT_EQ(r.sim->collisions().size(), 1u);
  EXPECT_EQ(r.sim->collisions().front().link, "palm");
  EXPECT_EQ(r.sim->collisions().front().object, "target");
  // The palm's front (palm_offset - palm_radius behind e) reached the face 0.10 m ahead of e.
  EXPECT_NEAR(r.sim->trueBasePose().x_m, 0.10 + m.gripper.palm_offset_m - m.gripper.palm_radius_m, 0.0021);
  // e went palm_offset - palm_radius deep: past the grasp frame (at 0.035), the error is the overshoot.
  EXPECT_NEAR(r.sim->graspError(0)->position_m, m.gripper.palm_offset_m - m.gripper.palm_radius_m - 0.035,
              0.0021);
  expectStoppedForGood(r, t);
}

TEST(SimContact, ArmLoweredToTheFloorStopsOnTheLowerFinger) {
  // A model with the shoulder 0.60 m above the floor (the hanging hand just clears it); the
  // stretched arm, fingers one above the other (wrist turned a quarter), swung down until the
  // lower fingertip meets the floor.
  EnonModel m = testing_util::enonModel();
  m.arm.bM0.t.z() = 0.60;
  Scenario sc = bare();
  SimObject floor;
  floor.name = "floor";
  floor.kind = sim::ObjectKind::kFloor;
  floor.solids.push_back({Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, -0.25)),
                          Eigen::Vector3d(5, 5, 0.25)});
  sc.world.objects.push_back(floor);
  testing_util::SimRig r(sc, m);
  Eigen::VectorXd q = armForward(m);
  q[4] += M_PI / 2;
  r.sim->setJointPositions(q);
  ASSERT_FALSE(r.sim->collided()) << r.sim->lastError();
  const std::string lower = r.sim->wMe().R.col(0).z() < 0 ? "finger_x+" : "finger_x-";
  Eigen::VectorXd down = Eigen::VectorXd::Zero(5);
  down[0] = -0.5;
  const double t = runUntilError(r, 300, [&](double) { r.robot->arm().setJointVelocity(down); });
  ASSERT_GT(t, 0) << "no collision";
  EXPECT_EQ(r.sim->collisions().front().link, lower);
  EXPECT_EQ(r.sim->collisions().front().object, "floor");
  EXPECT_LE(r.sim->collisions().front().depth_m, 0.002 + 1e-9);
  expectStoppedForGood(r, t);
}

TEST(SimContact, BaseDrivenIntoTheTableStops) {
  Scenario sc = sim::loadScenario(kTableSingle);
  // Facing the table's long side (front edge at x = 1.20 m) from 0.5 m away, beside the box.
  sc.start_x_m = 0.5;
  sc.start_y_m = 0.7;
  sc.start_theta_rad = 0;
  testing_util::SimRig r(sc);
  const double t = driveUntilError(r, 0.4);
  ASSERT_GT(t, 0) << "no collision";
  EXPECT_EQ(r.sim->collisions().front().link, "base");
  EXPECT_EQ(r.sim->collisions().front().object, "table");
  const double radius = r.model.base.body_radius_m;
  EXPECT_NEAR(r.sim->trueBasePose().x_m, 1.20 - radius, 0.0021);
  EXPECT_GE(r.sim->trueBasePose().x_m, 1.20 - radius);  // never further than the first contact + 2 mm
  expectStoppedForGood(r, t);
}

TEST(SimContact, ShippedScenariosStartWithoutContact) {
  for (const char* name : {"table_single", "table_clutter", "faults", "can_table"}) {
    const Scenario sc =
        sim::loadScenario(std::string(REFGRASP_SOURCE_DIR) + "/config/scenarios/" + name + ".yaml");
    testing_util::SimRig r(sc);
    r.run(5, nullptr);
    EXPECT_FALSE(r.sim->collided()) << name << ": " << r.sim->lastError();
  }
}

namespace {

// table_single with the base placed for the grasp: the target's grasp frame (z_g = +x_w) is
// exactly reachable with the forearm along z_g when the shoulder stands in the vertical plane of
// the approach, fore + sqrt(upper^2 - drop^2) behind it (the 5-joint arm cannot reach every pose).
struct GraspSetup {
  Scenario sc;
  int target = -1;
  Pose wMg;
  PlanarPose grasp_base;  ///< base pose with e exactly on the grasp frame
  Eigen::VectorXd q;      ///< joints of that grasp (IK by damped least squares)
};

GraspSetup graspSetup(const EnonModel& m) {
  GraspSetup s;
  s.sc = sim::loadScenario(kTableSingle);
  for (size_t i = 0; i < s.sc.world.objects.size(); ++i)
    if (s.sc.world.objects[i].is_target) s.target = static_cast<int>(i);
  const SimObject& o = s.sc.world.objects[static_cast<size_t>(s.target)];
  s.wMg = o.wMo * o.oMg;
  const double upper = m.arm.joints[2].d_m, fore = m.arm.joints[4].d_m + m.arm.nMe.t.z();
  const double drop = m.arm.bM0.t.z() - s.wMg.t.z();
  s.grasp_base = {s.wMg.t.x() - fore - std::sqrt(upper * upper - drop * drop),
                  s.wMg.t.y() - m.arm.bM0.t.y(), 0.0};
  const Pose bMg = s.grasp_base.toPose().inverse() * s.wMg;
  Eigen::VectorXd q0(5);
  q0 << 0.8, 0.0, 0.0, 0.8, 0.0;
  s.q = solveIk(ArmKinematics(m.arm), bMg, q0);
  return s;
}

constexpr double kApproach = 0.15;  // straight-line approach length along z_g (m)
constexpr double kSpeed = 0.1;      // m/s

// The straight-line approach from startBehind(): the base drives kApproach straight in along
// z_g = x_w with the arm still, then the gripper closes. Returns the time after closing.
double approachAndClose(testing_util::SimRig& r) {
  const int drive = static_cast<int>(std::lround(kApproach / kSpeed / r.dt));
  r.run(drive, [&](double) { r.robot->base().setVelocity(kSpeed, 0); });
  double t = drive * r.dt;
  r.run(1, [&](double) {
    r.robot->base().setVelocity(0, 0);
    r.robot->gripper().close();
  }, t);
  t += r.dt;
  r.run(30, nullptr, t);  // 0.6 s > close_time_s
  return t + 30 * r.dt;
}

// The grasp scenario with the base kApproach behind its grasp pose, shifted by `offset` (world):
// after the approach e is on the grasp frame + offset.
Scenario startBehind(const GraspSetup& s, const Eigen::Vector3d& offset) {
  Scenario sc = s.sc;
  sc.start_x_m = s.grasp_base.x_m - kApproach + offset.x();
  sc.start_y_m = s.grasp_base.y_m + offset.y();
  sc.start_theta_rad = 0;
  return sc;
}

}  // namespace

TEST(SimContact, StraightLineApproachHoldsWithinTheToleranceOnly) {
  const EnonModel m = testing_util::enonModel();
  const GraspSetup s = graspSetup(m);
  const Pose eMg = ArmKinematics(m.arm).forward(s.q).inverse() * s.grasp_base.toPose().inverse() * s.wMg;
  std::printf("IK residual %.2e m, %.2e rad\n", eMg.t.norm(), eMg.rotationVector().norm());
  ASSERT_LT(eMg.t.norm(), 1e-6);
  ASSERT_LT(eMg.rotationVector().norm(), 1e-6);
  const double tol = m.gripper.grasp_tolerance_m;
  // x_g = -y_w (across the face: the fingers' closing direction), z_g = +x_w (approach).
  struct Case {
    Eigen::Vector3d offset;
    bool held;
  };
  const std::vector<Case> cases = {
      {{0, 0, 0}, true},
      {{0, -0.9 * tol, 0}, true},   // along x_g
      {{0, 0.9 * tol, 0}, true},
      {{0, -1.1 * tol, 0}, false},
      {{0, 1.1 * tol, 0}, false},
      {{-0.9 * tol, 0, 0}, true},   // short of the grasp frame
      {{-1.1 * tol, 0, 0}, false},
      {{0.9 * tol, 0, 0}, true},    // past it: the palm is still clear of the front face
      {{1.1 * tol, 0, 0}, false},
  };
  for (const Case& c : cases) {
    testing_util::SimRig r(startBehind(s, c.offset), m);
    r.sim->setJointPositions(s.q);
    approachAndClose(r);
    const auto err = r.sim->graspError(s.target);
    EXPECT_FALSE(r.sim->collided()) << r.sim->lastError();
    EXPECT_NEAR(err->position_m, c.offset.norm(), 2e-6) << c.offset.transpose();
    EXPECT_EQ(r.robot->gripper().phase(), c.held ? GripperPhase::kHolding : GripperPhase::kClosedEmpty)
        << c.offset.transpose() << ": " << toString(r.robot->gripper().phase());
    EXPECT_EQ(r.robot->state().held_object, c.held ? "cereal_box" : "");
  }
}

TEST(SimContact, HeldObjectFollowsTheHandAndAHeavyOneSlips) {
  const EnonModel m = testing_util::enonModel();
  GraspSetup s = graspSetup(m);
  for (const double mass : {0.3, 0.8}) {  // max_payload_kg is 0.5
    s.sc.world.objects[static_cast<size_t>(s.target)].mass_kg = mass;
    testing_util::SimRig r(startBehind(s, Eigen::Vector3d::Zero()), m);
    r.sim->setJointPositions(s.q);
    const double t = approachAndClose(r);
    ASSERT_EQ(r.robot->gripper().phase(), GripperPhase::kHolding) << mass;
    const Pose wMo0 = r.sim->world().objects[static_cast<size_t>(s.target)].wMo;
    const Pose eMo = r.sim->wMe().inverse() * wMo0;
    // Lift: 0.1 m/s up for 1 s (Cartesian, damped least squares: 5 joints deliver part of it,
    // with some drift forward); stopped as soon as the gripper no longer holds.
    Twist up;
    up.v = Eigen::Vector3d(0, 0, 0.1);
    r.run(50, [&](double) {
      r.robot->arm().setVelocity(ArmFrame::kBase, r.robot->gripper().holding() ? up : Twist());
    }, t);
    r.run(1, [&](double) { r.robot->arm().setVelocity(ArmFrame::kBase, Twist()); }, t + 50 * r.dt);
    EXPECT_FALSE(r.sim->collided()) << r.sim->lastError();
    const Pose wMo = r.sim->world().objects[static_cast<size_t>(s.target)].wMo;
    const double hand_rise = r.sim->wMe().t.z() - (wMo0 * eMo.inverse()).t.z();
    SCOPED_TRACE(refgrasp::testing::formatted("mass %.1f kg: hand rose %.3f m, box rose %.3f m, gripper %s", mass,
                                              hand_rise, wMo.t.z() - wMo0.t.z(),
                                              toString(r.robot->gripper().phase())));
    if (mass < m.gripper.max_payload_kg) {
      EXPECT_GT(hand_rise, 0.03);
      EXPECT_EQ(r.robot->gripper().phase(), GripperPhase::kHolding);
      EXPECT_EQ(r.robot->state().held_object, "cereal_box");
      EXPECT_NEAR(translationError(eMo, r.sim->wMe().inverse() * wMo), 0, 1e-9);  // follows the hand
      EXPECT_NEAR(rotationError(eMo, r.sim->wMe().inverse() * wMo), 0, 1e-9);
    } else {
      // It slipped once the hand had moved it (its grasp frame, on e) 5 mm, plus at most one
      // period of lifting (about 2.5 mm with the forward drift).
      const double moved = (r.sim->wMe().t - (wMo0 * eMo.inverse()).t).norm();
      EXPECT_GT(moved, 0.005);
      EXPECT_LT(moved, 0.008);
      EXPECT_EQ(r.robot->gripper().phase(), GripperPhase::kClosedEmpty);
      EXPECT_EQ(r.robot->state().held_object, "");
      EXPECT_NEAR(translationError(wMo, wMo0), 0, 1e-12);  // dropped back where it stood
      EXPECT_NEAR(rotationError(wMo, wMo0), 0, 1e-9);
    }
  }
}

TEST(SimContact, AnItemWiderThanTheOpeningIsNotHeld) {
  // A T-shaped item: a stem that passes between the fingers, a crossbar 0.40 m wide (> the
  // 0.28 m opening) beyond the fingertips. Its grasp frame is on the stem, within tolerance, but
  // the item does not fit: closed on nothing. The same item with a 0.25 m crossbar is held.
  const EnonModel m = testing_util::enonModel();
  for (const double bar : {0.40, 0.25}) {
    const Eigen::VectorXd q = armForward(m);
    const Pose wMe = ArmKinematics(m.arm).forward(q);
    SimObject t = boxItem("tee", facingRobot(wMe.t - Eigen::Vector3d(0.02, 0, 0)), {0.06, 0.06, 0.04});
    // Crossbar: 0.08 m past the stem's front face (0.06 beyond the fingertips), along x_o.
    t.solids.push_back({Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, 0.12)),
                        Eigen::Vector3d(bar / 2, 0.03, 0.02)});
    const auto rig = closeOn(m, t, q);
    testing_util::SimRig& r = *rig;
    EXPECT_LT(r.sim->graspError(0)->position_m, m.gripper.grasp_tolerance_m);
    EXPECT_EQ(r.robot->gripper().phase(), bar > m.gripper.open_width_m ? GripperPhase::kClosedEmpty
                                                                       : GripperPhase::kHolding)
        << bar;
  }
}

TEST(SimContact, FramesWithoutImagesCarryTheSameTruthAndStamps) {
  registerBuiltinBackends();
  const EnonModel m = testing_util::enonModel();
  auto rendered = makeRobot(m, {"sim", {{"scenario", kTableSingle}}, "test"});
  auto bare_frames = makeRobot(m, {"sim", {{"scenario", kTableSingle}, {"render", "false"}}, "test"});
  EXPECT_TRUE(dynamic_cast<SimEnon&>(rendered->hardware()).renderImages());
  EXPECT_FALSE(dynamic_cast<SimEnon&>(bare_frames->hardware()).renderImages());
  for (Robot* r : {rendered.get(), bare_frames.get()}) {
    ASSERT_EQ(r->configure(), ReturnType::kOk);
    ASSERT_EQ(r->activate(), ReturnType::kOk);
  }
  const double dt = m.control_period_s;
  int frames = 0;
  for (int k = 0; k < 13; ++k) {  // 0.26 s of head and base motion: 12 frames at 48 Hz
    const double t = k * dt;
    std::optional<StereoFrame> f[2];
    Robot* robots[2] = {rendered.get(), bare_frames.get()};
    for (int i = 0; i < 2; ++i) {
      ASSERT_EQ(robots[i]->read(t, dt), ReturnType::kOk);
      ASSERT_EQ(robots[i]->camera().grab(t, &f[i]), ReturnType::kOk);
      robots[i]->head().setVelocity(0.6, 0.2);
      robots[i]->base().setVelocity(0.2, 0.3);
      ASSERT_EQ(robots[i]->write(t, dt), ReturnType::kOk);
    }
    ASSERT_EQ(f[0].has_value(), f[1].has_value()) << t;
    if (!f[0]) continue;
    ++frames;
    EXPECT_FALSE(f[0]->left.empty());
    EXPECT_FALSE(f[0]->right.empty());
    EXPECT_TRUE(f[1]->left.empty());
    EXPECT_TRUE(f[1]->right.empty());
    EXPECT_EQ(f[0]->stamp, f[1]->stamp);
    EXPECT_EQ(f[0]->index, f[1]->index);
    EXPECT_EQ(f[0]->capture.head->pan_rad, f[1]->capture.head->pan_rad);
    EXPECT_EQ(f[0]->capture.bMc->t, f[1]->capture.bMc->t);
    EXPECT_EQ(f[0]->capture.wMb_odom->t, f[1]->capture.wMb_odom->t);
    ASSERT_EQ(f[0]->truth.size(), 1u);
    ASSERT_EQ(f[1]->truth.size(), 1u);
    EXPECT_EQ(f[0]->truth[0].object, f[1]->truth[0].object);
    EXPECT_EQ(f[0]->truth[0].cMo.t, f[1]->truth[0].cMo.t);  // bit-identical
    EXPECT_EQ(f[0]->truth[0].cMo.R, f[1]->truth[0].cMo.R);
    EXPECT_EQ(f[0]->truth[0].rMo->t, f[1]->truth[0].rMo->t);
  }
  EXPECT_GE(frames, 12);
  // Rendering switched on mid-run: the images a run that always rendered has (same noise).
  dynamic_cast<SimEnon&>(bare_frames->hardware()).setRenderImages(true);
  for (int k = 13; k < 16; ++k) {
    const double t = k * dt;
    std::optional<StereoFrame> f[2];
    Robot* robots[2] = {rendered.get(), bare_frames.get()};
    for (int i = 0; i < 2; ++i) {
      ASSERT_EQ(robots[i]->read(t, dt), ReturnType::kOk);
      ASSERT_EQ(robots[i]->camera().grab(t, &f[i]), ReturnType::kOk);
    }
    if (!f[0]) continue;
    EXPECT_EQ(cv::norm(f[0]->left, f[1]->left, cv::NORM_INF), 0);
    EXPECT_EQ(cv::norm(f[0]->right, f[1]->right, cv::NORM_INF), 0);
  }
  try {
    makeRobot(m, {"sim", {{"scenario", kTableSingle}, {"render", "no"}}, "settings.yaml"});
    ADD_FAILURE() << "render: no accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("settings.yaml: render: expected true or false, got 'no'"),
              std::string::npos)
        << e.what();
  }
}

namespace {

// An upright can in code (scenario cylinder convention: y_o down the axis, z_o = +x_w towards
// the axis) with its axis at `axis`, its grasp frame on the axis (identity rotation: z_g = +x_w,
// x_g = -y_w across the diameter).
SimObject canItem(const std::string& name, const Eigen::Vector3d& axis, double radius, double height) {
  SimObject o;
  o.name = name;
  o.wMo = facingRobot(axis - Eigen::Vector3d(radius, 0, 0));
  o.oMg = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, radius));
  o.solids.push_back(sim::cylinderSolid(radius, height));
  return o;
}

}  // namespace

TEST(SimContact, AFingerDrivenIntoACanStopsOnItsTip) {
  // A can straight ahead of finger_x+ (x_e = -y_w: the finger is 0.152 m to the right of e), its
  // side 0.15 m from the fingertip: only that finger touches, when the base has moved the gap.
  const EnonModel m = testing_util::enonModel();
  const Eigen::VectorXd q = armForward(m);
  const Pose wMe = ArmKinematics(m.arm).forward(q);
  const robot::GripperModel& g = m.gripper;
  const double finger_y = -(g.open_width_m / 2 + g.finger_radius_m), tip = g.finger_length_m - g.palm_offset_m;
  const double gap = 0.15;
  Scenario sc = bare();
  sc.world.objects.push_back(canItem(
      "can", wMe.t + Eigen::Vector3d(tip + g.finger_radius_m + gap + 0.033, finger_y, 0), 0.033, 0.122));
  testing_util::SimRig r(sc, m);
  r.sim->setJointPositions(q);
  ASSERT_FALSE(r.sim->collided()) << r.sim->lastError();
  const sim::Proximity near = r.sim->nearest();
  EXPECT_NEAR(near.distance_m, gap, 1e-9);
  EXPECT_EQ(near.link, "finger_x+");
  EXPECT_EQ(near.object, "can");
  const double t = driveUntilError(r, 0.3);
  ASSERT_GT(t, 0) << "no collision";
  EXPECT_NEAR(r.sim->trueBasePose().x_m, gap, 0.0021);
  ASSERT_EQ(r.sim->collisions().size(), 1u);
  EXPECT_EQ(r.sim->collisions().front().link, "finger_x+");
  EXPECT_EQ(r.sim->collisions().front().object, "can");
  EXPECT_LE(r.sim->collisions().front().depth_m, 0.002 + 1e-9);
  EXPECT_NE(r.sim->lastError().find(": finger_x+ with can ("), std::string::npos) << r.sim->lastError();
  expectStoppedForGood(r, t);
}

TEST(SimContact, TheForearmLoweredOntoALyingCanStops) {
  // A can lying across the stretched arm's forearm (axis along y_w), 5 cm below it, under the
  // forearm's middle: lowering the arm about the shoulder, the forearm touches it first.
  const EnonModel m = testing_util::enonModel();
  const Eigen::VectorXd q = armForward(m);
  const std::vector<Pose> f = ArmKinematics(m.arm).frames(q);
  const Eigen::Vector3d mid = 0.5 * (f[static_cast<size_t>(m.arm.forearm.from_frame)].t +
                                     f[static_cast<size_t>(m.arm.forearm.to_frame)].t);
  Scenario sc = bare();
  SimObject can;
  can.name = "can";
  can.wMo = Pose(Eigen::Matrix3d::Identity(), mid - Eigen::Vector3d(0, 0, m.arm.forearm.radius_m + 0.05 + 0.033));
  can.solids.push_back({Pose::fromRotationVector(Eigen::Vector3d(M_PI / 2, 0, 0), Eigen::Vector3d::Zero()),
                        Eigen::Vector3d(0.033, 0.033, 0.061), true});
  sc.world.objects.push_back(can);
  testing_util::SimRig r(sc, m);
  r.sim->setJointPositions(q);
  ASSERT_FALSE(r.sim->collided()) << r.sim->lastError();
  EXPECT_NEAR(r.sim->nearest().distance_m, 0.05, 1e-6);
  EXPECT_EQ(r.sim->nearest().link, "forearm");
  Eigen::VectorXd down = Eigen::VectorXd::Zero(5);
  down[0] = -0.3;
  const double t = runUntilError(r, 100, [&](double) { r.robot->arm().setJointVelocity(down); });
  ASSERT_GT(t, 0) << "no collision";
  ASSERT_FALSE(r.sim->collisions().empty());
  EXPECT_EQ(r.sim->collisions().front().link, "forearm");
  EXPECT_EQ(r.sim->collisions().front().object, "can");
  EXPECT_LE(r.sim->collisions().front().depth_m, 0.002 + 1e-9);
  expectStoppedForGood(r, t);
}

TEST(SimContact, TheBaseDrivenIntoABinStops) {
  // A bin (a cylinder 0.15 m in radius, 0.5 m high) on the floor 1 m ahead: the base body (radius
  // 0.25 m) touches it when its centre is 0.40 m from the bin's axis.
  const EnonModel m = testing_util::enonModel();
  Scenario sc = bare();
  SimObject bin = canItem("bin", Eigen::Vector3d(1.0, 0, 0.25), 0.15, 0.5);
  sc.world.objects.push_back(bin);
  testing_util::SimRig r(sc, m);
  EXPECT_NEAR(r.sim->nearest().distance_m, 1.0 - 0.15 - m.base.body_radius_m, 1e-12);
  const double t = driveUntilError(r, 0.3);
  ASSERT_GT(t, 0) << "no collision";
  EXPECT_NEAR(r.sim->trueBasePose().x_m, 1.0 - 0.15 - m.base.body_radius_m, 0.0021);
  ASSERT_EQ(r.sim->collisions().size(), 1u);
  EXPECT_EQ(r.sim->collisions().front().link, "base");
  EXPECT_EQ(r.sim->collisions().front().object, "bin");
  expectStoppedForGood(r, t);
}

TEST(SimContact, ASideGraspOfACanHoldsItAcrossItsDiameter) {
  // The stretched arm's gripper frame on the can's grasp frame (on its axis): closing, the fingers
  // stop on its sides, 2r apart, and it is held; its grasp frame 1.1 tolerances to the side: not.
  const EnonModel m = testing_util::enonModel();
  const Eigen::VectorXd q = armForward(m);
  const Pose wMe = ArmKinematics(m.arm).forward(q);
  for (const double side : {0.0, 1.1 * m.gripper.grasp_tolerance_m}) {
    const auto rig = closeOn(m, canItem("can", wMe.t + Eigen::Vector3d(0, side, 0), 0.033, 0.122), q);
    testing_util::SimRig& r = *rig;
    EXPECT_NEAR(r.sim->graspError(0)->position_m, side, 1e-9);
    if (side == 0) {
      EXPECT_EQ(r.robot->gripper().phase(), GripperPhase::kHolding);
      EXPECT_EQ(r.robot->state().held_object, "can");
      EXPECT_NEAR(r.sim->fingerGap(), 0.066, 1e-12);
    } else {
      EXPECT_EQ(r.robot->gripper().phase(), GripperPhase::kClosedEmpty);
      EXPECT_EQ(r.sim->fingerGap(), 0);
    }
  }
}

TEST(SimContact, ABottleWiderThanTheOpeningIsNotHeld) {
  // A bottle gripped by its neck (radius 0.015 m, between the fingers) whose body, 6 cm below the
  // fingers, is 0.30 m across (> the 0.28 m opening): its width across the fingers does not fit,
  // closed on nothing. The same bottle 0.24 m across is held, the fingers stopped 0.24 m apart.
  const EnonModel m = testing_util::enonModel();
  const Eigen::VectorXd q = armForward(m);
  const Pose wMe = ArmKinematics(m.arm).forward(q);
  for (const double body : {0.30, 0.24}) {
    SimObject bottle = canItem("bottle", wMe.t, 0.015, 0.10);
    sim::Solid b = sim::cylinderSolid(body / 2, 0.20);
    b.oMs.t = Eigen::Vector3d(0, 0.06 + 0.10, 0.015);  // on the neck's axis, its top 0.06 below e
    bottle.solids.push_back(b);
    const auto rig = closeOn(m, bottle, q);
    testing_util::SimRig& r = *rig;
    EXPECT_NEAR(r.sim->graspError(0)->position_m, 0, 1e-9);
    if (body > m.gripper.open_width_m) {
      EXPECT_EQ(r.robot->gripper().phase(), GripperPhase::kClosedEmpty) << body;
    } else {
      EXPECT_EQ(r.robot->gripper().phase(), GripperPhase::kHolding) << body;
      EXPECT_NEAR(r.sim->fingerGap(), body, 1e-12);
    }
  }
}
