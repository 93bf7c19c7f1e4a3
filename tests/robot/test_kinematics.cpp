// Kinematics of the enon: hand-computed forward kinematics, Jacobian vs finite differences,
// damped least squares convergence within limits, closed-form base and head motion.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "robot/enon_model.h"
#include "robot/kinematics.h"
#include "robot_test_util.h"

using namespace refgrasp;
using namespace refgrasp::robot;

namespace {

const double kPi = 3.14159265358979323846;

Eigen::VectorXd randomJoints(const ArmModel& arm, std::mt19937_64& rng, double margin) {
  Eigen::VectorXd q(arm.dof());
  for (int i = 0; i < arm.dof(); ++i) {
    const JointLimits& l = arm.joints[static_cast<size_t>(i)].limits;
    q[i] = std::uniform_real_distribution<double>(l.min_rad + margin, l.max_rad - margin)(rng);
  }
  return q;
}

}  // namespace

TEST(Kinematics, DhPlanarTwoLinkMatchesHandComputation) {
  ArmModel arm;
  arm.joints.resize(2);
  arm.joints[0].a_m = 0.3;
  arm.joints[1].a_m = 0.2;
  const ArmKinematics kin(arm);
  const Eigen::Vector2d q(0.4, -0.7);
  const Pose e = kin.forward(q);
  EXPECT_NEAR(e.t.x(), 0.3 * std::cos(0.4) + 0.2 * std::cos(-0.3), 1e-12);
  EXPECT_NEAR(e.t.y(), 0.3 * std::sin(0.4) + 0.2 * std::sin(-0.3), 1e-12);
  EXPECT_NEAR(e.t.z(), 0, 1e-12);
  EXPECT_NEAR(rotationError(e, Pose(axisAngle({0, 0, 1}, -0.3), e.t)), 0, 1e-12);
}

TEST(Kinematics, EnonArmHandComputedPoses) {
  const EnonModel m = testing_util::enonModel();
  const ArmKinematics kin(m.arm);
  const Eigen::Vector3d shoulder(0, -0.20, 1.00);
  const double reach = 0.25 + 0.20 + 0.10;
  Eigen::VectorXd q = Eigen::VectorXd::Zero(5);
  // Hanging straight down, approach axis z_e pointing down.
  Pose e = kin.forward(q);
  EXPECT_NEAR((e.t - (shoulder + Eigen::Vector3d(0, 0, -reach))).norm(), 0, 1e-12);
  EXPECT_NEAR((e.R.col(2) - Eigen::Vector3d(0, 0, -1)).norm(), 0, 1e-12);
  // Shoulder pitch +90 deg: arm straight forward.
  q[0] = kPi / 2;
  e = kin.forward(q);
  EXPECT_NEAR((e.t - (shoulder + Eigen::Vector3d(reach, 0, 0))).norm(), 0, 1e-12);
  EXPECT_NEAR((e.R.col(2) - Eigen::Vector3d(1, 0, 0)).norm(), 0, 1e-12);
  // Elbow +90 deg only: upper arm down, forearm + hand forward.
  q.setZero();
  q[3] = kPi / 2;
  e = kin.forward(q);
  EXPECT_NEAR((e.t - (shoulder + Eigen::Vector3d(0.30, 0, -0.25))).norm(), 0, 1e-12);
  // Shoulder roll +90 deg: arm sideways, away from the body (to the right, -y).
  q.setZero();
  q[1] = kPi / 2;
  e = kin.forward(q);
  EXPECT_NEAR((e.t - (shoulder + Eigen::Vector3d(0, -reach, 0))).norm(), 0, 1e-12);
  // Upper-arm yaw +90 deg with the elbow at 90 deg: forearm turned about the upper arm axis.
  q.setZero();
  q[2] = kPi / 2;
  q[3] = kPi / 2;
  e = kin.forward(q);
  EXPECT_NEAR((e.t - shoulder).z(), -0.25, 1e-12);
  EXPECT_NEAR(std::hypot((e.t - shoulder).x(), (e.t - shoulder).y()), 0.30, 1e-12);
  EXPECT_NEAR(std::abs((e.t - shoulder).x()), 0, 1e-12);  // forward turned to the side
  // Wrist roll turns the gripper about its approach axis, not its position.
  q.setZero();
  q[0] = kPi / 2;
  q[4] = 0.7;
  const Pose e2 = kin.forward(q);
  q[4] = 0;
  const Pose e1 = kin.forward(q);
  EXPECT_NEAR(translationError(e1, e2), 0, 1e-12);
  EXPECT_NEAR(rotationError(e1, e2), 0.7, 1e-12);
  EXPECT_NEAR((e1.R.transpose() * e2.R * Eigen::Vector3d::UnitZ() - Eigen::Vector3d::UnitZ()).norm(),
              0, 1e-12);
}

