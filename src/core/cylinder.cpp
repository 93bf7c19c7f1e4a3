#include "core/cylinder.h"

#include <cmath>

#include "core/error.h"

namespace refgrasp {

namespace {
// A measured label may come out slightly longer than the circumference.
constexpr double kWrapTolerance = 0.01;
}  // namespace

void CylinderLabel::check(const std::string& where) const {
  auto positive = [](double x) { return std::isfinite(x) && x > 0; };
  if (!positive(radius_m)) throw ConfigError(where, "cylinder.radius_m", "must be a positive number of metres");
  if (!positive(width_m) || !positive(height_m))
    throw ConfigError(where, "cylinder.label_size_m", "must be two positive numbers of metres");
  if (image_width <= 0 || image_height <= 0)
    throw ConfigError(where, "reference_image", "empty label image");
  const double circumference = 2 * M_PI * radius_m;
  if (width_m > circumference * (1 + kWrapTolerance))
    throw ConfigError(where, "cylinder.label_size_m",
                      "width " + std::to_string(width_m) + " m is longer than the circumference 2 pi r = " +
                          std::to_string(circumference) + " m (radius_m " + std::to_string(radius_m) + ")");
}

bool CylinderLabel::fullWrap() const {
  return std::abs(width_m - 2 * M_PI * radius_m) <= kWrapTolerance * 2 * M_PI * radius_m;
}

double CylinderLabel::theta(double u) const {
  return (u - (image_width - 1) / 2.0) * metresPerPixelU() / radius_m;
}

Eigen::Vector3d CylinderLabel::point(const Eigen::Vector2d& uv) const {
  const double th = theta(uv.x());
  const double y = (uv.y() - (image_height - 1) / 2.0) * metresPerPixelV();
  return Eigen::Vector3d(radius_m * std::sin(th), y, radius_m * (1 - std::cos(th)));
}

Eigen::Vector3d CylinderLabel::normal(double u) const {
  const double th = theta(u);
  return Eigen::Vector3d(std::sin(th), 0, -std::cos(th));
}

std::optional<Eigen::Vector2d> CylinderLabel::pixel(const Eigen::Vector3d& X) const {
  // Angle about the axis, measured from the label centre's direction (-z from the axis).
  const double sx = X.x(), sz = radius_m - X.z();
  if (std::hypot(sx, sz) < 1e-12) return std::nullopt;
  double th = std::atan2(sx, sz);  // (-pi, pi]
  double u = th * radius_m / metresPerPixelU() + (image_width - 1) / 2.0;
  if (fullWrap()) {
    // Wrap into [-0.5, W - 0.5): the label's columns cover the whole circumference.
    const double period = 2 * M_PI * radius_m / metresPerPixelU();
    u = std::fmod(u + 0.5, period);
    if (u < 0) u += period;
    u -= 0.5;
    if (u >= image_width - 0.5) u = std::min(u, image_width - 0.5);
  } else if (u < -0.5 || u > image_width - 0.5) {
    return std::nullopt;
  }
  const double v = X.y() / metresPerPixelV() + (image_height - 1) / 2.0;
  return Eigen::Vector2d(u, v);
}

bool CylinderLabel::facesCamera(double u, double v, const Pose& cMo, double cos_margin) const {
  const Eigen::Vector3d X = point(Eigen::Vector2d(u, v));
  const Eigen::Vector3d camera_o = cMo.inverse().t;
  const Eigen::Vector3d ray = camera_o - X;
  const double len = ray.norm();
  if (!(len > 0)) return false;
  return normal(u).dot(ray) / len > cos_margin;
}

std::optional<double> CylinderLabel::intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
  // Distance from the axis (x = 0, z = r), in the x-z plane: |(o + t d) - axis|^2 = r^2.
  const double ox = o.x(), oz = o.z() - radius_m, dx = d.x(), dz = d.z();
  const double a = dx * dx + dz * dz;
  if (!(a > 1e-18)) return std::nullopt;  // parallel to the axis
  const double b = 2 * (ox * dx + oz * dz);
  const double c = ox * ox + oz * oz - radius_m * radius_m;
  const double disc = b * b - 4 * a * c;
  if (!(disc >= 0)) return std::nullopt;
  // The entering intersection (smaller t) is where the outer surface faces the ray.
  const double t = (-b - std::sqrt(disc)) / (2 * a);
  if (!(t > 0)) return std::nullopt;
  return t;
}

}  // namespace refgrasp
