#pragma once
// A cylinder object definition (docs/formats.md "Object definition", core/cylinder.h) from one
// photo of the can: its label, unrolled flat, and the label's size on the surface.
//
// Input: the photo's camera, the can's radius, two points on each of its two silhouette edges
// (the outline's long straight sides) and one point on the label's top border and one on its
// bottom border. Each silhouette edge and the camera centre span a plane tangent to the cylinder;
// with the radius, the two planes fix the axis in 3D (at distance r from both, inside the wedge
// they make). The border points' rays meet the surface at the label's two ends along the axis.
//
// Frames: the camera frame c of the photo (metres); the object frame o of core/cylinder.h, with
// theta = 0 on the surface line nearest the camera centre (the column facing the camera), y along
// the axis from the top border's end to the bottom border's, y = 0 half-way, z into the can.
// Pixels: (0, 0) is the centre of the top-left pixel; the photo's lens distortion (camera file)
// is honoured both when reading the points and when sampling the label.
#include <Eigen/Core>
#include <array>
#include <opencv2/core.hpp>
#include <string>

#include "core/camera.h"
#include "core/cylinder.h"
#include "core/pose.h"

namespace refgrasp::reference {

/// Points clicked in the photo (px).
struct CylinderPoints {
  std::array<Eigen::Vector2d, 2> left_edge, right_edge;  ///< two points on each silhouette edge
  Eigen::Vector2d label_top = Eigen::Vector2d::Zero();     ///< a point on the label's top border
  Eigen::Vector2d label_bottom = Eigen::Vector2d::Zero();  ///< a point on its bottom border
};

struct CylinderOptions {
  double radius_m = 0;  ///< the radius of the surface the label is wrapped on
  /// The unrolled part: where the angle between the surface normal and the ray to the camera
  /// stays below this (in the plane through the camera perpendicular to the axis). 65 deg keeps
  /// the label's foreshortening to cos 65 = 0.42 or better: beyond it a column of the photo
  /// spreads over more than 2.4 label columns, and an error in the axis (a clicked pixel) moves
  /// the label by as much.
  double max_incidence_rad = 65.0 * M_PI / 180.0;
  /// Label image resolution (px per metre on the surface, both directions); 0: the photo's own
  /// at the column facing the camera (f / its distance), so that the centre is neither blurred
  /// nor invented.
  double pixels_per_metre = 0;
  /// Each clicked silhouette edge is moved to the straight intensity edge within this distance
  /// of it (px), fitted along its whole length: a click is good to a pixel or two, and the axis's
  /// tilt comes from how the two edges converge, which 1.5 px of click noise on a 150 px edge
  /// already turns by degrees. 0: the clicks as given; at most 20.
  double snap_px = 4;
  /// Throws std::invalid_argument "--radius: ...", "--max-incidence: ...", "--pixels-per-metre: ...",
  /// "--snap: ...".
  void check() const;
};

struct CylinderGeometry {
  CylinderLabel label;  ///< radius, the unrolled part's size (arc length x height) and image size
  Pose cMo;             ///< object frame (core/cylinder.h) in the photo's camera frame
  double axis_distance_m = 0;  ///< from the camera centre to the axis
  double half_angle_rad = 0;   ///< the unrolled part spans theta in [-half, half]
  /// The silhouette edges used (photo px): the clicked points moved onto the fitted edge lines.
  std::array<std::array<Eigen::Vector2d, 2>, 2> edges_px;
  std::array<bool, 2> snapped{false, false};  ///< each edge was snapped to the photo
};

/// The axis, the label's extent along it and the unrolled part's size from the points (the edges
/// snapped to the photo, options.snap_px). Throws
/// std::invalid_argument with one line naming the option for points that are not finite or lie
/// outside the image, edges on one line or crossing between their points (no axis), a border
/// point off the can, top and bottom at one height, a can too small in the photo to unroll.
CylinderGeometry cylinderGeometry(const cv::Mat& photo, const CylinderPoints& points, const Intrinsics& camera,
                                  const CylinderOptions& options);

/// The label unrolled: label pixel (u, v) is the photo sampled where the surface point
/// label.point(u, v) projects (bilinear, supersampled where a label pixel covers more than one
/// photo pixel). Same type as the photo. Throws std::invalid_argument when part of the unrolled
/// region lies outside the photo.
cv::Mat unrollLabel(const cv::Mat& photo, const Intrinsics& camera, const CylinderGeometry& geometry);

/// Writes the cylinder definition YAML (the label image's path relative to it; the label image
/// must exist), then reads it back with the detector's loader. Throws ConfigError / OutputError.
void writeCylinderDefinition(const std::string& yaml_path, const std::string& name,
                             const std::string& label_path, const CylinderGeometry& geometry);

/// The photo with the silhouette edges used (magenta), the unrolled region's outline (yellow), the
/// axis (cyan) and the object axes (x red, y green, z blue; one radius long), for checking.
cv::Mat drawCylinder(const cv::Mat& photo, const CylinderGeometry& geometry, const Intrinsics& camera);

}  // namespace refgrasp::reference
