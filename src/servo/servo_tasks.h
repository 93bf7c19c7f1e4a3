#pragma once
// The vpServo tasks of search-approach-grasp. Each is a function of poses and joint states to
// velocity commands (no robot, no camera), so each is tested for convergence on its own
// (tests/servo/test_servo_tasks.cpp); the grasp controller (servo/grasp_controller.h) feeds them.
//
//   HeadPointingTask  pan/tilt servo centring a point in the camera image (vpFeaturePoint x, y)
//   BaseApproachTask  unicycle servo as in ViSP's Pioneer examples (servoPioneerPoint2DDepth):
//                     the image x of a point and log(Z / Z*) of another, seen by a virtual camera
//                     fixed on the base (the head camera at pan = tilt = 0, moved to the base
//                     origin), controlling (v, w)
//   ArmAlignTask      position-based servo of the gripper frame e to a desired pose e*
//                     (vpFeatureTranslation + vpFeatureThetaU of e*Me) with the 5 arm joints AND
//                     the base (v, w): 7 degrees of freedom for the 6 pose components, all six
//                     controlled; the one left over keeps the joints away from their limits
//                     (vpServo::secondaryTaskJointLimitAvoidance)
// Every task uses vpAdaptiveGain and scales its whole command (one factor, so the direction is
// kept) to its velocity limits.
//
// Frames (robot/enon_model.h): b base (x forward, y left, z up, on the floor), c left camera
// optical frame, e gripper (z_e the approach axis, fingers closing along x_e). aMb maps b
// coordinates into a (x_a = R x_b + t); metres, radians, seconds.
#include <Eigen/Core>
#include <memory>
#include <optional>
#include <string>

#include "core/pose.h"
#include "robot/enon_model.h"
#include "robot/kinematics.h"
#include "servo/grasp_geometry.h"

namespace refgrasp::servo {

/// vpAdaptiveGain: lambda(|e|_inf) = (at_zero - at_infinity) exp(-slope_at_zero |e| /
/// (at_zero - at_infinity)) + at_infinity, 1/s. A high gain near convergence ends the task
/// briskly; a low one far away keeps the first commands small.
struct GainOptions {
  double at_zero = 4.0;
  double at_infinity = 1.0;
  double slope_at_zero = 30.0;
  /// Throws std::invalid_argument "<what>.<field>: <problem>".
  void check(const std::string& what) const;
};

/// Camera twist (v, w in the camera frame c, reference point c's origin) per unit pan and tilt
/// rate: column 0 pan, column 1 tilt.
Eigen::Matrix<double, 6, 2> headJacobian(const robot::HeadModel& head, double pan_rad,
                                         double tilt_rad);

/// Gripper twist (v of e's origin and w, both in the gripper frame e) per unit joint rate, for the
/// arm joints then the base's (v_mps, w_radps) (columns dof, dof + 1): the base moving in the
/// world carries the arm with it. bMe = arm.forward(q).
Eigen::Matrix<double, 6, Eigen::Dynamic> gripperJacobian(const robot::ArmKinematics& arm,
                                                         const Eigen::VectorXd& q);

/// Velocity (in frame c, reference point c's origin) of a frame c fixed on the base at bMc when
/// the base moves at (v_mps along x_b, w_radps about z_b).
Twist baseTwistAt(const Pose& bMc, double v_mps, double w_radps);

// ---- head ------------------------------------------------------------------------------------

struct HeadPointingOptions {
  GainOptions gain{3.0, 1.5, 20.0};
  double max_pan_radps = 1.5;
  double max_tilt_radps = 1.0;
  /// Centred when |x| and |y| (normalised image coordinates, x = X / Z) are below this.
  double tolerance = 0.02;
  void check() const;
};

struct HeadCommand {
  double pan_radps = 0, tilt_radps = 0;
  double error = 0;        ///< |(x, y)| of the point, normalised image coordinates
  bool converged = false;  ///< within the tolerance
};

class HeadPointingTask {
 public:
  /// Throws std::invalid_argument for bad options.
  HeadPointingTask(const robot::HeadModel& head, const HeadPointingOptions& options = {});
  ~HeadPointingTask();
  HeadPointingTask(const HeadPointingTask&) = delete;
  HeadPointingTask& operator=(const HeadPointingTask&) = delete;

  /// \param cP the point to centre in the camera frame at the current head state (metres, Z > 0;
  /// a point behind the camera gives zero rates and converged = false).
  /// \param cV_carrier the camera's velocity caused by everything but the head (the base's
  /// motion), in the camera frame: fed forward, q_dot = -lambda J^+ e - J^+ L cV_carrier, so
  /// that the point stays centred while the base turns.
  HeadCommand compute(const Eigen::Vector3d& cP, double pan_rad, double tilt_rad,
                      const Twist& cV_carrier = {});
  const HeadPointingOptions& options() const { return opt_; }

