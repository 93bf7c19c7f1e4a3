#include "core/pose.h"

#include <cmath>

namespace refgrasp {

Pose Pose::fromRotationVector(const Eigen::Vector3d& rvec, const Eigen::Vector3d& t) {
  const double angle = rvec.norm();
  if (angle < 1e-15) return Pose(Eigen::Matrix3d::Identity(), t);
  return Pose(Eigen::AngleAxisd(angle, rvec / angle).toRotationMatrix(), t);
}

Eigen::Vector3d Pose::rotationVector() const {
  const Eigen::AngleAxisd aa(R);
  return aa.axis() * aa.angle();
}

Eigen::Matrix4d Pose::matrix() const {
  Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
  M.topLeftCorner<3, 3>() = R;
  M.topRightCorner<3, 1>() = t;
  return M;
}

double rotationError(const Pose& a, const Pose& b) {
  const Eigen::Matrix3d dR = a.R.transpose() * b.R;
  // atan2 keeps precision near zero, where acos((tr - 1) / 2) loses half the digits.
  const Eigen::Vector3d s(dR(2, 1) - dR(1, 2), dR(0, 2) - dR(2, 0), dR(1, 0) - dR(0, 1));
  return std::atan2(0.5 * s.norm(), 0.5 * (dR.trace() - 1.0));
}

double translationError(const Pose& a, const Pose& b) { return (a.t - b.t).norm(); }

Eigen::Matrix3d axisAngle(const Eigen::Vector3d& axis, double angle) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

Pose interpolate(const Pose& a, const Pose& b, double s) {
  const Eigen::Quaterniond qa(a.R), qb(b.R);
  return Pose(qa.slerp(s, qb).toRotationMatrix(), (1 - s) * a.t + s * b.t);
}

}  // namespace refgrasp
