#pragma once
// The robot's vision as a TargetEstimator (servo/target_estimator.h): the per-frame pipeline of
// servo/target_tracker.h (detection, confirmation by consecutive agreeing detections, tracking,
// re-detection in the predicted region then the whole frame; stereo), the same one pose_replay
// and vision_component --track run. Confirmed -> kConfirmed, seen but not confirmed ->
// kUnconfirmed, lost or a frame it cannot use -> kLost (with the one-line error).
#include <memory>
#include <string>

#include "detector/detector.h"
#include "servo/target_estimator.h"
#include "servo/target_tracker.h"

namespace refgrasp::servo {

class VisionEstimator : public TargetEstimator {
 public:
  /// \param detector with the target registered as `object` (it must outlive this).
  /// Throws std::invalid_argument for an unknown object id or bad options.
  VisionEstimator(const detector::Detector& detector, int object,
                  const TargetTrackerOptions& options = {});
  TargetObservation observe(const robot::StereoFrame& frame, const StereoRig& rig,
                            const std::optional<Pose>& prior_cMo) override;
  void reset() override;
  std::string name() const override { return "vision"; }
  /// The pipeline's record of the last frame (modes, detector calls, timings).
  const TargetFrame& last() const { return last_; }

 private:
  int object_;
  TargetTracker tracker_;
  TargetFrame last_;
};

}  // namespace refgrasp::servo
