#pragma once
// Making an object definition (config/objects/*.yaml, docs/formats.md "Object definition") from one
// photo of a planar object: the 6-DOF reference pose the detector needs, either from four clicked
// corners of a rectangle of known size (planar PnP) or from an AprilTag lying on the object's plane
// (ViSP's vpDetectorAprilTag finds the tag, the same planar PnP gives its pose).
//
// Object frame (DEVELOPERS.md planar convention): origin at the centre of the rectangle (of the
// tag), x along its top edge (TL -> TR), y along its left edge (TL -> BL), z = 0 on the plane and
// pointing away from the viewer. cMo: object frame in the camera frame of the photo (metres,
// radians). Corners and pixels: (0, 0) is the centre of the top-left pixel; the photo's lens
// distortion (camera file) is honoured by undistorting the corners.
#include <Eigen/Core>
#include <array>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"

namespace refgrasp::reference {

struct Reference {
  Pose cMo;                                        ///< object frame in the photo's camera frame
  std::vector<Eigen::Vector2d> pattern_region_px;  ///< simple polygon in the photo
  /// The region is the pattern's outline (corners, --region); false: it only bounds it (the photo
  /// minus the tag), written as pattern_region_exact: false.
  bool region_exact = true;
  std::array<Eigen::Vector2d, 4> corners_px;       ///< rectangle / tag corners TL, TR, BR, BL (photo px)
  double width_m = 0, height_m = 0;                ///< the rectangle's (the tag's) size
  double rms_px = 0;                               ///< reprojection RMS of the four corners
  std::string method;                              ///< e.g. "corners", "apriltag 36h11 id 3"
};

/// From the four corners TL, TR, BR, BL of a width_m x height_m rectangle in the photo; the
/// pattern region is the rectangle. Throws std::invalid_argument with one line ("--corners: ...",
/// "--size: ...") for non-finite corners, corners outside the image, corners that are not a
/// convex quadrilateral in that order, a tiny quadrilateral, or sizes <= 0.
Reference fromCorners(const std::array<Eigen::Vector2d, 4>& corners_px, double width_m,
                      double height_m, const Intrinsics& camera);

struct TagOptions {
  std::string family = "36h11";  ///< 36h11, 25h9, 16h5, circle21h7 ("tag" prefix allowed)
  double tag_size_m = 0;         ///< side of the tag's black square (its outer border)
  int id = -1;                   ///< the tag to use; -1: the only tag in the photo
  /// Pattern region (photo px); empty: the whole photo minus the tag and its white border.
  std::vector<Eigen::Vector2d> region_px;
};

/// From an AprilTag on the object's plane. Throws std::invalid_argument with one line for an
/// unknown family, tag_size_m <= 0, no tag found, several tags and no id, the id not found.
Reference fromTag(const cv::Mat& photo, const Intrinsics& camera, const TagOptions& options);

/// Writes the object definition YAML (paths of the photo and the camera file relative to it),
/// then reads it back with the detector's loader (so that a file it would refuse is an error
/// here). Throws ConfigError "<file>: <field>: <problem>".
void writeObjectDefinition(const std::string& yaml_path, const std::string& name,
                           const std::string& photo_path, const std::string& camera_path,
                           const Reference& ref);

/// The photo with the pattern region (yellow), the rectangle or tag (magenta) and the object
/// axes (x red, y green, z blue; half the rectangle's smaller side), for the user to check.
cv::Mat drawReference(const cv::Mat& photo, const Reference& ref, const Intrinsics& camera);

}  // namespace refgrasp::reference
