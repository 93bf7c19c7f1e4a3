#pragma once
// A label wrapped on a cylinder (a can, a bottle, a jar), shared by the detector, the simulator
// and make_reference.
//
// Object frame o (the planar-object convention on the curved surface): origin at the label
// image's centre on the surface; x along the image columns (tangent to the surface), y along the
// rows (parallel to the axis), z into the object. The axis is the line x = 0, z = r. A W x H
// label image's pixel (u, v) (OpenCV centres: pixel (0, 0) is centred at (0, 0)) lies at
//   arc length s = (u - (W-1)/2) w / W,   y = (v - (H-1)/2) h / H,   angle theta = s / r,
//   X_o = (r sin theta, y, r (1 - cos theta)),
// w and h the label's full width (arc length) and height on the surface, metres. The outward
// surface normal there is (sin theta, 0, -cos theta). With w = 2 pi r the label goes all the way
// round; w may not exceed that (a label overlapping itself has no single surface point).
#include <Eigen/Core>
#include <optional>
#include <string>

#include "core/pose.h"

namespace refgrasp {

struct CylinderLabel {
  double radius_m = 0;        ///< radius of the surface the label is wrapped on
  double width_m = 0;         ///< the label image's full width on the surface (arc length)
  double height_m = 0;        ///< the label image's full height (along the axis)
  int image_width = 0;        ///< W, label image pixels
  int image_height = 0;       ///< H

  /// Throws ConfigError(where, field, problem): radius, sizes and image size positive and
  /// finite, width_m <= 2 pi radius_m (+1 %, rounding in a measured label).
  void check(const std::string& where) const;

  /// True when the label goes all the way round (width_m within 1 % of 2 pi radius_m): its left
  /// and right image edges meet on the surface.
  bool fullWrap() const;
  double metresPerPixelU() const { return width_m / image_width; }
  double metresPerPixelV() const { return height_m / image_height; }

  /// Angle theta (radians) of label column u.
  double theta(double u) const;
  /// Label pixel (u, v) -> point on the surface, object frame (metres).
  Eigen::Vector3d point(const Eigen::Vector2d& uv) const;
  /// Outward unit normal at label column u, object frame.
  Eigen::Vector3d normal(double u) const;
  /// Object-frame point (on or near the surface) -> label pixel: its angle about the axis and
  /// its height, wrapped into the label's column range (-0.5 .. W-0.5) when the label goes all
  /// the way round. Empty when it falls off a partial label's columns (the bare surface) or lies
  /// on the axis.
  std::optional<Eigen::Vector2d> pixel(const Eigen::Vector3d& X_o) const;

  /// The axis point at height y (object frame): (0, y, r).
  Eigen::Vector3d axisPoint(double y) const { return Eigen::Vector3d(0, y, radius_m); }

  /// True when the surface point of label column u faces a camera at cMo: the camera centre lies
  /// on the outer side of the tangent plane there, by more than cos_margin of the viewing ray
  /// (cos of the angle between the normal and the ray to the camera > cos_margin; 0: any sliver).
  bool facesCamera(double u, double v, const Pose& cMo, double cos_margin = 0) const;

  /// Nearest intersection in front of the ray origin of a ray (object frame: origin o, direction
  /// d, any length) with the infinite cylinder's outer surface (only where the surface faces the
  /// ray). Returns the ray parameter t (point = o + t d), empty when it misses.
  std::optional<double> intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const;
};

}  // namespace refgrasp
