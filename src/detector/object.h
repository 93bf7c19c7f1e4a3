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
//
// A label on a cylinder (a can, a bottle, a jar); object frame and label geometry in
// core/cylinder.h:
//
//   name: soda_can
//   reference_image: soda_can_label.png  # the label unrolled flat: columns along the circumference
//   cylinder:
//     radius_m: 0.033                    # radius of the surface the label is wrapped on
//     label_size_m: [0.2073, 0.115]      # the image's full width (arc length) and height there
//   pattern_region: [[u,v], ...]         # optional, label px, as above
//
// An object of several views (the faces of a box; a can's label and its lid):
//
//   name: tea_box
//   views:
//     - definition: tea_box_front.yaml   # planar with reference_pose, or cylinder (relative to
//       oMv: {translation: [0, 0, 0], rotation_vector: [0, 0, 0]}   # this file); that view's
//     - definition: tea_box_left.yaml    # object frame in this object's frame (metres, radians)
//       oMv: {translation: [-0.1, 0, 0.035], rotation_vector: [0, 1.5708, 0]}
#include <Eigen/Core>
#include <array>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/cylinder.h"
#include "core/pose.h"
#include "detector/pose.h"

namespace refgrasp::detector {

struct ObjectModel;

/// One view of a several-view object.
struct ObjectView {
  std::string name;                          ///< the view definition's name (unique in the object)
  std::shared_ptr<const ObjectModel> model;  ///< planar with a reference pose, or a cylinder
  Pose oMv;  ///< the view's object frame in the several-view object's frame (metres, radians)
};

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
  /// A label on a cylinder: `reference` is the unrolled label, `camera` and `reference_cMo` a
  /// synthetic pinhole seeing it flat (cylinderObject), and `target` the flat label on the
  /// tangent plane at its centre, z = 0 in the object frame: the paper's planar approximation.
  std::optional<CylinderLabel> cylinder;
  /// A several-view object: its views; `reference` is empty and `target` unset.
  std::vector<ObjectView> views;

  bool has3d() const { return target.has_value(); }
  bool isCylinder() const { return cylinder.has_value(); }
  bool isMultiView() const { return !views.empty(); }
  bool hasPose() const { return has3d() || isMultiView(); }  ///< detections give a cMo
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

/// A cylinder object from its unrolled label (8-bit gray, label.image_width x image_height set
/// from it): the checks of makeObjectModel plus CylinderLabel::check.
ObjectModel cylinderObject(const std::string& name, const cv::Mat& label_gray, double radius_m,
                           double label_width_m, double label_height_m,
                           std::vector<Eigen::Vector2d> pattern_polygon_px = {}, const std::string& source = "");

/// Reads an object definition YAML (any of the three forms above). Throws ConfigError("<file>: <field>: <problem>").
ObjectModel loadObjectDefinition(const std::string& path);

}  // namespace refgrasp::detector
