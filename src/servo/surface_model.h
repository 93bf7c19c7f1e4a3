#pragma once
// The textured surfaces of an object with a pose, in its object frame, as the tracker sees them:
//
//   planar object     its pattern polygon on its plane (pattern_plane);
//   cylinder          the label (core/cylinder.h) within its pattern_region (label px), on the
//                     cylinder's surface, not the tangent plane of ObjectModel::target;
//   several views     every view's surfaces, each moved into the object frame by its oMv.
//
// What a surface offers: the point a camera ray meets first (the nearest hit on a surface seen
// from its outer side, within its textured extent when the object has several surfaces; the only
// surface of an object extends past its texture, so a feature that slides over the outline keeps
// a correct 3D point); the image region its texture covers at a pose (for seeding features); the
// fraction of it that is in the image.
//
// Outer side: a plane's is the side its reference camera saw it from; a cylinder's is away from
// its axis. The surfaces of one object are taken not to hide one another where they face the
// camera (a box, a can): masks are unions, not depth-tested; intersect() takes the nearest hit.
//
// Frames and units: cMo = object frame in the camera frame (metres, radians); image pixels
// distorted (as Intrinsics::project), the centre of the top-left pixel at (0, 0).
#include <Eigen/Core>
#include <array>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "core/camera.h"
#include "core/cylinder.h"
#include "core/pose.h"
#include "detector/object.h"

namespace refgrasp::servo {

/// A camera ray's first textured point.
struct SurfaceHit {
  Eigen::Vector3d X_o;  ///< the point, object frame (metres)
  Eigen::Vector3d n_o;  ///< the surface's outward unit normal there, object frame
  int surface = -1;     ///< which surface (0 .. SurfaceModel::surfaceCount() - 1)
};

class SurfaceModel {
 public:
  /// Throws std::invalid_argument for an object without a pose (2D only), naming it (start-up).
  explicit SurfaceModel(const detector::ObjectModel& object);

  int surfaceCount() const { return static_cast<int>(surfaces_.size()); }

  /// The first textured point on the ray through distorted pixel px of a camera at cMo; empty
  /// when the ray meets none (or meets it behind the camera).
  std::optional<SurfaceHit> intersect(const Pose& cMo, const Intrinsics& cam,
                                      const Eigen::Vector2d& px) const;

  /// CV_8UC1 of the camera's size, 255 where a surface's texture projects: every surface whose
  /// outer side faces the camera with cos(angle between its outward normal and the ray to the
  /// camera) > min_facing_cos (a cylinder: per strip of its label), each shrunk by border_px,
  /// and border_px kept off the image border. Empty mask (all 0) when nothing qualifies.
  cv::Mat mask(const Pose& cMo, const Intrinsics& cam, double border_px, double min_facing_cos) const;

  /// Fraction of the textured area facing the camera (projected, image px^2) that lies inside the
  /// image; 0 when nothing faces it, or a facing part lies behind the camera.
  double visibleFraction(const Pose& cMo, const Intrinsics& cam) const;

 private:
  struct Surface {
    Pose oMs;                                ///< surface frame in the object frame
    std::optional<CylinderLabel> cylinder;   ///< set: a label; else a plane
    std::vector<Eigen::Vector3d> polygon_s;  ///< plane: the pattern polygon, surface frame
    Eigen::Vector3d normal_s;                ///< plane: n of n.X = offset, surface frame
    double offset_m = 0;
    double outer_sign = 1;                   ///< plane: outward normal = outer_sign * normal_s
    std::vector<Eigen::Vector2d> label_polygon_px;  ///< cylinder: pattern region, label px
    /// cylinder: the label polygon cut into strips of a few degrees of arc, label px.
    std::vector<std::vector<Eigen::Vector2d>> strips_px;
  };
  void add(const detector::ObjectModel& model, const Pose& oMs);
  /// Projected outlines (distorted px) of the parts of surface s facing the camera by more than
  /// min_facing_cos; false when one of them lies behind the camera.
  bool facingOutlines(const Surface& s, const Pose& cMo, const Intrinsics& cam, double min_facing_cos,
                      std::vector<std::vector<Eigen::Vector2d>>* out) const;
  std::vector<Surface> surfaces_;
};

/// The pattern quadrilaterals of an object (corners TL, TR, BR, BL, object frame, metres): its
/// target's for a planar object or a cylinder (the flat label on the tangent plane), one per view
/// (moved by oMv) for a several-view object; empty for a 2D-only object.
std::vector<std::array<Eigen::Vector3d, 4>> patternQuads(const detector::ObjectModel& object);

/// Of patternQuads(object), the one a camera at cMo sees most squarely (the largest cos between
/// its +z, into the object, and the ray from the camera to its centre); empty without quads.
std::optional<std::array<Eigen::Vector3d, 4>> facingQuad(
    const std::vector<std::array<Eigen::Vector3d, 4>>& quads, const Pose& cMo);

}  // namespace refgrasp::servo
