#pragma once
// Offline pose replay: the per-frame processing of the pose_replay tool on recorded or file
// input, testable in-process. It is the robot's vision pipeline (servo/target_tracker.h:
// detect, confirm, track, re-detect) frame by frame, plus the frame number and ground truth.
//
// Per object and frame the mode is:
//   detect  the detector found it in this frame (pose from the detection);
//   track   the frame-to-frame tracker followed it from the previous frame (pose from the tracker);
//   lost    neither.
// With a tracker (TrackerFactory; pose_replay passes planarTrackerFactory()) and
// ReplayOptions::track: after a detection the tracker runs; when it loses the target the frame is
// detected again (predicted region, then the whole frame). Without a tracker, or with track =
// false (--no-track), every frame is detected.
//
// Frames and units: cMo = object frame in the camera frame (the LEFT camera for stereo), metres,
// radians. Deterministic: the same frames and options give the same results, bit for bit
// (time_ms aside).
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"
#include "core/types.h"
#include "detector/detector.h"
#include "robot/camera.h"
#include "servo/target_tracker.h"
#include "servo/tracker.h"

namespace refgrasp::servo {

struct ReplayOptions {
  bool track = true;  ///< false: detection on every frame even when a tracker is given
  /// The pipeline's options (its `track` is replaced by the one above and whether a tracker is
  /// given).
  TargetTrackerOptions pipeline;
  void check() const { pipeline.check(); }
};

/// One object in one frame.
struct ObjectFrame {
  int object = -1;          ///< detector object id
  std::string name;
  TrackMode mode = TrackMode::kLost;
  bool confirmed = false;   ///< confirmed by consecutive agreeing detections (TargetState)
  /// detect: the detection (best instance; the left eye's for stereo, found = false when only the
  /// right eye found it); track/lost: found = false.
  detector::Detection detection;
  std::optional<Pose> cMo;  ///< detect and track (3D objects): the pose; lost: empty
  /// Pattern corners TL, TR, BR, BL in the (left) image: detected, projected from cMo, or under
  /// the tracked homography (2D-only).
  std::optional<std::array<Eigen::Vector2d, 4>> corners;
  /// mode track, a 2D-only object: the tracked homography (TargetState::H)
  std::optional<Eigen::Matrix3d> H;
  std::string eyes;         ///< stereo: "both", "left", "right" or "none" (detect and track)
  TrackQuality quality;     ///< mode track: the (left) tracker's numbers
  std::optional<Pose> truth_cMo;  ///< ground truth when the frame carries it
};

struct ReplayFrame {
  int64_t frame = 0;   ///< 0-based position in the input
  FrameStamp stamp;    ///< capture time and device counter
  bool ok = true;
  std::string error;   ///< one line when the frame could not be processed (every object lost)
  std::vector<ObjectFrame> objects;  ///< one per detector object, id order
  int detector_calls = 0;  ///< detector runs in this frame
  double time_ms = 0;  ///< processing time: NOT deterministic, kept out of poses.jsonl
};

class PoseReplay {
 public:
  /// \param detector with every object registered (it must outlive the replay).
  /// \param trackers nullptr: detection on every frame.
  PoseReplay(const detector::Detector& detector, const ReplayOptions& options = {},
             TrackerFactory trackers = nullptr);
  ~PoseReplay();

  /// Processes the next frame. A frame the detector rejects (wrong size, bad pixel type) gives
  /// ok = false and a one-line error, every object lost, and the trackers reset. Never throws.
  ReplayFrame process(int64_t frame, const robot::MonoFrame& f, const Intrinsics& camera);
  ReplayFrame process(int64_t frame, const robot::StereoFrame& f, const StereoRig& rig);
  /// A frame the source could not deliver: recorded as an error, every object lost.
  ReplayFrame failed(int64_t frame, const FrameStamp& stamp, const std::string& error);

  /// Whether frames are tracked between detections (a tracker is given and options.track).
  bool tracking() const;

 private:
  ReplayFrame convert(int64_t frame, const TargetFrame& t, const std::vector<robot::ObjectTruth>& truth,
                      bool stereo) const;
  TargetTracker pipeline_;
};

}  // namespace refgrasp::servo
