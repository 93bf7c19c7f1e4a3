#pragma once
// Rigid transforms. Convention (as ViSP's cMo): aMb maps coordinates of a point in frame b to
// frame a, x_in_a = R * x_in_b + t. So cMo is the pose of the object frame in the camera frame.
// Units: metres and radians everywhere.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace refgrasp {

struct Pose {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();  ///< metres

  Pose() = default;
  Pose(const Eigen::Matrix3d& R_, const Eigen::Vector3d& t_) : R(R_), t(t_) {}
  /// From an axis-angle vector (axis * angle, radians) and a translation (metres).
  static Pose fromRotationVector(const Eigen::Vector3d& rvec, const Eigen::Vector3d& t);

  Eigen::Vector3d rotationVector() const;  ///< axis * angle, angle in [0, pi]
  Eigen::Matrix4d matrix() const;
  Pose inverse() const { return Pose(R.transpose(), -R.transpose() * t); }
  Pose operator*(const Pose& o) const { return Pose(R * o.R, R * o.t + t); }
  Eigen::Vector3d operator*(const Eigen::Vector3d& x) const { return R * x + t; }
  bool isFinite() const { return R.allFinite() && t.allFinite(); }
};

/// Angle (radians) of the rotation taking a.R to b.R.
double rotationError(const Pose& a, const Pose& b);
/// Euclidean distance (metres) between a.t and b.t.
double translationError(const Pose& a, const Pose& b);
/// Rigid interpolation from a (s = 0) to b (s = 1): slerp of the rotation, linear translation.
Pose interpolate(const Pose& a, const Pose& b, double s);
/// Rotation about `axis` (unit or not) by `angle` radians.
Eigen::Matrix3d axisAngle(const Eigen::Vector3d& axis, double angle);

}  // namespace refgrasp
