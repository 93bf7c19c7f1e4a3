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

/// The robot's pipeline options: TargetTrackerOptions' defaults, and a detection in the tracked
/// target's predicted region every 10 frames it processes (about 0.8 s in the simulated runs) that
/// restarts the tracker when it agrees. A grasp needs the pose within the gripper's tolerance
/// (2 cm) at the end of an approach that began where the target was first found, a metre or two
/// away: a tracker started from that far detection keeps its error (25-40 mm on a bottle found at
/// 1.3 m), while the detections on the way get better as the target grows.
TargetTrackerOptions robotPipelineOptions();

class VisionEstimator : public TargetEstimator {
 public:
  /// \param detector with the target registered as `object` (it must outlive this).
  /// Throws std::invalid_argument for an unknown object id or bad options.
  VisionEstimator(const detector::Detector& detector, int object,
                  const TargetTrackerOptions& options = robotPipelineOptions());
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
