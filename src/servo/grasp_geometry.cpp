#include "servo/grasp_geometry.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace refgrasp::servo {

ObjectExtent objectExtent(const detector::ObjectModel& object) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  ObjectExtent e;
  e.min_o.setConstant(kInf);
  e.max_o.setConstant(-kInf);
  const auto add = [&e](const Eigen::Vector3d& X) {
    e.min_o = e.min_o.cwiseMin(X);
    e.max_o = e.max_o.cwiseMax(X);
  };
  if (object.isMultiView()) {
    for (const detector::ObjectView& v : object.views) {
      if (!v.model) continue;
      const ObjectExtent ve = objectExtent(*v.model);
      for (int k = 0; k < 8; ++k)  // the view's box corners, moved into this object's frame
        add(v.oMv * Eigen::Vector3d(k & 1 ? ve.max_o.x() : ve.min_o.x(), k & 2 ? ve.max_o.y() : ve.min_o.y(),
                                    k & 4 ? ve.max_o.z() : ve.min_o.z()));
    }
  } else if (object.cylinder) {
    const CylinderLabel& c = *object.cylinder;
    add(Eigen::Vector3d(-c.radius_m, -0.5 * c.height_m, 0));
    add(Eigen::Vector3d(c.radius_m, 0.5 * c.height_m, 2 * c.radius_m));
  } else if (object.target) {
    for (const Eigen::Vector3d& X : object.target->corners_o) add(X);
  }
  if (!(e.min_o.array() <= e.max_o.array()).all())
    throw std::invalid_argument("objectExtent: object '" + object.name + "' has no metric geometry (2D only)");
  return e;
}

double ObjectExtent::depthBehind(const Pose& oMg) const {
  const Eigen::Vector3d p = oMg.t, d = -oMg.R.col(2);  // the line p + s d, s >= 0, out of the object
  if (((p - min_o).array() < 0).any() || ((max_o - p).array() < 0).any()) return 0;
  double s = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 3; ++i) {
    if (d[i] > 1e-12) s = std::min(s, (max_o[i] - p[i]) / d[i]);
    if (d[i] < -1e-12) s = std::min(s, (min_o[i] - p[i]) / d[i]);
  }
  return std::isfinite(s) ? s : 0;
}

double jointMargin(const robot::ArmModel& arm, const Eigen::VectorXd& q) {
  double m = 1.0;
  for (int i = 0; i < arm.dof() && i < q.size(); ++i) {
    const robot::JointLimits& l = arm.joints[static_cast<size_t>(i)].limits;
    const double range = l.max_rad - l.min_rad;
    if (range <= 0) continue;
    m = std::min(m, std::min(q[i] - l.min_rad, l.max_rad - q[i]) / range);
  }
  return m;
}

double planarHeading(const Pose& p) { return std::atan2(p.R(1, 0), p.R(0, 0)); }

ArmReach reachInShoulderPlane(const robot::ArmKinematics& arm, const Eigen::Matrix3d& bRe,
                              double z_m, const Eigen::VectorXd& q_start) {
  const robot::ArmModel& model = arm.model();
  const int n = arm.dof();
  Eigen::VectorXd q(n);
  for (int i = 0; i < n; ++i) {
    const robot::JointLimits& l = model.joints[static_cast<size_t>(i)].limits;
    q[i] = q_start.size() == n ? q_start[i] : 0.5 * (l.min_rad + l.max_rad);
  }
  const double y_m = model.bM0.t.y();
  // Rows: y, z of e's origin; rotation error (3), in b. Damped Newton, joints kept in range.
  ArmReach r;
  for (int it = 0; it < 200; ++it) {
    const Pose bMe = arm.forward(q);
    Eigen::Matrix<double, 5, 1> err;
    err << y_m - bMe.t.y(), z_m - bMe.t.z(),
        Pose(bRe * bMe.R.transpose(), Eigen::Vector3d::Zero()).rotationVector();
    r.position_error_m = err.head<2>().norm();
    r.rotation_error_rad = err.tail<3>().norm();
    if (r.position_error_m < 1e-6 && r.rotation_error_rad < 1e-6) break;
    const robot::Jacobian J = arm.jacobian(q);
    Eigen::MatrixXd A(5, n);
    A.row(0) = J.row(1);
    A.row(1) = J.row(2);
    A.bottomRows(3) = J.bottomRows(3);
    const double lambda = 0.02;
    const Eigen::MatrixXd AAt = A * A.transpose() + lambda * lambda * Eigen::MatrixXd::Identity(5, 5);
    Eigen::VectorXd dq = A.transpose() * AAt.ldlt().solve(err);
    const double big = dq.cwiseAbs().maxCoeff();
    if (big > 0.3) dq *= 0.3 / big;
    q += dq;
    for (int i = 0; i < n; ++i) {
      const robot::JointLimits& l = model.joints[static_cast<size_t>(i)].limits;
      q[i] = std::clamp(q[i], l.min_rad, l.max_rad);
    }
  }
  r.q = q;
  r.bMe = arm.forward(q);
  r.joint_margin = jointMargin(model, q);
  r.ok = r.position_error_m < 1e-4 && r.rotation_error_rad < 1e-4 && r.joint_margin > 0;
  return r;
}

BaseGoal baseGoalFor(const robot::ArmKinematics& arm, const Pose& wMed,
                     const Eigen::VectorXd& q_start) {
  BaseGoal g;
  const Eigen::Vector3d z = wMed.R.col(2);
  g.heading_rad = std::atan2(z.y(), z.x());
  const Eigen::Matrix3d wRb = axisAngle(Eigen::Vector3d::UnitZ(), g.heading_rad);
  g.reach = reachInShoulderPlane(arm, wRb.transpose() * wMed.R, wMed.t.z(), q_start);
  Eigen::Vector3d offset = wRb * g.reach.bMe.t;  // e's origin from the base origin, in w
  Eigen::Vector3d p = wMed.t - offset;
  p.z() = 0;
  g.wMb = Pose(wRb, p);
  return g;
}

ApproachPoints approachPoints(const Pose& wMb, const Pose& wMG, double lookahead_m,
                              double waypoint_m) {
  ApproachPoints a;
  const Eigen::Vector2d g = wMG.t.head<2>(), p = wMb.t.head<2>();
  const double hg = planarHeading(wMG);
  const Eigen::Vector2d dir(std::cos(hg), std::sin(hg));
  a.along_m = (p - g).dot(dir);
  a.lateral_m = dir.x() * (p - g).y() - dir.y() * (p - g).x();
  a.position_error_m = (p - g).norm();
  a.heading_error_rad = std::remainder(hg - planarHeading(wMb), 2 * M_PI);
  const double carrot = std::min(a.along_m + lookahead_m, lookahead_m);
  const Eigen::Vector2d c = g + carrot * dir, q = g + lookahead_m * dir, w = g - waypoint_m * dir;
  const Pose bMw = wMb.inverse();
  a.bAim = bMw * Eigen::Vector3d(c.x(), c.y(), 0);
  a.bDepth = bMw * Eigen::Vector3d(q.x(), q.y(), 0);
  a.bWaypoint = bMw * Eigen::Vector3d(w.x(), w.y(), 0);
  a.bAhead = bMw * Eigen::Vector3d(p.x() + 10 * dir.x(), p.y() + 10 * dir.y(), 0);
  a.bWaypoint.z() = a.bAim.z() = a.bDepth.z() = a.bAhead.z() = 0;
  a.depth_desired_m = lookahead_m;
  return a;
}

}  // namespace refgrasp::servo
