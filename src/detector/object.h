#pragma once
// Object definitions: one reference image of a planar textured object, optionally with the
// reference camera and the object's pose in that image (cMo). Public YAML contract:
//
//   name: poster                      # optional, default: file stem
//   reference_image: poster.png       # relative to this YAML; read as 8-bit grayscale
//   camera: poster_camera.yaml        # intrinsics of the reference image (ROS yaml or ViSP xml);
//                                     # required with reference_pose, optional otherwise
//   reference_pose:                   # optional: object frame in the reference camera frame
//     translation: [0, 0, 0.5]        #   metres
//     rotation_vector: [0, 0, 0]      #   radians (axis * angle)
//   pattern_region: [[u,v], ...]      # optional polygon in reference px (>= 3 points, simple);
//                                     # default: the whole image. The outline of the physical
//                                     # pattern: it may run past the image (a cropped reference)
//                                     # as long as some of it (>= 16 px^2) is inside; features
//                                     # come from that part, corners and pose use the outline.
//   pattern_plane: {normal: [0,0,1], offset: 0.0}   # optional, object frame: n.X = offset
//
// Without reference_pose the object is 2D-only: detections give H and corners, no cMo.
#include <Eigen/Core>
#include <array>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"
#include "detector/pose.h"

namespace refgrasp::detector {

struct ObjectModel {
  std::string name;
  std::string source;                    ///< definition file ("" when built in code)
  cv::Mat reference;                     ///< CV_8UC1 reference image
  std::optional<Intrinsics> camera;      ///< reference camera (may carry distortion)
  std::optional<Pose> reference_cMo;     ///< object frame in the reference camera frame
  std::vector<Eigen::Vector2d> pattern_polygon_px;  ///< reference px (as in the image)
  /// The polygon is the pattern's outline (traced, a rectangle's corners, the whole image of a
  /// texture). false: it only bounds the pattern (e.g. a whole photo around a tag, the object
  /// somewhere in it with other things around): verification then compares only the part of it
  /// the instance's matches cover, and the dense refinement is not used.
  bool pattern_region_exact = true;
  Eigen::Vector3d plane_normal_o = Eigen::Vector3d::UnitZ();
  double plane_offset_m = 0;
  /// Pattern corners TL, TR, BR, BL in reference px (as in the image): the polygon itself when
  /// it has 4 vertices, otherwise its axis-aligned bounding box.
  std::array<Eigen::Vector2d, 4> corners_px;
  /// 3D data for pose estimation (undistorted reference px); empty for 2D-only objects.
  std::optional<PlanarTarget> target;

  bool has3d() const { return target.has_value(); }
};

/// Validates the pieces and fills corners_px and target. Throws ConfigError(source or name, field,
/// problem) on bad input (same checks as the file loader).
ObjectModel makeObjectModel(const std::string& name, const cv::Mat& reference_gray,
                            const std::optional<Intrinsics>& camera,
                            const std::optional<Pose>& reference_cMo,
                            std::vector<Eigen::Vector2d> pattern_polygon_px = {},
                            const Eigen::Vector3d& plane_normal_o = Eigen::Vector3d::UnitZ(),
                            double plane_offset_m = 0, const std::string& source = "");

/// A texture used as its own reference image (DEVELOPERS.md planar convention): a pinhole with
/// f = W z_ref / width_m, c = ((W-1)/2, (H-1)/2) at cMo = (I, [0, 0, z_ref]).
ObjectModel textureObject(const std::string& name, const cv::Mat& texture_gray, double width_m,
                          double z_ref_m = 0.5);
/// The reference camera textureObject() uses.
Intrinsics textureCamera(const cv::Mat& texture, double width_m, double z_ref_m);

/// Reads an object definition YAML. Throws ConfigError("<file>: <field>: <problem>").
ObjectModel loadObjectDefinition(const std::string& path);

}  // namespace refgrasp::detector
