// The vpServo tasks on their own (servo/servo_tasks.h, servo/grasp_geometry.h): Jacobians against
// finite differences, and convergence of each task from seeded start poses, integrating the
// robot's kinematics in closed form (robot/kinematics.h) at the control period.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "robot/enon_model.h"
#include "robot/kinematics.h"
#include "servo/grasp_geometry.h"
#include "servo/servo_tasks.h"

using namespace refgrasp;

namespace {

robot::EnonModel enon() {
  return robot::loadEnonModel(std::string(REFGRASP_SOURCE_DIR) + "/config/enon.yaml");
}

double deg(double rad) { return rad * 180 / M_PI; }

// The grasp orientation of an upright object facing the robot's x axis: z_e = x_b (approach),
// x_e = -y_b (fingers close horizontally), y_e = -z_b.
Eigen::Matrix3d facingForward() {
  Eigen::Matrix3d R;
  R.col(0) = -Eigen::Vector3d::UnitY();
  R.col(1) = -Eigen::Vector3d::UnitZ();
  R.col(2) = Eigen::Vector3d::UnitX();
  return R;
}

Pose planar(double x, double y, double theta) { return robot::PlanarPose{x, y, theta}.toPose(); }

}  // namespace

TEST(ServoTasks, HeadJacobianMatchesFiniteDifferences) {
  const robot::EnonModel m = enon();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> pan(-1.4, 1.4), tilt(-0.4, 0.9);
  for (int k = 0; k < 10; ++k) {
    const double p = pan(rng), t = tilt(rng), h = 1e-6;
    const Eigen::Matrix<double, 6, 2> J = servo::headJacobian(m.head, p, t);
    const Pose c0 = robot::headCameraPose(m.head, p, t);
    for (int j = 0; j < 2; ++j) {
      const Pose c1 = robot::headCameraPose(m.head, p + (j == 0 ? h : 0), t + (j == 1 ? h : 0));
      const Pose d = c0.inverse() * c1;  // motion in the camera frame
      EXPECT_LT((d.t / h - J.block<3, 1>(0, j)).norm(), 1e-5);
      EXPECT_LT((d.rotationVector() / h - J.block<3, 1>(3, j)).norm(), 1e-5);
    }
  }
}

TEST(ServoTasks, GripperJacobianMatchesFiniteDifferencesWithTheBase) {
  const robot::EnonModel m = enon();
  const robot::ArmKinematics arm(m.arm);
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int k = 0; k < 10; ++k) {
    Eigen::VectorXd q(arm.dof());
    for (int i = 0; i < arm.dof(); ++i) {
      const auto& l = m.arm.joints[static_cast<size_t>(i)].limits;
      q[i] = 0.5 * (l.min_rad + l.max_rad) + 0.3 * (l.max_rad - l.min_rad) * u(rng);
    }
    const Eigen::MatrixXd J = servo::gripperJacobian(arm, q);
    ASSERT_EQ(J.cols(), arm.dof() + 2);
    const double h = 1e-6;
    const Pose wMe0 = arm.forward(q);  // base at the world origin
    for (int j = 0; j < arm.dof() + 2; ++j) {
      Eigen::VectorXd q1 = q;
      Pose wMb1;
      if (j < arm.dof()) q1[j] += h;
      if (j == arm.dof()) wMb1 = planar(h, 0, 0);      // base forward
      if (j == arm.dof() + 1) wMb1 = planar(0, 0, h);  // base turn
      const Pose d = wMe0.inverse() * (wMb1 * arm.forward(q1));
      EXPECT_LT((d.t / h - J.block(0, j, 3, 1)).norm(), 1e-5) << "column " << j;
      EXPECT_LT((d.rotationVector() / h - J.block(3, j, 3, 1)).norm(), 1e-5) << "column " << j;
    }
  }
}

