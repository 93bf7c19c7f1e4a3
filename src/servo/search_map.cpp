#include "servo/search_map.h"

#include <algorithm>
#include <cmath>

namespace refgrasp::servo {

bool Footprint::contains(const Eigen::Vector2d& p, double margin_m) const {
  const Eigen::Vector2d d = p - centre;
  const double c = std::cos(yaw_rad), s = std::sin(yaw_rad);
  const double x = c * d.x() + s * d.y(), y = -s * d.x() + c * d.y();  // in the footprint's axes
  return std::abs(x) <= half_m.x() + margin_m && std::abs(y) <= half_m.y() + margin_m;
}

double Footprint::distance(const Eigen::Vector2d& p) const {
  const Eigen::Vector2d d = p - centre;
  const double c = std::cos(yaw_rad), s = std::sin(yaw_rad);
  const double x = c * d.x() + s * d.y(), y = -s * d.x() + c * d.y();
  return std::hypot(std::max(0.0, std::abs(x) - half_m.x()), std::max(0.0, std::abs(y) - half_m.y()));
}

}  // namespace refgrasp::servo