TEST(Kinematics, JacobianMatchesFiniteDifferences) {
  const EnonModel m = testing_util::enonModel();
  const ArmKinematics kin(m.arm);
  std::mt19937_64 rng(11);
  const double h = 1e-6;
  double worst = 0;
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::VectorXd q = randomJoints(m.arm, rng, 0.0);
    const Jacobian J = kin.jacobian(q);
    const Pose e0 = kin.forward(q);
    for (int i = 0; i < kin.dof(); ++i) {
      Eigen::VectorXd qp = q, qm = q;
      qp[i] += h;
      qm[i] -= h;
      const Pose ep = kin.forward(qp), em = kin.forward(qm);
      const Eigen::Vector3d dv = (ep.t - em.t) / (2 * h);
      // Angular velocity in b: rotation vector of R(q+h) R(q-h)^T over 2h.
      const Eigen::Vector3d dw =
          Pose(ep.R * em.R.transpose(), Eigen::Vector3d::Zero()).rotationVector() / (2 * h);
      worst = std::max(worst, (J.block<3, 1>(0, i) - dv).norm());
      worst = std::max(worst, (J.block<3, 1>(3, i) - dw).norm());
    }
    (void)e0;
  }
  EXPECT_LT(worst, 1e-7);
}

TEST(Kinematics, DampedLeastSquaresReachesReachableTargetsWithinLimits) {
  const EnonModel m = testing_util::enonModel();
  const ArmKinematics kin(m.arm);
  std::mt19937_64 rng(7);
  const double dt = m.control_period_s;
  int reached = 0;
  const int trials = 20;
  double worst_pos = 0, worst_rot = 0;
  int worst_steps = 0;
  for (int trial = 0; trial < trials; ++trial) {
    Eigen::VectorXd q = randomJoints(m.arm, rng, 0.3);
    Eigen::VectorXd qt = q;
    for (int i = 0; i < kin.dof(); ++i) {
      const JointLimits& l = m.arm.joints[static_cast<size_t>(i)].limits;
      qt[i] = std::clamp(q[i] + std::uniform_real_distribution<double>(-0.6, 0.6)(rng),
                         l.min_rad + 0.2, l.max_rad - 0.2);
    }
    const Pose target = kin.forward(qt);
    double pos = 1, rot = 1;
    int k = 0;
    for (; k < 1500; ++k) {  // at most 30 s at 50 Hz
      const Pose e = kin.forward(q);
      const Eigen::Vector3d ep = target.t - e.t;
      const Eigen::Vector3d er = Pose(target.R * e.R.transpose(), Eigen::Vector3d::Zero()).rotationVector();
      pos = ep.norm();
      rot = er.norm();
      if (pos < 1e-3 && rot < 1e-2) break;
      Eigen::Matrix<double, 6, 1> v;
      v << 2.0 * ep, 2.0 * er;
      Eigen::VectorXd qdot = dampedLeastSquares(kin.jacobian(q), v, m.arm.dls_damping);
      qdot = limitJointVelocity(m.arm, q, qdot, dt);
      for (int i = 0; i < kin.dof(); ++i) {
        const JointLimits& l = m.arm.joints[static_cast<size_t>(i)].limits;
        EXPECT_LE(std::abs(qdot[i]), l.max_speed_radps + 1e-12);
        q[i] = integrateJoint(l, q[i], qdot[i], dt);
        ASSERT_GE(q[i], l.min_rad - 1e-12);
        ASSERT_LE(q[i], l.max_rad + 1e-12);
      }
    }
    if (pos < 1e-3 && rot < 1e-2) ++reached;
    worst_steps = std::max(worst_steps, k);
    worst_pos = std::max(worst_pos, pos);
    worst_rot = std::max(worst_rot, rot);
  }
  std::printf("DLS: reached %d/%d, worst final error %.2e m, %.2e rad, worst %d cycles\n",
              reached, trials, worst_pos, worst_rot, worst_steps);
  EXPECT_EQ(reached, trials);
}

TEST(Kinematics, JointVelocityLimitsKeepDirectionAndStopOnPositionLimits) {
  const EnonModel m = testing_util::enonModel();
  Eigen::VectorXd q = Eigen::VectorXd::Constant(5, 0.5);
  Eigen::VectorXd qdot(5);
  qdot << 3.0, -0.5, 0.2, 0.1, 0.0;  // joint 0 at 3x its 1.0 rad/s limit
  const Eigen::VectorXd out = limitJointVelocity(m.arm, q, qdot, 0.02);
  EXPECT_NEAR(out[0], 1.0, 1e-12);
  EXPECT_NEAR((out - qdot / 3.0).norm(), 0, 1e-12);
  // Elbow 1 mrad from its lower limit 0, commanded -1 rad/s: stops exactly on the limit.
  q[3] = 0.001;
  qdot.setZero();
  qdot[3] = -1.0;
  const Eigen::VectorXd o2 = limitJointVelocity(m.arm, q, qdot, 0.02);
  EXPECT_NEAR(q[3] + o2[3] * 0.02, 0.0, 1e-15);
  // Already beyond the limit: never pushed further out.
  q[3] = -0.01;
  EXPECT_EQ(limitJointVelocity(m.arm, q, qdot, 0.02)[3], 0.0);
}

