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
  return clipToConvex(polygon, {lo, Eigen::Vector2d(hi.x(), lo.y()), hi, Eigen::Vector2d(lo.x(), hi.y())});
}

std::vector<Eigen::Vector2d> clipToConvex(const std::vector<Eigen::Vector2d>& polygon,
                                          const std::vector<Eigen::Vector2d>& convex) {
  if (convex.size() < 3) return {};
  const double orientation = signedArea(convex) >= 0 ? 1 : -1;
  std::vector<Eigen::Vector2d> out = polygon, in;
  for (size_t e = 0; e < convex.size() && !out.empty(); ++e) {
    const Eigen::Vector2d& c = convex[e];
    const Eigen::Vector2d d = convex[(e + 1) % convex.size()] - c;
    // >= 0: on the inner side of the edge (left of it for a positive winding).
    auto side = [&](const Eigen::Vector2d& p) { return orientation * (d.x() * (p.y() - c.y()) - d.y() * (p.x() - c.x())); };
    in.swap(out);
    out.clear();
    for (size_t i = 0; i < in.size(); ++i) {
      const Eigen::Vector2d &a = in[i], &b = in[(i + 1) % in.size()];
      const double sa = side(a), sb = side(b);
      if (sa >= 0) out.push_back(a);
      if ((sa >= 0) != (sb >= 0)) out.push_back(a + sa / (sa - sb) * (b - a));
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