TEST(ServoTasks, ReachInShoulderPlaneHoldsTheGripperForward) {
  const robot::EnonModel m = enon();
  const robot::ArmKinematics arm(m.arm);
  for (const double z : {0.76, 0.80, 0.84, 0.90}) {
    const servo::ArmReach r = servo::reachInShoulderPlane(arm, facingForward(), z);
    ASSERT_TRUE(r.ok) << "z " << z;
    EXPECT_NEAR(r.bMe.t.z(), z, 1e-4);
    EXPECT_NEAR(r.bMe.t.y(), m.arm.bM0.t.y(), 1e-4);
    EXPECT_LT(rotationError(r.bMe, Pose(facingForward(), Eigen::Vector3d::Zero())), 1e-4);
    EXPECT_GT(r.bMe.t.x(), 0.3) << "in front of the base";
    EXPECT_GT(r.joint_margin, 0.05);
  }
}

// Head pointing: a point anywhere in the camera's view is centred (|x|, |y| < tolerance) within
// 2 s, the head integrated in closed form within its limits (the camera's roll about its optical
// axis is not controllable by a pan-tilt head, and the task does not ask for it).
TEST(ServoTasks, HeadPointingConvergesFromSeededStarts) {
  const robot::EnonModel m = enon();
  servo::HeadPointingTask task(m.head);
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> dist(1.0, 2.5), bearing(-1.2, 1.2), height(0.6, 1.1),
      pan(-1.0, 1.0), tilt(-0.2, 0.6);
  const double dt = m.control_period_s;
  int tried = 0;
  for (int k = 0; tried < 20 && k < 200; ++k) {
    const double b = bearing(rng), d = dist(rng);
    const Eigen::Vector3d bP(d * std::cos(b), d * std::sin(b), height(rng));
    double p = b + 0.5 * pan(rng), t = tilt(rng);
    const Eigen::Vector3d c0 = robot::headCameraPose(m.head, p, t).inverse() * bP;
    if (c0.z() < 0.3 || std::abs(c0.x() / c0.z()) > 0.5 || std::abs(c0.y() / c0.z()) > 0.4) continue;
    ++tried;
    double time = 0;
    servo::HeadCommand cmd;
    for (; time < 2.0; time += dt) {
      cmd = task.compute(robot::headCameraPose(m.head, p, t).inverse() * bP, p, t);
      if (cmd.converged) break;
      EXPECT_LE(std::abs(cmd.pan_radps), task.options().max_pan_radps + 1e-12);
      EXPECT_LE(std::abs(cmd.tilt_radps), task.options().max_tilt_radps + 1e-12);
      p = robot::integrateJoint(m.head.pan, p, cmd.pan_radps, dt);
      t = robot::integrateJoint(m.head.tilt, t, cmd.tilt_radps, dt);
    }
    EXPECT_TRUE(cmd.converged) << "start " << k << " error " << cmd.error;
    EXPECT_LT(time, 2.0) << "start " << k;
  }
  EXPECT_EQ(tried, 20);
}

// Base approach: from seeded starts 1-2.5 m from the goal, anywhere up to 70 deg off the
// approach line as seen from the goal (the line itself turned up to 30 deg), the base stops on
// the goal pose within 3 cm (lateral) / 1 cm (along the line) and 1 deg in under 12 s, never
// past the goal along the line (the table lies beyond). Far off the line it goes to the
// waypoint W first; the Pioneer features then fix the distance and bearing of Q, the heading is
// G's because the base drove along the line, and a last turn in place removes what is left.
TEST(ServoTasks, BaseApproachReachesTheGoalPoseFromSeededStarts) {
  const robot::EnonModel m = enon();
  servo::BaseApproachTask task;
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> dist(1.0, 2.5), off(-1.2, 1.2), turn(-0.52, 0.52),
      heading(-0.8, 0.8);
  const double dt = m.control_period_s;
  int via_waypoint = 0;
  for (int k = 0; k < 20; ++k) {
    const double line = turn(rng);  // approach direction in the world
    const Pose wMg = planar(3.0, 0.5, line);
    const double d = dist(rng), o = off(rng);
    robot::PlanarPose b{3.0 - d * std::cos(line + o), 0.5 - d * std::sin(line + o),
                        line + o + heading(rng)};
    task.restart();
    double time = 0, max_along = -1e9;
    servo::BaseCommand c;
    bool waypoint = false;
    for (; time < 20; time += dt) {
      c = task.approach(b.toPose(), wMg);
      waypoint = waypoint || c.stage == servo::ApproachStage::kToWaypoint;
      max_along = std::max(max_along, c.points.along_m);
      if (c.stage == servo::ApproachStage::kDone) break;
      double v = c.v_mps, w = c.w_radps;
      robot::clipBaseVelocity(m.base, &v, &w);
      b = robot::integrateUnicycle(b, v, w, dt);
    }
    via_waypoint += waypoint;
    const servo::ApproachPoints& a = c.points;
    EXPECT_EQ(c.stage, servo::ApproachStage::kDone) << "start " << k;
    EXPECT_LT(std::abs(a.lateral_m), 0.03) << "start " << k;
    EXPECT_LT(std::abs(a.along_m), 0.01) << "start " << k;
    EXPECT_LT(std::abs(deg(a.heading_error_rad)), 1.0) << "start " << k;
    EXPECT_LE(max_along, 0.0) << "start " << k;
    EXPECT_LT(time, 12) << "start " << k;
  }
  EXPECT_GE(via_waypoint, 1);  // both ways are taken
  EXPECT_LT(via_waypoint, 20);
}

