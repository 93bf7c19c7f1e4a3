#pragma once
// Search-approach-grasp on the enon: one step(t, dt) per control period owns the cycle
// read -> grab -> estimate -> decide -> write and its safety rules (STYLE.md "The servo loop").
// It reaches the robot only through the HAL (robot/hal.h, robot/camera.h), and perception only
// through a TargetEstimator (servo/target_estimator.h): vision, or the simulator's ground truth.
//
// Phases and their outcomes (GraspReport):
//   search    stop-and-look head sweeps, base turns, other viewpoints (servo/search_plan.h) until
//             the estimator CONFIRMS the target            found | not_found | timeout
//   approach  the base to the pose from which the arm reaches the pre-grasp pose (pure pursuit
//             onto the approach line, then the Pioneer-style servo; servo/servo_tasks.h), the
//             head pointing at the target, the arm moving to its reaching configuration
//                                                          converged | lost | unreachable | timeout
//   align     PBVS of the gripper to the pre-grasp pose e* = g Trans(0, 0, -pregraspDistance())
//             (arm joints + base; all six components)     converged | lost | timeout
//   grasp     straight-line final approach along z_e (the PBVS following e* sliding to g at
//             grasp_speed_mps; the base does not drive forward), close, check holding, lift,
//             check still holding
//                                                          holding | missed | dropped | lost | timeout
// A phase ends the run on any outcome but its success one (converged / found / holding), except
// "lost" (the target stayed unconfirmed for reacquire_timeout_s), which returns to the search.
//
// Safety (every step): zero velocity to every actuator
//   - when the target is not CONFIRMED in a phase that moves towards it (approach, align, the
//     grasp's final approach): lost in this period's frame, unconfirmed, or no confirmed frame
//     for max_estimate_age_s; an unconfirmed target never moves the robot;
//   - when a look of the search holds an unconfirmed target;
//   - when converged, done or failed, and on every error: a robot read/write or camera error, a
//     frame the estimator cannot use (wrong size, no ground truth for the oracle), an exception
//     from anything (the estimator included): the robot is stopped, step() returns kError with
//     one line, and every later step() only stops the robot again.
// and no forward base motion in the approach and the align that would bring the base's body
// within fixture_clearance_m of a fixture of the room map (the arm then reaches alone), nor in
// the final approach at all (final_approach_base false, the default).
//
// Frames: w is the ODOMETRY frame (wMb_odom); the target is kept as wMo = wMb_odom(capture) *
// bMc(capture) * cMo, i.e. compensated for the camera and base motion between the exposure and
// the use, and seen from the base now as bMo = wMb_odom(now)^-1 wMo. cMo is the object in the
// LEFT camera frame at capture; g the grasp frame (oMg from the caller); e the gripper. Metres,
// radians, seconds.
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/pose.h"
#include "core/types.h"
#include "robot/hal.h"
#include "servo/grasp_geometry.h"
#include "servo/search_map.h"
#include "servo/search_plan.h"
#include "servo/servo_tasks.h"
#include "servo/target_estimator.h"

namespace refgrasp::servo {

struct GraspOptions {
  SearchPlanOptions search;
  /// The search by belief (servo/search_belief.h) over `room` (odometry frame; empty: an unknown
  /// room); false: the sweep of servo/search_plan.h, each direction once.
  bool belief_search = true;
  BeliefSearchOptions belief;
  RoomMap room;
  HeadPointingOptions head;
  BaseApproachOptions base;
  ArmAlignOptions arm;

