#include "core/geometry.h"

#include <cmath>
#include <limits>

namespace refgrasp {

double shoelace2(const Eigen::Vector2d* p, size_t n) {
  double a = 0;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d& q = p[(i + 1) % n];
    a += p[i].x() * q.y() - q.x() * p[i].y();
  }
  return a;
}

Eigen::Vector2d polygonCentroid(const std::vector<Eigen::Vector2d>& polygon) {
  double a2 = 0, cx = 0, cy = 0;
  const size_t n = polygon.size();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d &p = polygon[i], &q = polygon[(i + 1) % n];
    const double c = p.x() * q.y() - q.x() * p.y();
    a2 += c;
    cx += (p.x() + q.x()) * c;
    cy += (p.y() + q.y()) * c;
  }
  if (a2 == 0) return Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  return Eigen::Vector2d(cx, cy) / (3 * a2);
}

std::vector<Eigen::Vector2d> clipToBox(const std::vector<Eigen::Vector2d>& polygon,
                                       const Eigen::Vector2d& lo, const Eigen::Vector2d& hi) {
  std::vector<Eigen::Vector2d> out = polygon, in;
  // One half-plane per box side: coordinate `axis` times `sign` <= `sign` x bound.
  for (int side = 0; side < 4 && !out.empty(); ++side) {
    const int axis = side % 2;
    const double sign = side < 2 ? -1 : 1;
    const double bound = side < 2 ? lo[axis] : hi[axis];
    auto inside = [&](const Eigen::Vector2d& p) { return sign * (p[axis] - bound) <= 0; };
    in.swap(out);
    out.clear();
    for (size_t i = 0; i < in.size(); ++i) {
      const Eigen::Vector2d &a = in[i], &b = in[(i + 1) % in.size()];
      if (inside(a)) out.push_back(a);
      if (inside(a) != inside(b)) {
        const double t = (bound - a[axis]) / (b[axis] - a[axis]);
        out.push_back(a + t * (b - a));
      }
    }
  }
  return out;
}

Eigen::Matrix3d hartleyNormalization(const std::vector<Eigen::Vector2d>& p) {
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const auto& x : p) c += x;
  c /= static_cast<double>(p.size());
  double d = 0;
  for (const auto& x : p) d += (x - c).norm();
  d /= static_cast<double>(p.size());
  const double s = d > 1e-12 ? std::sqrt(2.0) / d : 1.0;
  Eigen::Matrix3d T;
  T << s, 0, -s * c.x(), 0, s, -s * c.y(), 0, 0, 1;
  return T;
}

}  // namespace refgrasp