// The way to the waypoint W keeps the object within the head's reach (its pan limit, 1.57 rad,
// plus half its field of view, 0.57). The object 1.86 rad to the right of the base, W behind it
// (x < 0) on the way: backing up to W, as any W behind once did, would leave the object behind
// the base (3.1 rad off its heading) at W; driving forwards keeps it within 1.9 rad, ahead at W.
// The object ahead and W just behind the base: it backs up, the object ahead all along.
TEST(ServoTasks, BaseApproachGoesToTheWaypointTheWayThatKeepsTheObjectInView) {
  const robot::EnonModel m = enon();
  const double dt = m.control_period_s;
  struct Case {
    Eigen::Vector3d object;  // world, at table height
    double line;             // heading of G (towards the object)
    bool expect_backwards;
    double max_bearing;      // of the object from the base's heading over the approach (rad)
  };
  for (const Case& k : {Case{{-0.75, -2.5, 0.8}, 4.451, false, 1.9}, Case{{0.9, 0.0, 0.8}, 0.0, true, 0.3}}) {
    const Eigen::Vector3d x_g(std::cos(k.line), std::sin(k.line), 0);
    const Eigen::Vector3d g = k.object - 0.6 * x_g;
    const Pose wMg = planar(g.x(), g.y(), k.line);
    servo::BaseApproachTask task;
    robot::PlanarPose b{0, 0, 0};
    double worst = 0, first_v = 0, time = 0;
    servo::BaseCommand c;
    for (; time < 30; time += dt) {
      c = task.approach(b.toPose(), wMg, k.object);
      if (c.stage == servo::ApproachStage::kToWaypoint && first_v == 0 && std::abs(c.v_mps) > 1e-3)
        first_v = c.v_mps;
      const Eigen::Vector3d bo = b.toPose().inverse() * k.object;
      worst = std::max(worst, std::abs(std::atan2(bo.y(), bo.x())));
      if (c.stage == servo::ApproachStage::kDone) break;
      double v = c.v_mps, w = c.w_radps;
      robot::clipBaseVelocity(m.base, &v, &w);
      b = robot::integrateUnicycle(b, v, w, dt);
    }
    std::printf("object at (%.2f, %.2f): to W %s, the object at most %.2f rad off the heading, done in %.1f s\n",
                k.object.x(), k.object.y(), first_v < 0 ? "backwards" : "forwards", worst, time);
    EXPECT_EQ(c.stage, servo::ApproachStage::kDone);
    EXPECT_EQ(first_v < 0, k.expect_backwards);
    EXPECT_LT(worst, k.max_bearing);
  }
}