  /// e* in front of the grasp frame along -z_g: at least pregrasp_distance_m, and at least
  /// pregrasp_clearance_m outside the object's extent (a grasp frame deep inside a large object:
  /// the fingers start clear of its face whatever its size).
  double pregrasp_distance_m = 0.12;
  double pregrasp_clearance_m = 0.05;
  /// The base does not drive forward when its body (the model's vertical cylinder about z_b)
  /// would come within this of a fixture of `room` (m) in the next control period at the phase's
  /// speed; turning never brings it closer. The arm then serves the task alone. Without a room
  /// map there is no guard. 2 cm: below the 6 cm the body clears a table by in a grasp of the
  /// reach the model was checked for (config/enon.yaml), so that grasp never meets the guard.
  /// The map is odometry-relative: with odometry noise it can be off by more than this
  /// (room_hotel_corner), which is why the final approach does not rely on it
  /// (final_approach_base).
  double fixture_clearance_m = 0.02;
  double approach_arm_tolerance_rad = 0.05;    ///< arm joints at the reaching configuration
  double arm_ready_speed_fraction = 0.6;  ///< of each joint's limit, moving to that configuration
  /// The base comes no closer than this to its approach goal (m) until the arm is within
  /// arm_ready_tolerance_rad of its reaching configuration: an arm still rising from where it
  /// hangs sweeps its open fingers through the table's edge if the base is already there.
  double arm_ready_distance_m = 0.4;
  double arm_ready_tolerance_rad = 0.15;
  double align_position_tolerance_m = 0.003;
  double align_rotation_tolerance_rad = 0.015;
  double grasp_speed_mps = 0.1;           ///< final approach along z_e
  /// The final approach's base: false, it does not drive forward (it may turn and back off) and
  /// the arm slides the gripper onto the grasp frame; true, the base takes its share as in the
  /// align. The last 12 cm go over the table, whose edge the robot knows only through its
  /// odometry-relative map: a base share of them put the body against the edge of a low grasp
  /// frame near it, the map's guard (fixture_clearance_m) off by the odometry's drift.
  bool final_approach_base = false;
  double grasp_position_tolerance_m = 0.003;
  double grasp_rotation_tolerance_rad = 0.015;
  double lift_m = 0.05;
  double lift_speed_mps = 0.08;
  double hold_check_s = 0.3;              ///< still holding this long after the lift: success

  /// Frames are given to the estimator at most this often (0: every frame). Processing fewer
  /// frames than the camera delivers is what a real-time loop does when its vision is slower
  /// than the camera; the target between frames is the world estimate seen through odometry.
  double frame_period_s = 1.0 / 16;
  /// 0: the world estimate is the last confirmed observation; in (0, 1): each confirmed
  /// observation moves it this fraction of the way (exponential smoothing of vision noise).
  double estimate_smoothing = 0.0;
  double max_estimate_age_s = 0.4;   ///< no confirmed frame for longer: the target is lost
  double reacquire_timeout_s = 2.0;  ///< lost target: hold still this long, then search again
  int max_searches = 3;              ///< searches in one run (the first included)

