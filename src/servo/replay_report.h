#pragma once
// What pose_replay writes into OUTDIR (docs/tools/pose_replay.md "Outputs"):
//   poses.jsonl     one line per frame (per object and frame with several objects): "frame"
//                   (0-based), "index" (device counter), "stamp", ["object"], "mode"
//                   (detect/track/lost), the detect_object fields ("found", "homography",
//                   "corners", "R", "t", "inliers"; "eyes" for stereo), and with ground truth
//                   "truth" {R, t} and "error" {translation_m, rotation_deg}. A frame that could
//                   not be processed has mode "lost" and "error_text". No timings: the same input
//                   and options give the same file, byte for byte.
//   trajectory.tum  TUM format "stamp tx ty tz qx qy qz qw" of cMo for the frames with a pose
//                   (trajectory_<object>.tum with several objects); truth.tum alike when the input
//                   has ground truth (evo_ape tum truth.tum trajectory.tum)
//   poses.csv       one row per frame and object: stamp, mode, position, quaternion, rotation
//                   vector (deg), inliers, truth and errors (empty cells when unknown)
//   overlay.mp4     every frame with the pattern outline, the object axes (x red, y green,
//                   z blue; half the pattern's larger side), mode and frame number (H.264, else
//                   MPEG-4 part 2); frames/NNNNNN.png instead with png_frames
//   summary.json    counts per mode, lost segments, mode changes, error statistics with ground
//                   truth; "timing_ms" is the only non-deterministic field
//   plot.png        per object: x, y, z (m) and the rotation vector theta*u (deg) over time, the
//                   mode strip (detect green, track blue, lost red), lost frames shaded, ground
//                   truth in gray and the errors when known
#include <fstream>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>
#include <string>
#include <vector>

#include "core/camera.h"
#include "detector/detector.h"
#include "robot/sources.h"
#include "servo/replay.h"

namespace refgrasp::servo {

struct ReplayReportOptions {
  bool png_frames = false;   ///< overlay frames as PNG files instead of overlay.mp4
  std::string input;         ///< what was replayed, for summary.json
  bool stereo = false;
  bool tracking = false;     ///< whether a tracker ran between detections
};

class ReplayReport {
 public:
  /// Creates OUTDIR (it may exist: the files are replaced) and opens the per-frame files.
  /// Throws ConfigError "<path>: <problem>" (start-up).
  ReplayReport(const std::string& outdir, const detector::Detector& detector,
               const ReplayReportOptions& options);
  ~ReplayReport();

  /// Appends a frame. image: the (left) frame the poses refer to, with its camera (empty for a
  /// frame the source could not deliver: no overlay). False + a one-line error naming the file
  /// when something cannot be written (the replay should stop: the disk is full).
  bool add(const ReplayFrame& r, const cv::Mat& image, const Intrinsics& camera, std::string* error);
  /// Writes summary.json and plot.png and closes the files. False + error on an I/O failure.
  bool finish(std::string* error);
  /// One-line notes for the user (e.g. the video codec fell back to PNG frames).
  const std::vector<std::string>& notes() const { return notes_; }

  /// poses.jsonl lines of a frame (without newlines). tag_objects: add "object".
  static std::vector<std::string> jsonLines(const ReplayFrame& r, bool tag_objects);

 private:
  struct Sample;
  bool writeOverlay(const cv::Mat& overlay, int64_t frame, std::string* error);

  std::string dir_;
  const detector::Detector& det_;
  ReplayReportOptions opt_;
  std::ofstream jsonl_, csv_;
  std::vector<std::unique_ptr<std::ofstream>> tum_, truth_tum_;
  std::vector<std::string> tum_names_, truth_names_;
  std::vector<Sample> samples_;  ///< per frame and object, for the summary and the plot
  std::vector<std::string> errors_;
  int64_t failed_ = 0;
  std::vector<double> time_ms_;
  cv::VideoWriter video_;
  cv::Mat pending_overlay_;      ///< first overlay, written when the frame rate is known
  Seconds first_stamp_ = 0;
  bool video_failed_ = false;
  std::vector<std::string> notes_;
};

struct ReplayRunResult {
  int64_t frames = 0;       ///< frames replayed (failed ones included)
  int failed = 0;           ///< frames that could not be processed (each reported through on_error)
  std::string write_error;  ///< non-empty when the report could not be written: the run stopped
};

/// Replays every frame of `source` (its mono or its stereo source, whichever is set) through
/// `replay` into `report` (finish() is left to the caller). Poses use `camera` (mono) or `rig`
/// (stereo). A frame the source cannot deliver or the replay cannot use is reported through
/// on_error as one line naming the input and the frame, recorded as lost, and the run goes on;
/// on_progress(frames done) after every frame. Never throws.
ReplayRunResult replaySource(robot::OpenedSource& source, PoseReplay& replay, ReplayReport& report,
                             const Intrinsics& camera, const StereoRig& rig,
                             const std::function<void(const std::string&)>& on_error,
                             const std::function<void(int64_t)>& on_progress);

/// The overlay of one frame (BGR): outline and axes of every object with a pose, the frame
/// number, and each object's mode.
cv::Mat drawOverlay(const cv::Mat& image, const ReplayFrame& r, const detector::Detector& detector,
                    const Intrinsics& camera);

}  // namespace refgrasp::servo
