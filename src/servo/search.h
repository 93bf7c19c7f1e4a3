#pragma once
// The search phase of search-approach-grasp: stop-and-look head sweeps (straight ahead, then
// alternately left and right), then a base turn once every head position was tried, until the
// stereo detector finds the target. It drives the robot through the HAL only (robot/hal.h).
//
// Per control period the app calls step(t, dt), which owns the cycle and its safety rules:
// robot.read, camera grab, decide, robot.write. On any error (robot read/write, camera, a frame
// the detector rejects, an exception) the robot is stopped (zero velocity) and step returns
// kError with a one-line message; nothing throws out of step().
// Frames: lMo is the object in the LEFT camera frame at the frame's capture (metres, radians).
#include <optional>
#include <string>
#include <vector>

#include "core/types.h"
#include "detector/detector.h"
#include "robot/hal.h"

namespace refgrasp::servo {

struct SearchOptions {
  double tilt_rad = 0.16;        ///< head tilt while searching (> 0 looks down)
  double pan_step_rad = 0.45;    ///< between looks; less than the ~1.15 rad horizontal field of view
  double settle_s = 0.25;        ///< wait after the head stops, so frames are sharp
  double head_tolerance_rad = 0.01;  ///< head "at" its target when pan and tilt are this close
  double turn_rad = 1.0;         ///< base turn once every head position was tried
  double turn_speed_radps = 0.5;
  /// Throws std::invalid_argument "SearchOptions.<field>: <problem>".
  void check() const;
};

enum class SearchPhase { kPointHead, kSettle, kLook, kTurnBase, kFound, kError };
const char* toString(SearchPhase p);

/// One look: a stereo detection on a frame taken after the head settled.
struct SearchLook {
  int number = 0;                ///< 1, 2, ...
  Seconds t = 0;                 ///< control time of the look
  robot::StereoFrame frame;      ///< the frame looked at (capture state filled)
  detector::StereoDetection detection;  ///< of the target object
  double extract_ms = 0, total_ms = 0;  ///< both eyes
  bool found() const { return detection.fused.lMo.has_value(); }
};

struct SearchStep {
  robot::ReturnType status = robot::ReturnType::kOk;
  std::string error;                 ///< one line when status != kOk
  SearchPhase phase = SearchPhase::kPointHead;  ///< after this step
  std::optional<SearchLook> look;    ///< set on the steps that looked
};

class SearchController {
 public:
  /// \param robot active robot; \param detector with the target registered as `object`.
  /// Throws std::invalid_argument for bad options or an unknown object id (start-up).
  SearchController(robot::Robot& robot, const detector::Detector& detector, int object,
                   const SearchOptions& options = {});

  /// One control period at time t (period dt): read, grab, decide, write. Never throws. Once the
  /// target is found (or after an error) every call only stops the robot (and repeats the error).
  SearchStep step(Seconds t, Seconds dt);

  SearchPhase phase() const { return phase_; }
  int looks() const { return looks_; }
  /// The head pan angles tried from each base heading, in order (rad).
  const std::vector<double>& pans() const { return pans_; }

 private:
  SearchStep decide(Seconds t, SearchStep s);
  SearchStep fail(SearchStep s, const std::string& error);

  robot::Robot& robot_;
  const detector::Detector& detector_;
  int object_;
  SearchOptions opt_;
  std::vector<double> pans_;
  SearchPhase phase_ = SearchPhase::kPointHead;
  size_t pan_index_ = 0;
  Seconds settle_until_ = 0;
  double turn_start_theta_ = 0;
  int looks_ = 0;
  std::string error_;  ///< the error that ended the search
};

}  // namespace refgrasp::servo
