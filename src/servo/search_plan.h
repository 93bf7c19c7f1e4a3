#pragma once
// The search phase of search-approach-grasp as a plan the grasp controller follows each control
// period (no robot I/O here: servo/grasp_controller.h reads, grabs, estimates and writes).
//
// Stop-and-look: the head goes to a pan, waits `settle_s`, and the frames taken after that are
// looked at until the estimator says lost (next look), or confirmed (found). An unconfirmed
// target holds the look still until it is confirmed or lost, up to `confirm_timeout_s`.
// Efficient: each world direction is looked at once. The pans from one base heading are a grid
// spaced so that neighbouring views overlap by 2 x edge_margin_rad (an object cut by the edge
// of one view is whole in the next), visited nearest-first. When no pan within the head's
// range would show an unseen direction, the base drives to another viewpoint (viewpoint_step_m
// along the heading it started with; move_before_turning) while one is left, and the search
// starts over there; at the last viewpoint the base turns by the smallest angle that brings
// every unseen direction within reach, until every direction was seen; then it gives up
// (kNotFound). An unconfirmed target holds the look even through frames that miss it, until it
// is confirmed or confirm_timeout_s has passed.
//
// Directions are bearings in the odometry frame (rad, counter-clockwise from x_w): base heading
// + pan. Metres, radians, seconds.
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/types.h"
#include "robot/enon_model.h"
#include "robot/hal.h"
#include "servo/target_estimator.h"

namespace refgrasp::servo {

struct SearchPlanOptions {
  double tilt_rad = 0.16;            ///< head tilt while searching (> 0 looks down)
  /// Overlap of neighbouring views on each side. The default holds a 22 cm face seen from 1 m.
  double edge_margin_rad = 0.12;
  double settle_s = 0.25;            ///< wait after the head stops, so frames are sharp
  double head_tolerance_rad = 0.01;  ///< head "at" its target when pan and tilt are this close
  /// A look with an unconfirmed target waits this long for the confirmation.
  double confirm_timeout_s = 1.0;
  double turn_speed_radps = 0.6;
  double heading_tolerance_rad = 0.02;
  double viewpoint_step_m = 0.8;
  double drive_speed_mps = 0.5;
  int max_viewpoints = 1;            ///< new viewpoints tried after the first
  /// When the head's sweep from a viewpoint finds nothing and a viewpoint is left, drive to it
  /// before turning the base to look behind (a target too small to detect from afar is found
  /// from closer; targets behind the robot are rarer). false: look all around first.
  bool move_before_turning = true;
  /// Throws std::invalid_argument "SearchPlanOptions.<field>: <problem>".
  void check() const;
};

enum class SearchState {
  kPointHead,  ///< head moving to the next pan
  kSettle,     ///< head there, waiting for sharp frames
  kLook,       ///< frames after settling are looked at
  kTurnBase,   ///< turning so that unseen directions come within the head's reach
  kMoveBase,   ///< driving to another viewpoint
  kFound,      ///< a confirmed target: the search is over
  kNotFound    ///< every direction from every viewpoint was seen
};
const char* toString(SearchState s);

/// What the robot should do this period.
struct SearchCommand {
  SearchState state = SearchState::kPointHead;
  double pan_rad = 0, tilt_rad = 0;  ///< head position target
  double base_v_mps = 0, base_w_radps = 0;
  /// Frames captured at or after `look_after` are to be given to the estimator.
  bool look = false;
  Seconds look_after = 0;
  bool new_look = false;  ///< a new look starts: forget what the estimator held
};

class SearchPlan {
 public:
  /// \param camera the (left) camera intrinsics: its horizontal field of view spaces the looks.
  /// Throws std::invalid_argument for bad options.
  SearchPlan(const robot::EnonModel& model, const Intrinsics& camera,
             const SearchPlanOptions& options = {});

  /// Starts over from the current state: nothing seen yet, the current heading as the start.
  /// `head_only`: a search after a loss, next to the table with the arm out: the first look is
  /// where the head points now (it was on the target), at the head's current tilt, and the base
  /// neither turns nor drives; when the head's looks find nothing the search ends (kNotFound).
  void restart(const robot::RobotState& state, bool head_only = false);
  /// One control period. `observed`: the estimator's verdict on a frame looked at this period
  /// (kNone when no frame was looked at); `frame_stamp` its capture time.
  SearchCommand decide(Seconds t, const robot::RobotState& state, TargetStatus observed,
                       Seconds frame_stamp);

  SearchState state() const { return state_; }
  int looks() const { return looks_; }
  int viewpoints() const { return viewpoint_; }
  /// Half-width of the directions one look covers (rad): half the field of view minus the margin.
  double coverHalfWidth() const { return half_; }
  /// Pans of one heading's grid, in the order a sweep from pan 0 visits them.
  std::vector<double> panGrid() const;
  /// Fraction of all directions seen from the current viewpoint.
  double coverage() const;

 private:
  bool seen(double bearing) const;
  void markSeen(double bearing);
  /// Unseen directions a look at `pan` from `heading` would show (rad).
  double gain(double heading, double pan) const;
  bool nextLook(double heading, double pan_now);
  void startTurnOrMove(const robot::RobotState& s);

  robot::HeadModel head_;
  SearchPlanOptions opt_;
  double half_ = 0;
  std::vector<double> grid_;
  std::vector<bool> seen_;  ///< per bin of the circle
  SearchState state_ = SearchState::kPointHead;
  double pan_target_ = 0;
  Seconds settle_until_ = 0, look_started_ = 0;
  bool unconfirmed_ = false;
  double turn_target_ = 0;          ///< heading to turn to (odometry)
  Eigen::Vector2d move_from_, move_dir_;
  double start_heading_ = 0;
  int viewpoint_ = 0, looks_ = 0;
  bool head_only_ = false;
  double tilt_ = 0;  ///< of every look
};

}  // namespace refgrasp::servo