// Arm align: from seeded starts (the arm's joints up to 0.25 rad off the reaching configuration,
// i.e. the gripper ~5-20 cm and up to 15 deg off the pre-grasp pose; the base up to 3 cm and
// 3 deg off its goal, more than the approach leaves) the gripper reaches e* within 1 mm and
// 0.2 deg (5 mm and 2 deg are required) in under 4 s. All six pose components are
// controlled (5 arm joints + the base's v and w); no joint comes within 5 % of its range of a
// limit, and the base moves less than 5 cm.
TEST(ServoTasks, ArmAlignConvergesFromSeededStartsWithTheBaseContributing) {
  const robot::EnonModel m = enon();
  const robot::ArmKinematics arm(m.arm);
  servo::ArmAlignTask task(m.arm);
  std::mt19937 rng(41);
  std::uniform_real_distribution<double> u(-1, 1), height(0.76, 0.90);
  const double dt = m.control_period_s;
  for (int k = 0; k < 20; ++k) {
    // A grasp in front of a base at the origin, reachable by the shoulder-plane configuration.
    const servo::ArmReach reach = servo::reachInShoulderPlane(arm, facingForward(), height(rng));
    ASSERT_TRUE(reach.ok);
    const Pose wMed = reach.bMe;  // the base starts at its goal = the world origin, then is moved
    robot::PlanarPose b{0.03 * u(rng), 0.03 * u(rng), 0.05 * u(rng)};
    const robot::PlanarPose b0 = b;
    // The arm starts off: a random joint offset moving the gripper 5-15 cm / up to 20 deg away.
    Eigen::VectorXd q = reach.q;
    for (int i = 0; i < arm.dof(); ++i) q[i] += 0.25 * u(rng);
    for (int i = 0; i < arm.dof(); ++i) {
      const auto& l = m.arm.joints[static_cast<size_t>(i)].limits;
      q[i] = std::clamp(q[i], l.min_rad + 0.05, l.max_rad - 0.05);
    }
    double time = 0, margin = 1;
    servo::ArmCommand c;
    for (; time < 4; time += dt) {
      const Pose bMed = b.toPose().inverse() * wMed;
      c = task.compute(q, bMed);
      if (c.position_error_m() < 0.001 && c.rotation_error_rad() < 0.2 * M_PI / 180) break;
      const Eigen::VectorXd qdot = robot::limitJointVelocity(m.arm, q, c.qdot_radps, dt);
      for (int i = 0; i < arm.dof(); ++i)
        q[i] = robot::integrateJoint(m.arm.joints[static_cast<size_t>(i)].limits, q[i], qdot[i], dt);
      b = robot::integrateUnicycle(b, c.base_v_mps, c.base_w_radps, dt);
      margin = std::min(margin, servo::jointMargin(m.arm, q));
      EXPECT_LE(std::abs(c.base_v_mps), task.options().max_base_v_mps + 1e-9);
      EXPECT_LE(std::abs(c.base_w_radps), task.options().max_base_w_radps + 1e-9);
    }
    const Pose wMe = b.toPose() * arm.forward(q);
    EXPECT_LT(translationError(wMe, wMed), 0.001) << "start " << k;
    EXPECT_LT(deg(rotationError(wMe, wMed)), 0.2) << "start " << k;
    EXPECT_GT(margin, 0.05) << "start " << k;
    EXPECT_LT(std::hypot(b.x_m - b0.x_m, b.y_m - b0.y_m), 0.05) << "start " << k;
  }
}

