#pragma once
// Where the target is in a camera frame: the one seam between perception and the grasp
// controller (servo/grasp_controller.h). Two estimators stand behind it:
//   VisionEstimator (servo/vision_estimator.h)  the robot's vision on the images;
//   OracleEstimator (here)                      the simulator's ground truth carried by the frame
//                                               (frame.truth), with visibility decided
//                                               geometrically from the pattern's projection:
//                                               the same controller without the price of vision.
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
#include "core/pose.h"
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
  double border_px = 4;          ///< every pattern corner at least this far inside the image
  /// Shortest projected pattern side: smaller is too far to see. A little below the size at
  /// which single-frame SIFT detection of the shipped textures starts to fail: the oracle is
  /// slightly more generous than vision, never less.
  double min_side_px = 32;
  double max_view_angle_rad = 1.2;  ///< between the pattern's normal and the line of sight
  void check() const;
};

/// Ground truth as an estimator. Confirmed at once when visible (no confirmation delay: the
/// truth does not need one); lost when not visible or when the frame carries no truth for it.
class OracleEstimator : public TargetEstimator {
 public:
  /// \param object the target's definition (its pattern corners; several views: the view seen
  /// most squarely counts); its name must match the frame's truth entries. Throws
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
  std::string name_;
  std::vector<std::array<Eigen::Vector3d, 4>> quads_o_;  ///< patternQuads (one per view)
  OracleOptions opt_;
};

}  // namespace refgrasp::servo