 private:
  struct Impl;
  robot::HeadModel head_;
  HeadPointingOptions opt_;
  std::unique_ptr<Impl> impl_;
};

// ---- base ------------------------------------------------------------------------------------

/// Stages of BaseApproachTask::approach.
enum class ApproachStage {
  kToWaypoint,  ///< far off the approach line: to W (Pioneer servo on W itself)
  kFaceLine,    ///< at W: turn in place to face along the line
  kAlongLine,   ///< pure pursuit of the carrot, Pioneer depth on Q, until on G along the line
  kTurn,        ///< on G: turn in place to G's heading (what is left is lateral)
  kDone
};
const char* toString(ApproachStage s);  ///< "to_waypoint", "face_line", "along_line", "turn", "done"

struct BaseApproachOptions {
  GainOptions turn_gain{3.0, 2.0, 20.0};   ///< on the image x of the aimed point
  GainOptions drive_gain{3.0, 1.0, 10.0};  ///< on log(Z / Z*)
  double max_v_mps = 0.6;
  double max_w_radps = 1.0;
  /// The speed is scaled by 1 - |bearing| / turn_in_place_rad: the base turns in place while
  /// the aimed point is more than this off its x axis.
  double turn_in_place_rad = 0.8;
  double lookahead_m = 0.5;          ///< carrot distance; Q's distance after G (Z* on the line)
  double waypoint_m = 0.5;           ///< W's distance before G
  double line_tolerance_m = 0.15;    ///< closer to the line than this (and before W): no waypoint
  double waypoint_tolerance_m = 0.05;
  double along_tolerance_m = 0.01;   ///< on G along the line
  double heading_tolerance_rad = 0.015;
  void check() const;
};

struct BaseCommand {
  double v_mps = 0, w_radps = 0;
  ApproachStage stage = ApproachStage::kDone;  ///< approach() only
  ApproachPoints points;                       ///< approach() only
  double bearing_rad = 0;    ///< of the aimed point, counter-clockwise from x_b
  double depth_error_m = 0;  ///< Z - Z* of the depth point
};

class BaseApproachTask {
 public:
  /// Throws std::invalid_argument for bad options.
  explicit BaseApproachTask(const BaseApproachOptions& options = {});
  ~BaseApproachTask();
  BaseApproachTask(const BaseApproachTask&) = delete;
  BaseApproachTask& operator=(const BaseApproachTask&) = delete;

  /// Pioneer-style servo: image x of `bAim` -> 0 (the base turns to face it) and log(Z / Z*) of
  /// `bDepth` -> 0 (Z its distance along x_b), both points in the base frame (metres; heights are
  /// ignored). Points behind or far to the side: turn in place first.
  BaseCommand compute(const Eigen::Vector3d& bAim, const Eigen::Vector3d& bDepth,
                      double depth_desired_m);
  /// Turn in place to face `bAim` (v = 0).
  BaseCommand face(const Eigen::Vector3d& bAim);
  /// To the goal pose wMG (the base pose w = world or odometry): stages ApproachStage, chosen
  /// afresh after restart(): a base near the approach line (line_tolerance_m) and before W
  /// starts along the line, any other at W. Zero velocity once done. `wObject` (the object's
  /// centre, same frame as wMb) decides the way to W; without it, Q on the line beyond G.
  BaseCommand approach(const Pose& wMb, const Pose& wMG,
                       const std::optional<Eigen::Vector3d>& wObject = std::nullopt);
  void restart() { stage_.reset(), backwards_to_waypoint_.reset(); }
  const BaseApproachOptions& options() const { return opt_; }

 private:
  struct Impl;
  BaseApproachOptions opt_;
  std::unique_ptr<Impl> impl_;
  std::optional<ApproachStage> stage_;
  /// The way to W, chosen when the base first heads there and kept until it reaches it (the
  /// choice is a tie when W and the object are 90 deg apart: chosen afresh, it would flip).
  std::optional<bool> backwards_to_waypoint_;
};

// ---- arm -------------------------------------------------------------------------------------

struct ArmAlignOptions {
  GainOptions gain{2.5, 1.2, 30.0};
  /// Fraction of each joint's speed limit the task may use.
  double joint_speed_fraction = 0.6;
  double max_base_v_mps = 0.10;   ///< base contribution limits
  double max_base_w_radps = 0.25;
  double max_linear_mps = 0.20;   ///< gripper speed limits (whole command scaled)
  double max_angular_radps = 0.8;
  /// Weight of the base columns in the minimum-norm solution (1 = as cheap as an arm joint per
  /// unit; smaller leaves more of the motion to the arm). 0 excludes the base: the 5 arm joints
  /// then serve the 6 components in the least-squares sense.
  double base_weight = 0.5;
  bool joint_limit_avoidance = true;
  /// vpServo::secondaryTaskJointLimitAvoidance parameters (ViSP's defaults): the avoidance starts
  /// rho x range from a limit and is at full strength rho x rho1 x range further out.
  double joint_limit_rho = 0.1;
  double joint_limit_rho1 = 0.3;
  double joint_limit_lambda_tune = 0.7;
  void check() const;
};

struct ArmCommand {
  Eigen::VectorXd qdot_radps;     ///< arm joints
  double base_v_mps = 0, base_w_radps = 0;
  Eigen::Vector3d t_m = Eigen::Vector3d::Zero();         ///< translation of e*Me (in e*)
  Eigen::Vector3d theta_u_rad = Eigen::Vector3d::Zero(); ///< rotation of e*Me as theta u
  double position_error_m() const { return t_m.norm(); }
  double rotation_error_rad() const { return theta_u_rad.norm(); }
};

class ArmAlignTask {
 public:
  /// Throws std::invalid_argument for bad options or an arm without joints.
  ArmAlignTask(const robot::ArmModel& arm, const ArmAlignOptions& options = {});
  ~ArmAlignTask();
  ArmAlignTask(const ArmAlignTask&) = delete;
  ArmAlignTask& operator=(const ArmAlignTask&) = delete;

  /// \param q arm joints now; \param bMed desired gripper pose e* in the base frame now (static
  /// in the world); \param base_may_advance false: the base does not drive forward (its body is
  /// at a fixture), the arm and the base's turn and reverse serve the task.
  ArmCommand compute(const Eigen::VectorXd& q, const Pose& bMed, bool base_may_advance = true);
  const ArmAlignOptions& options() const { return opt_; }
  const robot::ArmKinematics& kinematics() const { return kin_; }

 private:
  struct Impl;
  robot::ArmKinematics kin_;
  ArmAlignOptions opt_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace refgrasp::servo
