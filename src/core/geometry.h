#pragma once
// Plane geometry shared by every module: polygon area and centroid (shoelace), isotropic point
// normalisation. Pixels or metres alike; a polygon is its vertices in order, closed implicitly.
#include <Eigen/Core>
#include <cstddef>
#include <vector>

namespace refgrasp {

/// Twice the signed area (shoelace sum of x_i y_{i+1} - x_{i+1} y_i). Positive when the vertices
/// turn from +x towards +y (clockwise on screen in image coordinates, y down).
double shoelace2(const Eigen::Vector2d* polygon, size_t n);

/// Signed area, half the shoelace sum (any container of Eigen::Vector2d with data()/size()).
template <class Polygon>
double signedArea(const Polygon& polygon) {
  return 0.5 * shoelace2(polygon.data(), polygon.size());
}

/// Area-weighted centroid. Needs a non-zero area; returns NaN coordinates otherwise.
Eigen::Vector2d polygonCentroid(const std::vector<Eigen::Vector2d>& polygon);

/// The part of a simple polygon (any winding, convex or not) inside the axis-aligned box
/// [lo, hi] (Sutherland-Hodgman): its area is the intersection's; empty when they do not meet.
std::vector<Eigen::Vector2d> clipToBox(const std::vector<Eigen::Vector2d>& polygon,
                                       const Eigen::Vector2d& lo, const Eigen::Vector2d& hi);
/// The part of a simple polygon (any winding, convex or not) inside a convex polygon (any
/// winding; Sutherland-Hodgman, one half-plane per edge): its area is the intersection's.
std::vector<Eigen::Vector2d> clipToConvex(const std::vector<Eigen::Vector2d>& polygon,
                                          const std::vector<Eigen::Vector2d>& convex);

/// Isotropic (Hartley) normalisation: the similarity T with T x = s (x - c), c the centroid and
/// s making the mean distance from it sqrt(2) (s = 1 for coincident points).
Eigen::Matrix3d hartleyNormalization(const std::vector<Eigen::Vector2d>& points);

}  // namespace refgrasp
