#include "robot/kinematics.h"

#include <algorithm>
#include <cmath>

namespace refgrasp::robot {

Pose PlanarPose::toPose() const {
  return Pose(axisAngle(Eigen::Vector3d::UnitZ(), theta_rad), Eigen::Vector3d(x_m, y_m, 0));
}

PlanarPose integrateUnicycle(const PlanarPose& s, double v, double w, double dt) {
  PlanarPose e = s;
  const double dth = w * dt;
  e.theta_rad = s.theta_rad + dth;
  if (std::abs(dth) < 1e-9) {
    // Second-order expansion of the arc; exact to rounding for |dth| this small.
    const double mid = s.theta_rad + 0.5 * dth;
    e.x_m += v * dt * std::cos(mid);
    e.y_m += v * dt * std::sin(mid);
  } else {
    e.x_m += v / w * (std::sin(e.theta_rad) - std::sin(s.theta_rad));
    e.y_m -= v / w * (std::cos(e.theta_rad) - std::cos(s.theta_rad));
  }
  // Keep theta in (-pi, pi] so long runs do not lose precision.
  e.theta_rad = std::atan2(std::sin(e.theta_rad), std::cos(e.theta_rad));
  return e;
}

void clipBaseVelocity(const BaseModel& base, double* v, double* w) {
  *v = std::clamp(*v, -base.max_linear_speed_mps, base.max_linear_speed_mps);
  *w = std::clamp(*w, -base.max_angular_speed_radps, base.max_angular_speed_radps);
  const double wheel = std::abs(*v) + std::abs(*w) * 0.5 * base.track_width_m;
  if (wheel > base.max_wheel_speed_mps) {
    const double s = base.max_wheel_speed_mps / wheel;
    *v *= s;
    *w *= s;
  }
}

Pose headCameraPose(const HeadModel& head, double pan, double tilt) {
  const Pose pMt(axisAngle(Eigen::Vector3d::UnitZ(), pan) * axisAngle(Eigen::Vector3d::UnitY(), tilt),
                 Eigen::Vector3d(0, 0, head.tilt_height_m));
  return head.bMp * pMt * head.tMc;
}

double integrateJoint(const JointLimits& l, double q, double rate, double dt) {
  rate = std::clamp(rate, -l.max_speed_radps, l.max_speed_radps);
  return std::clamp(q + rate * dt, std::min(q, l.min_rad), std::max(q, l.max_rad));
}

double moveJointTowards(const JointLimits& l, double q, double target, double dt) {
  target = std::clamp(target, l.min_rad, l.max_rad);
  const double step = l.max_speed_radps * dt;
  return q + std::clamp(target - q, -step, step);
}

Pose dhTransform(const DhJoint& j, double q) {
  const double th = q + j.theta_offset_rad;
  const double ct = std::cos(th), st = std::sin(th);
  const double ca = std::cos(j.alpha_rad), sa = std::sin(j.alpha_rad);
  Eigen::Matrix3d R;
  R << ct, -st * ca, st * sa,  //
      st, ct * ca, -ct * sa,   //
      0, sa, ca;
  return Pose(R, Eigen::Vector3d(j.a_m * ct, j.a_m * st, j.d_m));
}

std::vector<Pose> ArmKinematics::frames(const Eigen::VectorXd& q) const {
  std::vector<Pose> out;
  out.reserve(arm_.joints.size() + 2);
  Pose bMi = arm_.bM0;
  out.push_back(bMi);
  for (size_t i = 0; i < arm_.joints.size(); ++i) {
    bMi = bMi * dhTransform(arm_.joints[i], q[static_cast<Eigen::Index>(i)]);
    out.push_back(bMi);
  }
  out.push_back(bMi * arm_.nMe);
  return out;
}

Pose ArmKinematics::forward(const Eigen::VectorXd& q) const { return frames(q).back(); }

Jacobian ArmKinematics::jacobian(const Eigen::VectorXd& q) const {
  const std::vector<Pose> f = frames(q);
  const Eigen::Vector3d pe = f.back().t;
  Jacobian J(6, dof());
  for (int i = 0; i < dof(); ++i) {
    // Joint i+1 turns about z of DH frame i.
    const Eigen::Vector3d z = f[static_cast<size_t>(i)].R.col(2);
    const Eigen::Vector3d p = f[static_cast<size_t>(i)].t;
    J.block<3, 1>(0, i) = z.cross(pe - p);
    J.block<3, 1>(3, i) = z;
  }
  return J;
}

Eigen::VectorXd dampedLeastSquares(const Jacobian& J, const Eigen::Matrix<double, 6, 1>& v,
                                   double lambda) {
  const Eigen::Matrix<double, 6, 6> A =
      J * J.transpose() + lambda * lambda * Eigen::Matrix<double, 6, 6>::Identity();
  return J.transpose() * A.ldlt().solve(v);
}

Eigen::VectorXd limitJointVelocity(const ArmModel& arm, const Eigen::VectorXd& q,
                                   const Eigen::VectorXd& qdot, double dt) {
  Eigen::VectorXd out = qdot;
  double scale = 1.0;
  for (int i = 0; i < arm.dof(); ++i) {
    const double lim = arm.joints[static_cast<size_t>(i)].limits.max_speed_radps;
    if (std::abs(out[i]) > lim) scale = std::min(scale, lim / std::abs(out[i]));
  }
  out *= scale;
  if (dt <= 0) return out;
  for (int i = 0; i < arm.dof(); ++i) {
    const JointLimits& l = arm.joints[static_cast<size_t>(i)].limits;
    const double next = q[i] + out[i] * dt;
    if (out[i] > 0 && next > l.max_rad) out[i] = std::max(0.0, (l.max_rad - q[i]) / dt);
    if (out[i] < 0 && next < l.min_rad) out[i] = std::min(0.0, (l.min_rad - q[i]) / dt);
  }
  return out;
}

Twist rotateTwist(const Eigen::Matrix3d& R, const Twist& v) {
  Twist o;
  o.v = R * v.v;
  o.w = R * v.w;
  return o;
}

}  // namespace refgrasp::robot
