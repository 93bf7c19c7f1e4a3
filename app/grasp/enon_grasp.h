#pragma once
// enon_grasp: search-approach-grasp on an enon (app/enon_grasp.cpp is `return runEnonGrasp(...)`).
// The wiring lives here so that it is tested in process: robot backend, target definition and
// grasp frame, estimator (vision or --oracle), the grasp controller's loop, the progress line,
// the summary line, the log and the video.
#include <cstdio>
#include <map>
#include <optional>
#include <string>

#include "servo/grasp_controller.h"

namespace refgrasp::grasp_app {

/// Exit status of enon_grasp (docs/tools/enon_grasp.md "Exit status").
enum ExitCode {
  kExitGrasped = 0,     ///< the target is held after the lift
  kExitNoGrasp = 1,     ///< a phase failed: not_found, timeout, unreachable, missed, dropped, lost
  kExitBadInput = 2,    ///< bad options or files (one line naming the file and field)
  kExitRobotError = 3,  ///< the robot, its camera or a collision stopped the run (robot stopped)
  kExitOutput = 4,      ///< the log or the video could not be written (robot stopped)
};

struct EnonGraspOptions {
  std::string backend = "sim";
  /// The scenario: for "sim" the world; for every backend the target's definition and grasp
  /// frame (its object with target: true).
  std::string scenario;
  std::string enon = "config/enon.yaml";
  std::optional<uint64_t> seed;  ///< overrides the scenario's seed
  bool oracle = false;           ///< the simulator's ground truth instead of vision (sim only)
  std::string log_dir, video;
  double max_time_s = 0;         ///< 0: the scenario's max_duration_s
  std::string detector_config;
  std::map<std::string, std::string> backend_params;  ///< extra backend settings (dds: domain, ns)
  /// Not "sim": the robot's camera from this frame source instead of the backend's (robot/
  /// sources.h; on the enon "bb2": the Bumblebee2 on this computer's FireWire bus, with the robot
  /// model's rig). Empty: the backend's camera (dds: image_raw on the bus).
  std::string camera;
  std::map<std::string, std::string> camera_settings;  ///< robot::SourceRequest::settings
  servo::GraspOptions grasp;
  /// SIGINT/SIGTERM end the run: until the robot is active at once (tool::exitOnSignal, set by
  /// the caller), then by stopping the robot and returning tool::interruptedCode(signal).
  bool interruptible = false;
};

struct EnonGraspResult {
  int exit_code = kExitNoGrasp;
  std::string summary;   ///< the JSON summary line (without newline)
  std::string error;     ///< one line when exit_code != 0
  servo::GraspReport report;
  double sim_time_s = 0;
  int collisions = 0;
  double final_position_mm = -1, final_rotation_deg = -1;
  int iterations = 0, frames_used = 0;
};

/// Runs one grasp. Start-up problems (files, options) throw ConfigError / std::invalid_argument
/// (the CLI maps them to exit 2); everything after that is a result. `progress`: where the
/// updating progress line goes (nullptr: none).
EnonGraspResult runEnonGraspSession(const EnonGraspOptions& options, std::FILE* progress);

/// The command line: parse, run, print the summary line on stdout, return the exit status.
int runEnonGrasp(int argc, char** argv);

}  // namespace refgrasp::grasp_app
