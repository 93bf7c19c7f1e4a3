#pragma once
// Kinematics of the enon: differential-drive base (unicycle), pan-tilt head, serial DH arm.
// Frames and conventions are those of robot/enon_model.h. Metres, radians, seconds.
#include <Eigen/Core>
#include <vector>

#include "core/pose.h"
#include "core/types.h"
#include "robot/enon_model.h"

namespace refgrasp::robot {

using Jacobian = Eigen::Matrix<double, 6, Eigen::Dynamic>;

// ---- Base ------------------------------------------------------------------------------------

/// Base pose on the floor: wMb = (Rz(theta), (x, y, 0)).
struct PlanarPose {
  double x_m = 0, y_m = 0, theta_rad = 0;
  Pose toPose() const;
};

/// Exact unicycle motion with constant (v, w) over dt: a circular arc (a segment when w = 0).
PlanarPose integrateUnicycle(const PlanarPose& start, double v_mps, double w_radps, double dt_s);

/// Clips (v, w) to the base limits: each to its own bound, then both scaled by one factor so that
/// neither wheel exceeds max_wheel_speed_mps (keeps the curvature v / w).
void clipBaseVelocity(const BaseModel& base, double* v_mps, double* w_radps);

// ---- Head ------------------------------------------------------------------------------------

/// bMc: left camera optical frame in the base frame for the given pan and tilt.
Pose headCameraPose(const HeadModel& head, double pan_rad, double tilt_rad);

/// A joint position after moving at `rate` for dt, stopped at the position limits.
double integrateJoint(const JointLimits& limits, double q_rad, double rate_radps, double dt_s);
/// A joint position after moving towards `target` at the joint's top speed for dt.
double moveJointTowards(const JointLimits& limits, double q_rad, double target_rad, double dt_s);

// ---- Arm -------------------------------------------------------------------------------------

/// i-1Mi for one standard DH row at joint angle q.
Pose dhTransform(const DhJoint& j, double q_rad);

class ArmKinematics {
 public:
  explicit ArmKinematics(const ArmModel& arm) : arm_(arm) {}
  int dof() const { return arm_.dof(); }
  const ArmModel& model() const { return arm_; }

  /// bMe: gripper frame in the base frame.
  Pose forward(const Eigen::VectorXd& q) const;
  /// bMi for i = 0..n (DH frames; element 0 is bM0), then bMe as the last element.
  std::vector<Pose> frames(const Eigen::VectorXd& q) const;
  /// Geometric Jacobian in the base frame, reference point at the origin of e:
  /// bVe = (v of e's origin, w), both expressed in b, = J(q) * qdot.
  Jacobian jacobian(const Eigen::VectorXd& q) const;

 private:
  ArmModel arm_;
};

/// Damped least squares: qdot = J^T (J J^T + lambda^2 I)^-1 v.
Eigen::VectorXd dampedLeastSquares(const Jacobian& J, const Eigen::Matrix<double, 6, 1>& v,
                                   double lambda);

/// Joint velocities made safe: all scaled by one factor so none exceeds its speed limit (keeps
/// the direction), then any joint that would cross a position limit within dt is slowed to stop
/// exactly on it (and does not move further out when already beyond it).
Eigen::VectorXd limitJointVelocity(const ArmModel& arm, const Eigen::VectorXd& q,
                                   const Eigen::VectorXd& qdot, double dt_s);

/// Twist in b expressed from a twist in e: bVe = [bRe 0; 0 bRe] eVe (same reference point).
Twist rotateTwist(const Eigen::Matrix3d& R, const Twist& v);

}  // namespace refgrasp::robot
