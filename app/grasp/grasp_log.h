#pragma once
// What enon_grasp writes besides its summary (docs/tools/enon_grasp.md "Outputs"):
//   --log DIR    a refgrasp recording of the camera frames the controller used (recording.json,
//                calib/, frames/, index.jsonl with capture state, robot state and ground truth;
//                pose_replay reads it back) plus DIR/control.jsonl, one JSON line per control
//                iteration (GraspLog::line: time, phase, target status, cMo estimate, ground truth
//                when simulated, error norm, commands, robot state), so a run can be replayed;
//   --video FILE the frames used, with the pattern outline, the object axes (x red, y green,
//                z blue), the phase and the error (GraspVideo).
#include <fstream>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>
#include <optional>
#include <string>

#include "core/json.h"
#include "detector/object.h"
#include "robot/files/recording.h"
#include "servo/grasp_controller.h"

namespace refgrasp::grasp_app {

class GraspLog {
 public:
  /// Creates DIR (it must not exist or be empty) as a recording of `rig`, and DIR/control.jsonl.
  /// Throws ConfigError "<path>: <problem>" (start-up).
  GraspLog(const std::string& dir, const StereoRig& rig, const std::string& source,
           const std::string& target_name);
  /// Appends the iteration (and its frame, when it used one). `extra`: fields added to the line
  /// (e.g. the simulator's ground-truth grasp error). False + one line naming the file on an
  /// I/O failure (the run should stop).
  bool add(const servo::GraspIteration& it, const Json& extra, std::string* error);
  const std::string& dir() const { return dir_; }

  /// The control.jsonl line of an iteration; `frame`: its frame's number in the recording.
  static Json line(const servo::GraspIteration& it, const std::string& target_name,
                   std::optional<int64_t> frame);

 private:
  std::string dir_, target_;
  std::unique_ptr<files::RecordingWriter> recording_;
  std::ofstream control_;
};

class GraspVideo {
 public:
  /// \param fps frame rate of the video (the controller's frame rate). Nothing is opened before
  /// the first frame.
  GraspVideo(const std::string& path, const detector::ObjectModel& target, const Intrinsics& camera,
             double fps);
  /// Adds the iteration's frame when it has one (with an image). False + one line when the file
  /// cannot be opened or written.
  bool add(const servo::GraspIteration& it, std::string* error);
  int frames() const { return frames_; }

  /// The annotated picture of an iteration's frame (BGR).
  static cv::Mat draw(const servo::GraspIteration& it, const detector::ObjectModel& target,
                      const Intrinsics& camera);

 private:
  std::string path_;
  const detector::ObjectModel& target_;
  Intrinsics camera_;
  double fps_;
  cv::VideoWriter writer_;
  int frames_ = 0;
};

}  // namespace refgrasp::grasp_app
