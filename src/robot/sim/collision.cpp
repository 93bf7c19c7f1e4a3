#include "robot/sim/collision.h"

#include <algorithm>
#include <cmath>

namespace refgrasp::sim {

namespace {

// Signed distance to the axis-aligned box [-h, h] (box coordinates).
double boxSdf(const Eigen::Vector3d& q, const Eigen::Vector3d& h) {
  const Eigen::Vector3d d = q.cwiseAbs() - h;
  const double outside = d.cwiseMax(0.0).norm();
  const double inside = std::min(d.maxCoeff(), 0.0);
  return outside + inside;
}

double rectSdf(const Eigen::Vector2d& q, const Eigen::Vector2d& h) {
  const Eigen::Vector2d d = q.cwiseAbs() - h;
  return d.cwiseMax(0.0).norm() + std::min(d.maxCoeff(), 0.0);
}

// Signed distance to the cylinder about the z axis of radius r, z in [-h, h] (its coordinates).
double cylinderSdf(const Eigen::Vector3d& q, double r, double h) {
  const double radial = std::hypot(q.x(), q.y()) - r, axial = std::abs(q.z()) - h;
  return std::hypot(std::max(radial, 0.0), std::max(axial, 0.0)) + std::min(std::max(radial, axial), 0.0);
}

// Minimum of a convex function f of the segment parameter s in [0, 1], for a segment of length
// len: the segment's points are within tolerance_m of the minimiser's. `s_min` (optional) gets s.
template <class F>
double minimumOnSegment(const F& f, double len, double* s_min, double tolerance_m) {
  double lo = 0, hi = 1;
  // Golden section: the bracket [lo, hi] always holds a minimiser of the convex f.
  constexpr double kInvPhi = 0.6180339887498949;
  double x1 = hi - kInvPhi * (hi - lo), x2 = lo + kInvPhi * (hi - lo);
  double f1 = f(x1), f2 = f(x2);
  while ((hi - lo) * len > tolerance_m) {
    if (f1 <= f2) {
      hi = x2;
      x2 = x1;
      f2 = f1;
      x1 = hi - kInvPhi * (hi - lo);
      f1 = f(x1);
    } else {
      lo = x1;
      x1 = x2;
      f1 = f2;
      x2 = lo + kInvPhi * (hi - lo);
      f2 = f(x2);
    }
  }
  // The minimiser is within tolerance of every point of the bracket; the ends of the segment
  // are checked too (a minimum at s = 0 or 1 is reached only in the limit otherwise).
  double best_s = f1 <= f2 ? x1 : x2, best = std::min(f1, f2);
  for (const double s : {0.0, 1.0}) {
    const double v = f(s);
    if (v < best) best = v, best_s = s;
  }
  if (s_min) *s_min = best_s;
  return best;
}

// Signed distance between a vertical cylinder c and a vertical prism spanning z in [z_lo, z_hi]
// whose cross-section is `horizontal` away from c's disc (signed, in the horizontal plane).
double prismDistance(double horizontal, double z_lo, double z_hi, const VerticalCylinder& c) {
  const double vertical_gap = std::max(z_lo - (c.z0_m + c.height_m), c.z0_m - z_hi);
  // Distance between two prisms: both gaps combine; overlapping in one direction, the other
  // decides; overlapping in both, the shallower penetration.
  if (horizontal > 0 && vertical_gap > 0) return std::hypot(horizontal, vertical_gap);
  return std::max(horizontal, vertical_gap);
}

}  // namespace

double signedDistance(const OrientedBox& box, const Eigen::Vector3d& p) {
  return boxSdf(box.wMb.R.transpose() * (p - box.wMb.t), box.half_m);
}

double segmentSignedDistance(const OrientedBox& box, const Eigen::Vector3d& a,
                             const Eigen::Vector3d& b, double* s_min, double tolerance_m) {
  // In box coordinates, once.
  const Eigen::Vector3d qa = box.wMb.R.transpose() * (a - box.wMb.t);
  const Eigen::Vector3d qd = box.wMb.R.transpose() * (b - a);
  return minimumOnSegment([&](double s) { return boxSdf(qa + s * qd, box.half_m); }, qd.norm(), s_min,
                          tolerance_m);
}

double signedDistance(const OrientedBox& box, const Capsule& c) {
  return segmentSignedDistance(box, c.a, c.b) - c.radius_m;
}

double signedDistance(const OrientedBox& box, const VerticalCylinder& c) {
  const Eigen::Matrix3d& R = box.wMb.R;
  int vertical = -1;
  for (int k = 0; k < 3; ++k)
    if (std::abs(R(2, k)) > 1 - 1e-9) vertical = k;
  Eigen::Vector2d u, v, h;  // horizontal axes (unit) and half extents of the box's footprint
  double half_z;
  if (vertical >= 0) {
    const int i = (vertical + 1) % 3, j = (vertical + 2) % 3;
    u = R.block<2, 1>(0, i).normalized();
    v = R.block<2, 1>(0, j).normalized();
    h = Eigen::Vector2d(box.half_m[i], box.half_m[j]);
    half_z = box.half_m[vertical];
  } else {
    // Tilted: its world-axis-aligned bounding box.
    const Eigen::Vector3d aabb = R.cwiseAbs() * box.half_m;
    u = Eigen::Vector2d::UnitX();
    v = Eigen::Vector2d::UnitY();
    h = aabb.head<2>();
    half_z = aabb.z();
  }
  const Eigen::Vector2d p = c.centre - box.wMb.t.head<2>();
  const double horizontal = rectSdf(Eigen::Vector2d(p.dot(u), p.dot(v)), h) - c.radius_m;
  return prismDistance(horizontal, box.wMb.t.z() - half_z, box.wMb.t.z() + half_z, c);
}

double extentAlong(const OrientedBox& box, const Eigen::Vector3d& u) {
  return 2 * (box.wMb.R.transpose() * u).cwiseAbs().dot(box.half_m);
}

double signedDistance(const OrientedCylinder& c, const Eigen::Vector3d& p) {
  return cylinderSdf(c.wMc.R.transpose() * (p - c.wMc.t), c.radius_m, c.half_height_m);
}

double segmentSignedDistance(const OrientedCylinder& c, const Eigen::Vector3d& a,
                             const Eigen::Vector3d& b, double* s_min, double tolerance_m) {
  const Eigen::Vector3d qa = c.wMc.R.transpose() * (a - c.wMc.t);
  const Eigen::Vector3d qd = c.wMc.R.transpose() * (b - a);
  return minimumOnSegment([&](double s) { return cylinderSdf(qa + s * qd, c.radius_m, c.half_height_m); },
                          qd.norm(), s_min, tolerance_m);
}

double signedDistance(const OrientedCylinder& c, const Capsule& cap) {
  return segmentSignedDistance(c, cap.a, cap.b) - cap.radius_m;
}

double signedDistance(const OrientedCylinder& c, const VerticalCylinder& v) {
  // Two prisms over discs: an upright cylinder about c's centre of this radius and half height.
  const auto upright = [&](double radius_m, double half_height_m) {
    const double horizontal = (v.centre - c.wMc.t.head<2>()).norm() - radius_m - v.radius_m;
    return prismDistance(horizontal, c.wMc.t.z() - half_height_m, c.wMc.t.z() + half_height_m, v);
  };
  const Eigen::Vector3d axis = c.wMc.R.col(2);
  if (std::abs(axis.z()) > 1 - 1e-9) return upright(c.radius_m, c.half_height_m);
  // Tilted: two solids that contain it, its world-axis-aligned bounding box and the upright
  // cylinder about its centre that bounds it; each is at most as far as c, so the larger of
  // their distances is too (the cylinder is the tighter one when c is nearly upright).
  Eigen::Vector3d half;
  for (int k = 0; k < 3; ++k) half[k] = extentAlong(c, Eigen::Vector3d::Unit(k)) / 2;
  const double sideways = axis.head<2>().norm();
  return std::max(signedDistance(OrientedBox{Pose(Eigen::Matrix3d::Identity(), c.wMc.t), half}, v),
                  upright(c.radius_m + c.half_height_m * sideways, half.z()));
}

double extentAlong(const OrientedCylinder& c, const Eigen::Vector3d& u) {
  const double along = c.wMc.R.col(2).dot(u);
  return 2 * (c.half_height_m * std::abs(along) + c.radius_m * std::sqrt(std::max(0.0, 1 - along * along)));
}

}  // namespace refgrasp::sim
