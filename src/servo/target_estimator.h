#pragma once
// Where the target is in a camera frame: the one seam between perception and the grasp
// controller (servo/grasp_controller.h). Two estimators stand behind it:
//   VisionEstimator (servo/vision_estimator.h)  the robot's vision on the images;
//   OracleEstimator (here)                      the simulator's ground truth carried by the frame
//                                               (frame.truth), with visibility decided
//                                               geometrically from the pattern's projection (a
//                                               cylinder's label: the part of it the camera sees
//                                               on the surface): the same controller without the
//                                               price of vision.
// The controller only moves the robot on a CONFIRMED target.
//
// Frames: cMo = object frame in the LEFT camera frame at the frame's capture (exposure centre);
// metres, radians. A prior is the controller's prediction of that pose (from its world estimate
// and the capture state), which an estimator may use to search a region first.
#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/camera.h"
#include "core/cylinder.h"
#include "core/pose.h"
#include "detector/detector.h"
#include "detector/object.h"
#include "robot/camera.h"

namespace refgrasp::servo {

enum class TargetStatus {
  kNone,         ///< no frame was processed in this step (nothing new; not a loss)
  kLost,         ///< a frame was processed and the target is not in it
  kUnconfirmed,  ///< seen, but not yet confirmed by consecutive frames: never moves the robot
  kConfirmed     ///< seen and confirmed
};
const char* toString(TargetStatus s);  ///< "none", "lost", "unconfirmed", "confirmed"

struct TargetObservation {
  TargetStatus status = TargetStatus::kNone;
  std::optional<Pose> cMo;  ///< unconfirmed / confirmed: object in the left camera at capture
  /// Pattern corners TL, TR, BR, BL in the left image (px), when seen.
  std::optional<std::array<Eigen::Vector2d, 4>> corners;
  std::string source;       ///< how it was obtained: "detect", "track", "truth", ...
  /// Vision, a frame the detector ran on: what it saw and reported (servo::TargetState's
  /// detector_stats and detector_best), for the log.
  std::optional<detector::ObjectStats> detector_stats;
  std::optional<detector::Detection> detector_best;
  /// One line when the frame could not be used (wrong size, no ground truth): the controller
  /// then stops the robot with this error.
  std::string error;
};

class TargetEstimator {
 public:
  virtual ~TargetEstimator() = default;
  /// The target in `frame` (both eyes, calibrated by `rig`). Must not throw in normal operation;
  /// the controller treats an exception as an error and stops the robot.
  virtual TargetObservation observe(const robot::StereoFrame& frame, const StereoRig& rig,
                                    const std::optional<Pose>& prior_cMo) = 0;
  /// Forgets the target (tracks, confirmation): the search starts again.
  virtual void reset() = 0;
  /// "vision" or "oracle" (logs, summaries).
  virtual std::string name() const = 0;
};

struct OracleOptions {
  /// A plane: every pattern corner at least this far inside the image; a cylinder's label: the
  /// label points counted as seen.
  double border_px = 4;
  /// Shortest projected pattern side: smaller is too far to see. A little below the size at
  /// which single-frame SIFT detection of the shipped textures starts to fail: the oracle is
  /// slightly more generous than vision, never less. A cylinder's label is judged by the part
  /// of it the camera sees (visibleLabel), which is narrow (at most the diameter) and partly
  /// foreshortened: it is visible when that part covers at least min_side_px^2 (the smallest
  /// planar pattern's area) and neither of its extents is under min_side_px / 2 (a sliver holds
  /// no descriptor's window): vision finds cans whose seen part is under 32 px wide
  /// (docs/results.md, "Worlds beyond the plane").
  double min_side_px = 32;
  /// Between the pattern's normal and the line of sight (a cylinder: at each label point).
  double max_view_angle_rad = 1.2;
  void check() const;
};

/// What a camera sees of a label wrapped on a cylinder: the label points that face it (cos of
/// the angle between the outward normal and the ray to the camera > min_facing_cos), lie in
/// front of it and project at least border_px inside its image. On a convex surface a point that
/// faces the camera is not hidden by the surface itself (other objects are not considered).
struct VisibleLabel {
  int points = 0;         ///< label samples seen
  /// Extent of the seen points' projections across the image of the cylinder's axis and along
  /// it (px); 0 when no point is seen.
  double width_px = 0, height_px = 0;
  double area_px2 = 0;    ///< area of the seen points' projections' convex hull (px^2)
  /// TL, TR, BR, BL: the seen label columns and rows (their range, label px) projected; the
  /// seen points' bounding box when a corner of that range lies behind the camera.
  std::array<Eigen::Vector2d, 4> corners{};
};

/// Label points (label px) that stand for a pattern region (label px, the object's
/// pattern_polygon_px) in visibleLabel(): column centres about 1 deg of arc apart, 48 rows from
/// the region's top to its bottom in each column.
std::vector<Eigen::Vector2d> labelSamples(const CylinderLabel& label,
                                          const std::vector<Eigen::Vector2d>& region_px);

/// The seen part of a label (samples from labelSamples) at cMo (label's object frame in the
/// camera frame; distorted px).
VisibleLabel visibleLabel(const CylinderLabel& label, const std::vector<Eigen::Vector2d>& samples_px,
                          const Pose& cMo, const Intrinsics& camera, double border_px,
                          double min_facing_cos);

/// Ground truth as an estimator. Confirmed at once when visible (no confirmation delay: the
/// truth does not need one); lost when not visible or when the frame carries no truth for it.
class OracleEstimator : public TargetEstimator {
 public:
  /// \param object the target's definition (its pattern corners; a cylinder: its label's
  /// pattern region on the surface; several views: the planar view seen most squarely, or any
  /// cylinder view); its name must match the frame's truth entries. Throws
  /// std::invalid_argument for a 2D-only object or bad options.
  OracleEstimator(const detector::ObjectModel& object, const OracleOptions& options = {});
  TargetObservation observe(const robot::StereoFrame& frame, const StereoRig& rig,
                            const std::optional<Pose>& prior_cMo) override;
  void reset() override {}
  std::string name() const override { return "oracle"; }

  /// Whether the pattern seen at cMo by `camera` is visible by the options' rules; the corners.
  bool visible(const Pose& cMo, const Intrinsics& camera,
               std::array<Eigen::Vector2d, 4>* corners = nullptr) const;

 private:
  struct Label {
    CylinderLabel label;
    Pose oMv;                                ///< label's frame in the object frame
    std::vector<Eigen::Vector2d> samples_px;  ///< labelSamples of its pattern region
  };
  void add(const detector::ObjectModel& model, const Pose& oMv);
  bool planeVisible(const Pose& cMo, const Intrinsics& cam, std::array<Eigen::Vector2d, 4>* corners) const;

  std::string name_;
  std::vector<std::array<Eigen::Vector3d, 4>> quads_o_;  ///< the planar views' pattern quads
  std::vector<Label> labels_;                            ///< the cylinder views' labels
  OracleOptions opt_;
};

}  // namespace refgrasp::servo
