#pragma once
// The component's detector and publisher. For each frame the detector thread takes from the
// input, it runs the detector (mono or stereo) or, with `track`, the robot's detect-confirm-track
// pipeline (servo/target_tracker.h), and publishes the results: <ns>/object_pose (the first
// object, when found), <ns>/detections (every instance found), <ns>/object_info (one per object,
// found or not; a 2D-only object's always found = false, it has no pose) and <ns>/object_corners
// (one per object: the pattern's corners, the only result of a 2D-only object). A frame the input's checks or the detector reject gives found = false for every
// object and one rate-limited warning per kind of problem. It counts processed, tracked and
// rejected frames and times each processed one (detector, wait in the slot, own work).
//
// Threads: process() runs on the detector thread only (the facade's loop); the rest is set up
// in the constructor.
// Owns: the detector, the tracking pipeline (with track; it refers to the detector), the four
// writers. Reads the input's checks and topic names; writes the shared statistics and log.
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "component/detect_service.h"
#include "component/frame_input.h"
#include "component/rate_limited_log.h"
#include "component/shared_stats.h"
#include "component/vision_component.h"
#include "detector/detector.h"
#include "robot/dds/transport.h"
#include "servo/target_tracker.h"

namespace refgrasp::component {

class Worker {
 public:
  /// Creates the pipeline (with options.track) and the writers of the topics under options.ns.
  /// `object_names` in the detector's order. Throws dds::DdsError.
  Worker(detector::Detector detector, const VisionComponentOptions& options,
         std::vector<std::string> object_names, dds::Participant& participant, const FrameInput& input,
         SharedStats& stats, RateLimitedLog& log);
  Worker(const Worker&) = delete;
  Worker& operator=(const Worker&) = delete;

  /// Checks the frame, detects (or tracks), publishes and counts it. Returns the result for each
  /// object (have = true), for the detect service.
  /// \param taken_at when the detector thread took the job from the slot (steady clock, s).
  std::vector<ObjectResult> process(const FrameJob& job, double taken_at);

 private:
  struct FrameOutcome;

  /// Runs the detector or the pipeline on a usable frame.
  void detect(const FrameJob& job, const CheckedFrame& frame, FrameOutcome* outcome);
  void detectMono(const FrameJob& job, const CheckedFrame& frame, FrameOutcome* outcome);
  void detectStereo(const FrameJob& job, const CheckedFrame& frame, FrameOutcome* outcome);
  void track(const FrameJob& job, const CheckedFrame& frame, FrameOutcome* outcome);
  /// The frame through the pipeline; stamps and counter as the detector gets them.
  servo::TargetFrame trackFrame(const FrameJob& job, const CheckedFrame& frame);
  /// A frame with a problem: nothing found, the problem as every object's error, one warning.
  void reject(const FrameJob& job, FrameOutcome* outcome);

  void publish(const dds::msg::Header& image_header, const FrameOutcome& outcome);
  void publishDetections(const dds::msg::Header& header, const FrameOutcome& outcome);
  void publishObjectInfo(const dds::msg::Header& header, const FrameOutcome& outcome);
  void publishObjectCorners(const dds::msg::Header& header, const FrameOutcome& outcome);
  /// Counts the frame processed or rejected; times a processed one (steady clock, s).
  void countFrame(const FrameJob& job, const FrameOutcome& outcome, double taken_at,
                  double detect_start, double detect_end, double published_at);

  detector::Detector detector_;
  const Pose lMr_;  ///< stereo: the right eye in the left eye's frame
  std::unique_ptr<servo::TargetTracker> pipeline_;  ///< with track (refers to detector_)
  const std::vector<std::string> object_names_;
  /// Per object: empty, or (a 2D-only object) why the detect service has no pose for it.
  std::vector<std::string> two_d_errors_;
  const FrameInput& input_;
  SharedStats& stats_;
  RateLimitedLog& log_;
  dds::Writer<dds::msg::PoseStamped> pose_writer_;
  dds::Writer<dds::msg::Detection3DArray> detections_writer_;
  dds::Writer<dds::msg::ObjectInfo> object_info_writer_;
  dds::Writer<dds::msg::ObjectCorners> object_corners_writer_;
};

}  // namespace refgrasp::component