  /// The approach gives up as "unreachable" only when no arm configuration reaches the
  /// pre-grasp pose of any estimate for this long (one poor estimate, e.g. a far view's tilt
  /// error, must not end the run); meanwhile the robot holds still (or keeps the last
  /// reachable goal).
  double unreachable_patience_s = 1.0;
  /// Reachability is judged only on estimates from within reestimate_range_m of the base (m,
  /// horizontal): an unreachable pre-grasp pose from further (a small face detected from afar
  /// can come out with its plane flipped) drives the base towards the target's position, the
  /// head on it, until it is reestimate_stop_m away, and the estimates made from there decide.
  double reestimate_range_m = 2.0;
  double reestimate_stop_m = 1.5;
  double search_timeout_s = 120;  ///< a 10 x 10 m room with four tables takes a minute to tour
  double approach_timeout_s = 30;
  double align_timeout_s = 15;
  double grasp_timeout_s = 15;
  /// Throws std::invalid_argument "GraspOptions.<field>: <problem>" (nested options too).
  void check() const;
};

enum class GraspPhase { kSearch, kApproach, kAlign, kGrasp, kDone, kFailed };
const char* toString(GraspPhase p);  ///< "search", "approach", "align", "grasp", "done", "failed"

/// The grasp phase's sub-steps, in order: the servo slides the gripper onto the grasp frame
/// (reach), the gripper closes (close), the arm lifts (lift), the hold is checked (hold).
enum class GraspSubStep { kReach, kClose, kLift, kHold };
const char* toString(GraspSubStep s);  ///< "reach", "close", "lift", "hold" (control.jsonl's detail)

/// One control period, everything a log line needs to replay it.
struct GraspIteration {
  Seconds t = 0;
  GraspPhase phase = GraspPhase::kSearch;  ///< after this step
  std::string detail;        ///< sub-step: search state, "drive"/"turn", "reach"/"close"/...
  std::string event;         ///< what happened in this step ("" most of the time)
  TargetStatus observed = TargetStatus::kNone;  ///< the estimator on this period's frame
  bool confirmed = false;    ///< the controller acts on a confirmed target in this period
  bool target_driven = false;  ///< this period's commands depend on the target (must be zero if !confirmed)
  /// The frame given to the estimator, if any. Frames are grabbed only when wanted: in the
  /// search's looks and the target-driven phases, at most every frame_period_s.
  std::optional<robot::StereoFrame> frame;
  TargetObservation observation;            ///< the estimator's result on `frame`
  /// Ground truth of the frame grabbed in this period, when it carries one (simulators; logs
  /// and evaluation only, never control), and that frame's device counter.
  std::vector<robot::ObjectTruth> truth;
  std::optional<int64_t> grabbed_index;
  std::optional<Pose> wMo;                  ///< the world (odometry) estimate after this step
  std::optional<Pose> bMe_desired;          ///< align / grasp: e* in the base frame now
  double distance_m = -1;     ///< gripper origin to grasp frame origin (estimate; -1 unknown)
  double error_position_m = -1, error_rotation_rad = -1;  ///< the active task's error (-1 none)
  robot::RobotState state;    ///< as read in this step
  robot::RobotCommand command;  ///< as written in this step (zero when stopped)
  /// The search's belief after this step (shared, unchanged between looks; null when the run
  /// has no belief), and the look that started in this step.
  std::shared_ptr<const SearchBelief> belief;
  std::optional<SearchLook> look_started;
};

struct GraspStep {
  robot::ReturnType status = robot::ReturnType::kOk;
  std::string error;  ///< one line when status != kOk
  GraspIteration it;
};

struct PhaseReport {
  double time_s = 0;
  std::string outcome;  ///< "" while running
};

struct GraspReport {
  bool success = false;
  std::string failure;  ///< one line when the run failed
  std::map<std::string, PhaseReport> phases;  ///< by phase name, the phases that ran
  int searches = 0;
  /// At the close: gripper to grasp frame, from the controller's estimate (m, rad; -1 unknown).
  double close_position_error_m = -1, close_rotation_error_rad = -1;
};

class GraspController {
 public:
  /// \param robot an active robot; \param estimator the target's estimator (outlives this);
  /// \param oMg the grasp frame in the object frame; \param object_o the object's extent
  /// (objectExtent): the head keeps its centre in view, and the pre-grasp pose stands
  /// pregrasp_clearance_m outside it. Throws std::invalid_argument for bad options.
  GraspController(robot::Robot& robot, TargetEstimator& estimator, const Pose& oMg,
                  const ObjectExtent& object_o, const GraspOptions& options = {});
  /// e* before the grasp frame along -z_g (m): the options' distance or the clearance rule.
  double pregraspDistance() const { return pregrasp_m_; }
  ~GraspController();

  /// One control period at time t (period dt). Never throws.
  GraspStep step(Seconds t, Seconds dt);

  /// Ends the run from outside (e.g. the application's time limit): the current phase gets
  /// `outcome`, the run fails with `why`, the robot is stopped.
  void abort(Seconds t, const std::string& outcome, const std::string& why);

  GraspPhase phase() const { return phase_; }
  bool finished() const { return phase_ == GraspPhase::kDone || phase_ == GraspPhase::kFailed; }
  const GraspReport& report() const { return report_; }
  const GraspOptions& options() const { return opt_; }