TEST(Kinematics, UnicycleStepsComposeToTheClosedFormArc) {
  const double v = 0.6, w = 0.35, dt = 0.02;
  const PlanarPose start{1.0, -2.0, 0.3};
  PlanarPose p = start;
  const int n = 1500;  // 30 s, more than one full turn
  for (int k = 0; k < n; ++k) p = integrateUnicycle(p, v, w, dt);
  const double T = n * dt;
  const double th = start.theta_rad + w * T;
  EXPECT_NEAR(p.x_m, start.x_m + v / w * (std::sin(th) - std::sin(start.theta_rad)), 1e-9);
  EXPECT_NEAR(p.y_m, start.y_m - v / w * (std::cos(th) - std::cos(start.theta_rad)), 1e-9);
  EXPECT_NEAR(std::remainder(p.theta_rad - th, 2 * kPi), 0, 1e-9);
  // Every point stays on the circle of radius v / w about the centre.
  const double cx = start.x_m - v / w * std::sin(start.theta_rad);
  const double cy = start.y_m + v / w * std::cos(start.theta_rad);
  EXPECT_NEAR(std::hypot(p.x_m - cx, p.y_m - cy), v / w, 1e-9);
  // Straight line and turning on the spot.
  const PlanarPose s = integrateUnicycle(start, 0.5, 0.0, 4.0);
  EXPECT_NEAR(s.x_m, 1.0 + 2.0 * std::cos(0.3), 1e-12);
  EXPECT_NEAR(s.y_m, -2.0 + 2.0 * std::sin(0.3), 1e-12);
  const PlanarPose r = integrateUnicycle(start, 0.0, 0.5, 1.0);
  EXPECT_NEAR(r.x_m, 1.0, 1e-12);
  EXPECT_NEAR(r.theta_rad, 0.8, 1e-12);
}

TEST(Kinematics, BaseVelocityClippingRespectsWheelLimits) {
  const EnonModel m = testing_util::enonModel();
  double v = 5.0, w = 0.0;
  clipBaseVelocity(m.base, &v, &w);
  EXPECT_NEAR(v, 0.83, 1e-12);  // 3 km/h
  v = 0.8;
  w = 1.0;
  clipBaseVelocity(m.base, &v, &w);
  EXPECT_NEAR(std::abs(v) + std::abs(w) * m.base.track_width_m / 2, m.base.max_wheel_speed_mps,
              1e-12);
  EXPECT_NEAR(v / w, 0.8, 1e-12);  // curvature kept
}

TEST(Kinematics, HeadCameraPoseHandComputed) {
  const EnonModel m = testing_util::enonModel();
  Pose c = headCameraPose(m.head, 0, 0);
  EXPECT_NEAR((c.t - Eigen::Vector3d(0.05, 0.06, 1.25)).norm(), 0, 1e-12);
  EXPECT_NEAR((c.R.col(2) - Eigen::Vector3d(1, 0, 0)).norm(), 0, 1e-12);   // looks forward
  EXPECT_NEAR((c.R.col(0) - Eigen::Vector3d(0, -1, 0)).norm(), 0, 1e-12);  // x right
  EXPECT_NEAR((c.R.col(1) - Eigen::Vector3d(0, 0, -1)).norm(), 0, 1e-12);  // y down
  c = headCameraPose(m.head, kPi / 2, 0);
  EXPECT_NEAR((c.t - Eigen::Vector3d(-0.06, 0.05, 1.25)).norm(), 0, 1e-12);
  EXPECT_NEAR((c.R.col(2) - Eigen::Vector3d(0, 1, 0)).norm(), 0, 1e-12);  // looks left
  c = headCameraPose(m.head, 0, 0.3);
  EXPECT_NEAR((c.R.col(2) - Eigen::Vector3d(std::cos(0.3), 0, -std::sin(0.3))).norm(), 0, 1e-12);
  EXPECT_NEAR(c.t.z(), 1.22 + 0.03 * std::cos(0.3) - 0.05 * std::sin(0.3), 1e-12);
}

TEST(Kinematics, JointIntegrationClosedForm) {
  const JointLimits l{-1.0, 1.0, 0.5};
  double q = 0;
  for (int k = 0; k < 30; ++k) q = integrateJoint(l, q, 0.4, 0.1);
  EXPECT_NEAR(q, 1.0, 1e-12);  // 1.2 rad requested, stopped on the limit
  q = 0;
  for (int k = 0; k < 10; ++k) q = integrateJoint(l, q, -2.0, 0.1);  // clipped to 0.5 rad/s
  EXPECT_NEAR(q, -0.5, 1e-12);
  q = 0;
  for (int k = 0; k < 7; ++k) q = moveJointTowards(l, q, 0.6, 0.1);
  EXPECT_NEAR(q, 0.35, 1e-12);
  for (int k = 0; k < 10; ++k) q = moveJointTowards(l, q, 0.6, 0.1);
  EXPECT_NEAR(q, 0.6, 1e-12);
}
