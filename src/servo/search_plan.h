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
// With a belief (useBelief: a room map, or none for an unknown room) the search instead follows
// servo/search_belief.h: each look is the one that explains the most belief mass per second from
// wherever the base can reach, the base drives there along a free path (kMoveBase: waypoints,
// turning in place towards each, then kTurnBase to the look's heading), every missed look
// lowers the belief where it would have seen the target, an unconfirmed candidate that did not
// confirm raises it around the candidate, and the search ends (kNotFound) only when every place
// has been seen well enough (BeliefSearch::done) or no look can add anything; otherwise the
// controller's time budget ends it. A search after a loss (head_only) keeps the sweep.
//
// Directions are bearings in the odometry frame (rad, counter-clockwise from x_w): base heading
// + pan. Metres, radians, seconds.
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/types.h"
#include "robot/enon_model.h"
#include "robot/hal.h"
#include "servo/search_belief.h"
#include "servo/search_map.h"
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
  double turn_speed_radps = 0.9;     ///< the base's limit is 1.0; its wheels allow 0.9 while driving slowly
  double heading_tolerance_rad = 0.02;
  double viewpoint_step_m = 0.8;
  double drive_speed_mps = 0.7;      ///< below the base's 0.83 limit, leaving its wheels room to steer
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

  /// Searches by belief from now on (the next restart): `map` in the odometry frame (empty: an
  /// unknown room). Throws std::invalid_argument for bad options.
  void useBelief(const RoomMap& map, const BeliefSearchOptions& options);
  bool beliefMode() const { return belief_ != nullptr; }

  /// Starts over from the current state: nothing seen yet, the current heading as the start.
  /// `head_only`: a search after a loss, next to the table with the arm out: the first look is
  /// where the head points now (it was on the target), at the head's current tilt, and the base
  /// neither turns nor drives; when the head's looks find nothing the search ends (kNotFound).
  /// `hint_w` (belief mode): where the target was last seen (odometry x, y): looked at first.
  void restart(const robot::RobotState& state, bool head_only = false,
               const std::optional<Eigen::Vector2d>& hint_w = std::nullopt);
  /// One control period. `observed`: the estimator's verdict on a frame looked at this period
  /// (kNone when no frame was looked at); `frame_stamp` its capture time.
  /// `candidate_w`: with kUnconfirmed, where the candidate stands (odometry x, y), if known.
  /// `weak`: the frame's detector saw weak evidence (a candidate refused by a check).
  SearchCommand decide(Seconds t, const robot::RobotState& state, TargetStatus observed,
                       Seconds frame_stamp,
                       const std::optional<Eigen::Vector2d>& candidate_w = std::nullopt,
                       bool weak = false);

  SearchState state() const { return state_; }
  int looks() const { return looks_; }
  int viewpoints() const { return viewpoint_; }
  /// Half-width of the directions one look covers (rad): half the field of view minus the margin.
  double coverHalfWidth() const { return half_; }
  /// Pans of one heading's grid, in the order a sweep from pan 0 visits them.
  std::vector<double> panGrid() const;
  /// Fraction of all directions seen from the current viewpoint.
  double coverage() const;
  /// Belief mode: the belief after the last look (null otherwise), the look started by the last
  /// decide() (once), the plan being followed, and why the search ended ("" while it runs).
  std::shared_ptr<const SearchBelief> belief() const { return snapshot_; }
  std::optional<SearchLook> takeStartedLook();
  const PlannedLook& planned() const { return planned_; }
  const BeliefSearch* beliefSearch() const { return belief_.get(); }
  const std::string& endReason() const { return end_reason_; }

 private:
  bool seen(double bearing) const;
  void markSeen(double bearing);
  /// Unseen directions a look at `pan` from `heading` would show (rad).
  double gain(double heading, double pan) const;
  bool nextLook(double heading, double pan_now);
  void startTurnOrMove(const robot::RobotState& s);
  /// Belief mode: the look after this one (or kNotFound).
  void planNext(const robot::RobotState& s);
  /// Belief mode, driving or turning: a confirmed target ends the search, a candidate stops
  /// the base and is looked at (true: the state changed).
  bool holdOnTheWay(Seconds t, const robot::RobotState& s, TargetStatus observed,
                    const std::optional<Eigen::Vector2d>& candidate_w);
  /// Belief mode: base command along the planned path; true when its end is reached.
  bool followPath(const robot::RobotState& s, SearchCommand* c);

  robot::HeadModel head_;
  robot::EnonModel model_;
  Intrinsics camera_;
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
  // Belief mode.
  std::shared_ptr<BeliefSearch> belief_;
  std::shared_ptr<const SearchBelief> snapshot_;
  PlannedLook planned_;
  size_t waypoint_ = 0;
  std::optional<Eigen::Vector2d> candidate_w_;  ///< the look's last unconfirmed candidate
  std::optional<SearchLook> started_;
  std::string end_reason_;
  double half_fov_ = 0;
  bool on_the_way_ = true;  ///< frames taken while driving or turning are looked at
};

}  // namespace refgrasp::servo