 private:
  GraspStep fail(GraspStep s, const std::string& error);
  void enter(GraspPhase p, Seconds t, const std::string& outcome_of_previous, GraspIteration* it);
  void finish(bool success, const std::string& outcome, const std::string& failure, Seconds t,
              GraspIteration* it);
  /// Grabs a frame when one is wanted (and due by frame_period_s) and gives it to the
  /// estimator; updates the target belief. One line on a camera error or a frame the estimator
  /// cannot use, else "".
  std::string observe(Seconds t, bool want, Seconds look_after, GraspIteration* it);
  void decideSearch(Seconds t, GraspIteration* it);
  void decideApproach(Seconds t, GraspIteration* it);
  void decideAlign(Seconds t, GraspIteration* it);
  void decideGrasp(Seconds t, GraspIteration* it);
  /// Target-driven phases: true when the target is confirmed; otherwise holds the robot still,
  /// and after reacquire_timeout_s returns to the search.
  bool targetUsable(Seconds t, GraspIteration* it);
  /// Head pointing at the target's centre, the base's commanded motion fed forward.
  void pointHead(const Pose& wMb, double base_v_mps, double base_w_radps);
  void stopMotion();
  Pose wMb() const;
  /// Whether the base may drive forward at v_mps for one control period from wMb_now without
  /// its body coming within fixture_clearance_m of a fixture of the room; when not, `blocker`
  /// names that fixture.
  bool baseMayAdvance(const Pose& wMb_now, double v_mps, std::string* blocker = nullptr) const;
  /// Zeroes b's forward speed when the base may not advance; notes the fixture in the log once.
  void guardBase(const Pose& wMb_now, BaseCommand* b, GraspIteration* it);
  /// An approach goal moved back along its heading until the body clears every fixture of the
  /// room by fixture_clearance_m (the arm reaches the difference), so the guard never holds the
  /// base short of it.
  Pose clearOfFixtures(const Pose& wMb_goal) const;
  /// The same guard for the arm task's base motion, at the speed it may command.
  bool armBaseMayAdvance(const Pose& wMb_now, GraspIteration* it);
  std::string guard_note_;  ///< the fixture the guard last stopped the base at ("" none)
  /// ": <the hardware's one-line reason>" for the last read/write error, or "".
  std::string why() const;

  robot::Robot& robot_;
  TargetEstimator& est_;
  Pose oMg_;
  Eigen::Vector3d centre_o_;
  GraspOptions opt_;
  double pregrasp_m_ = 0;
  SearchPlan plan_;
  HeadPointingTask head_task_;
  BaseApproachTask base_task_;
  ArmAlignTask arm_task_;

  GraspPhase phase_ = GraspPhase::kSearch;
  std::string detail_;
  bool started_ = false;
  Seconds phase_start_ = 0, last_t_ = 0;
  GraspReport report_;
  std::string error_;

  // Target belief.
  std::optional<Pose> wMo_;
  Seconds confirmed_stamp_ = -1e9;  ///< capture time of the last confirmed observation
  TargetStatus belief_ = TargetStatus::kNone;
  std::optional<Seconds> lost_since_;
  Seconds next_grab_ = -1e9;        ///< frame-rate limiter (control time)
  SearchCommand search_cmd_;
  std::optional<Eigen::Vector2d> candidate_w_;  ///< this period's unconfirmed candidate (odometry x, y)

  // Phase state.
  std::optional<BaseGoal> goal_;
  std::optional<Seconds> unreachable_since_;  ///< approach: first estimate in a row without a reach
  bool closer_ = false;  ///< approach: driving nearer a far target before judging reachability
  Seconds grasp_started_ = 0;
  GraspSubStep grasp_step_ = GraspSubStep::kReach;
  Seconds step_started_ = 0;
  Pose lift_start_bMe_;
};

}  // namespace refgrasp::servo
