#pragma once
// Offline pose replay: the per-frame processing of the pose_replay tool (the robot's detection
// and tracking, frame by frame, on recorded or file input), testable in-process.
//
// Per object and frame the mode is:
//   detect  the detector found it in this frame (pose from the detection);
//   track   a frame-to-frame tracker followed it from the previous frame (pose from the tracker);
//   lost    neither.
// With a tracker (TrackerFactory) and ReplayOptions::track: after a detection the tracker is
// started; on the next frames it tracks, and when it loses the target the frame is detected
// again. Without a tracker, or with track = false (--no-track), every frame is detected.
// The tracker of issue 8 plugs in behind FrameTracker; until then pose_replay runs detect-only.
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

namespace refgrasp::servo {

enum class TrackMode { kDetect, kTrack, kLost };
const char* toString(TrackMode m);  ///< "detect", "track", "lost"

/// Frame-to-frame tracking of one object (the seam for issue 8's tracker). Gray CV_8UC1 frames.
class FrameTracker {
 public:
  virtual ~FrameTracker() = default;
  /// Starts on the frame a detection was made in, at the detected pose.
  virtual void start(const cv::Mat& gray, const Intrinsics& camera, const Pose& cMo) = 0;
  /// The pose in the next frame, or empty when the target is lost. Never throws.
  virtual std::optional<Pose> track(const cv::Mat& gray, const Intrinsics& camera) = 0;
};

/// A tracker for an object; nullptr (or an empty factory): detection on every frame.
using TrackerFactory =
    std::function<std::unique_ptr<FrameTracker>(const detector::ObjectModel& object)>;

struct ReplayOptions {
  bool track = true;  ///< false: detection on every frame even when a tracker is given
  void check() const {}
};

/// One object in one frame.
struct ObjectFrame {
  int object = -1;          ///< detector object id
  std::string name;
  TrackMode mode = TrackMode::kLost;
  /// detect: the detection (best instance; the left eye's for stereo, found = false when only the
  /// right eye found it); track/lost: found = false.
  detector::Detection detection;
  std::optional<Pose> cMo;  ///< detect and track (3D objects): the pose; lost: empty
  /// Pattern corners TL, TR, BR, BL in the (left) image: detected, or projected from cMo.
  std::optional<std::array<Eigen::Vector2d, 4>> corners;
  std::string eyes;         ///< stereo detections: "both", "left", "right" or "none"
  std::optional<Pose> truth_cMo;  ///< ground truth when the frame carries it
};

struct ReplayFrame {
  int64_t frame = 0;   ///< 0-based position in the input
  FrameStamp stamp;    ///< capture time and device counter
  bool ok = true;
  std::string error;   ///< one line when the frame could not be processed (every object lost)
  std::vector<ObjectFrame> objects;  ///< one per detector object, id order
  double time_ms = 0;  ///< processing time: NOT deterministic, kept out of poses.jsonl
};

class PoseReplay {
 public:
  /// \param detector with every object registered (it must outlive the replay).
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
  struct Track;
  ReplayFrame start(int64_t frame, const FrameStamp& stamp,
                    const std::vector<robot::ObjectTruth>& truth) const;
  void fill(ObjectFrame* o, const Intrinsics& camera) const;
  /// Runs the active trackers (mode track or, when they lose it, lost); true when an object is
  /// left to detect.
  bool trackAll(ReplayFrame* r, const cv::Mat& gray, const Intrinsics& camera);
  void startTracker(const ObjectFrame& o, const cv::Mat& gray, const Intrinsics& camera);

  const detector::Detector& det_;
  ReplayOptions opt_;
  TrackerFactory factory_;
  std::vector<std::unique_ptr<Track>> tracks_;
};

/// The pattern corners of a 3D object (object frame, metres) projected with cMo into `camera`.
std::array<Eigen::Vector2d, 4> projectPattern(const detector::ObjectModel& object, const Pose& cMo,
                                              const Intrinsics& camera);

}  // namespace refgrasp::servo
