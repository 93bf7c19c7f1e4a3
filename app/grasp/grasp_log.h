#pragma once
// What enon_grasp writes besides its summary (docs/tools/enon_grasp.md "Outputs"):
//   --log DIR    a refgrasp recording of the camera frames the controller used (recording.json,
//                calib/, frames/, index.jsonl with capture state, robot state and ground truth;
//                pose_replay reads it back) plus DIR/control.jsonl, one JSON line per control
//                iteration (GraspLog::line: time, phase, target status, cMo estimate, ground truth
//                when simulated, error norm, commands, robot state), so a run can be replayed;
//   --video FILE the frames used, with the pattern outline, the object axes (x red, y green,
//                z blue), the phase and the error (GraspVideo); on the simulated enon beside it
//                the robot seen by a camera following it and the top-down map (three panels).
#include <fstream>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>
#include <optional>
#include <string>

#include "core/json.h"
#include "detector/object.h"
#include "grasp/grasp_map.h"
#include "robot/enon_model.h"
#include "robot/files/recording.h"
#include "robot/sim/robot_view.h"
#include "robot/sim/sim_enon.h"
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
  /// Simulated runs: every video frame shows three panels side by side, the head camera (draw()),
  /// the world and the robot from a camera following it (sim::FollowCamera, 640 x 480) and the
  /// top-down map (TopDownMap, 640 x 480, the odometry frame taken as the world frame: see
  /// grasp_map.h). `sim` must outlive the video. Without it (a robot over DDS) the video is the
  /// head camera alone.
  void showOutside(const sim::SimEnon& sim, const robot::EnonModel& model);
  /// Adds the iteration's frame when it has one (with an image); with showOutside, every
  /// iteration also extends the robot's path and the looks the map shows. False + one line when
  /// the file cannot be opened or written.
  bool add(const servo::GraspIteration& it, std::string* error);
  int frames() const { return frames_; }

  /// The annotated picture of an iteration's frame (BGR).
  static cv::Mat draw(const servo::GraspIteration& it, const detector::ObjectModel& target,
                      const Intrinsics& camera);
  /// Panels side by side (BGR), each scaled to the first one's height.
  static cv::Mat sideBySide(const std::vector<cv::Mat>& panels);
  /// The external view and the map now (after add() has seen the iteration; needs showOutside).
  cv::Mat externalPanel();
  cv::Mat mapPanel() const;

 private:
  // The simulator and what the map accumulates (showOutside).
  struct Outside {
    const sim::SimEnon* sim = nullptr;
    robot::EnonModel model;
    sim::FollowCamera follow;
    std::unique_ptr<TopDownMap> map;
    MapFrame state;
    std::shared_ptr<const servo::SearchBelief> belief;
  };
  void observe(const servo::GraspIteration& it);

  std::unique_ptr<Outside> outside_;
  std::string path_;
  const detector::ObjectModel& target_;
  Intrinsics camera_;
  double fps_;
  cv::VideoWriter writer_;
  int frames_ = 0;
};

}  // namespace refgrasp::grasp_app