// The base held at a fixture (base_may_advance false): the final approach of a grasp, the
// gripper 10 cm behind a reachable pre-grasp pose along its axis, with the base standing still
// in x: the task never drives the base forward and the arm alone brings the gripper there.
TEST(ServoTasks, ArmAlignWithTheBaseHeldReachesWithTheArmAlone) {
  const robot::EnonModel m = enon();
  const robot::ArmKinematics arm(m.arm);
  servo::ArmAlignTask task(m.arm);
  const double dt = m.control_period_s;
  for (const double h : {0.78, 0.84, 0.90}) {
    const servo::ArmReach reach = servo::reachInShoulderPlane(arm, facingForward(), h);
    ASSERT_TRUE(reach.ok);
    const Pose wMed = reach.bMe * Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, 0.10));  // 10 cm on along z_e
    Eigen::VectorXd q = reach.q;
    robot::PlanarPose b{0, 0, 0};
    double max_v = 0, time = 0;
    servo::ArmCommand c;
    for (; time < 6; time += dt) {
      c = task.compute(q, b.toPose().inverse() * wMed, /*base_may_advance=*/false);
      if (c.position_error_m() < 0.001 && c.rotation_error_rad() < 0.2 * M_PI / 180) break;
      max_v = std::max(max_v, c.base_v_mps);
      const Eigen::VectorXd qdot = robot::limitJointVelocity(m.arm, q, c.qdot_radps, dt);
      for (int i = 0; i < arm.dof(); ++i)
        q[i] = robot::integrateJoint(m.arm.joints[static_cast<size_t>(i)].limits, q[i], qdot[i], dt);
      b = robot::integrateUnicycle(b, c.base_v_mps, c.base_w_radps, dt);
    }
    EXPECT_LE(max_v, 0.0) << h;
    EXPECT_LE(b.x_m, 1e-9) << h;
    const Pose wMe = b.toPose() * arm.forward(q);
    EXPECT_LT(translationError(wMe, wMed), 0.001) << h;
    EXPECT_LT(deg(rotationError(wMe, wMed)), 0.2) << h;
    // With the base free the same task drives it forward (what the hold takes away).
    servo::ArmAlignTask free_task(m.arm);
    EXPECT_GT(free_task.compute(reach.q, wMed).base_v_mps, 0.01) << h;
  }
}


// The joint-limit avoidance (vpServo::secondaryTaskJointLimitAvoidance) at work: from harsher
// starts (the base up to 8 cm and 6 deg off its goal, which the arm must make up, often by
// rolling the shoulder towards its -0.3 rad limit) every start converges with the avoidance and
// none touches a limit; without it some joint runs into its limit on at least one start.
TEST(ServoTasks, JointLimitAvoidanceKeepsTheArmOffItsLimits) {
  const robot::EnonModel m = enon();
  const robot::ArmKinematics arm(m.arm);
  for (const bool avoid : {true, false}) {
    servo::ArmAlignOptions o;
    o.joint_limit_avoidance = avoid;
    servo::ArmAlignTask task(m.arm, o);
    std::mt19937 rng(41);
    std::uniform_real_distribution<double> u(-1, 1), height(0.76, 0.90);
    const double dt = m.control_period_s;
    double worst = 1;
    int converged = 0;
    for (int k = 0; k < 20; ++k) {
      const servo::ArmReach reach = servo::reachInShoulderPlane(arm, facingForward(), height(rng));
      const Pose wMed = reach.bMe;
      robot::PlanarPose b{0.08 * u(rng), 0.08 * u(rng), 0.1 * u(rng)};
      Eigen::VectorXd q = reach.q;
      for (int i = 0; i < arm.dof(); ++i) q[i] += 0.25 * u(rng);
      for (int i = 0; i < arm.dof(); ++i) {
        const auto& l = m.arm.joints[static_cast<size_t>(i)].limits;
        q[i] = std::clamp(q[i], l.min_rad + 0.05, l.max_rad - 0.05);
      }
      for (double time = 0; time < 8; time += dt) {
        const servo::ArmCommand c = task.compute(q, b.toPose().inverse() * wMed);
        if (c.position_error_m() < 0.001 && c.rotation_error_rad() < 0.2 * M_PI / 180) {
          ++converged;
          break;
        }
        const Eigen::VectorXd qdot = robot::limitJointVelocity(m.arm, q, c.qdot_radps, dt);
        for (int i = 0; i < arm.dof(); ++i)
          q[i] = robot::integrateJoint(m.arm.joints[static_cast<size_t>(i)].limits, q[i], qdot[i], dt);
        b = robot::integrateUnicycle(b, c.base_v_mps, c.base_w_radps, dt);
        worst = std::min(worst, servo::jointMargin(m.arm, q));
      }
    }
    if (avoid) {
      EXPECT_EQ(converged, 20);
      EXPECT_GT(worst, 0.01);
    } else {
      EXPECT_LT(worst, 0.001);
    }
  }
}
