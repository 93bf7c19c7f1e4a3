#pragma once
// Where the base must stand and which arm configuration reaches a grasp: the geometry behind the
// approach and align phases, from the robot model and the grasp frame only (nothing here knows
// a scenario).
//
// Frames: w world (z up; in the controller the odometry frame), b base (x forward, y left, z up),
// e gripper (z_e approach axis, fingers close along x_e), g the object's grasp frame. The grasp
// pose is e = g; the pre-grasp pose e* = g * Trans(0, 0, -pregrasp_distance_m), in front of the
// object on the approach axis. aMb maps b coordinates into a; metres, radians.
#include <Eigen/Core>

#include "core/pose.h"
#include "detector/object.h"
#include "robot/kinematics.h"

namespace refgrasp::servo {

/// An arm configuration for a gripper pose.
struct ArmReach {
  bool ok = false;           ///< converged within the tolerances and inside the joint limits
  Eigen::VectorXd q;         ///< arm joints (rad)
  Pose bMe;                  ///< the gripper pose q gives
  double position_error_m = 0, rotation_error_rad = 0;  ///< to the requested pose components
  double joint_margin = 0;   ///< smallest distance to a limit, as a fraction of the joint's range
};

/// The arm's comfortable "reach forward" configuration: the gripper at height `z_m` with
/// orientation `bRe`, in the vertical plane of the shoulder (y = the arm mount's y). Five equations
/// for five joints, solved by damped Newton steps from `q_start` (or from mid-range joints when
/// empty). Its x is what the arm reaches in front of the base in that orientation.
ArmReach reachInShoulderPlane(const robot::ArmKinematics& arm, const Eigen::Matrix3d& bRe,
                              double z_m, const Eigen::VectorXd& q_start = {});

/// The base pose for a grasp: standing so that the pre-grasp pose wMed is reached by the arm
/// configuration `reach` (computed for bRe = the pre-grasp orientation seen from that base).
struct BaseGoal {
  Pose wMb;                 ///< base pose in w (on the floor, z = 0, rotation about z only)
  double heading_rad = 0;   ///< of x_b, counter-clockwise from x_w
  ArmReach reach;           ///< the arm configuration reaching wMed from wMb
};

/// Base heading: along the horizontal projection of the approach axis z_e* (the base faces the
/// object's grasp side). Position: wMed's origin minus the reach's horizontal offset.
/// `q_start` seeds the arm solution (e.g. the previous goal's).
BaseGoal baseGoalFor(const robot::ArmKinematics& arm, const Pose& wMed,
                     const Eigen::VectorXd& q_start = {});

/// The points a unicycle base steers by on its way to a goal pose G (servo/servo_tasks.h
/// BaseApproachTask::approach): the approach line runs through G along x_G; W lies on it
/// `waypoint_m` before G, Q `lookahead_m` after G; the carrot lies on it `lookahead_m` ahead of
/// the base's own projection on it, never past Q. Base frame, z = 0.
struct ApproachPoints {
  Eigen::Vector3d bWaypoint = Eigen::Vector3d::Zero();  ///< W
  Eigen::Vector3d bAim = Eigen::Vector3d::Zero();    ///< the carrot
  Eigen::Vector3d bDepth = Eigen::Vector3d::Zero();  ///< Q, base frame (z = 0)
  Eigen::Vector3d bAhead = Eigen::Vector3d::Zero();  ///< a point far along x_G from the base: face it to take G's heading
  double depth_desired_m = 0;
  double position_error_m = 0;  ///< |base origin - G| on the floor
  double heading_error_rad = 0; ///< heading of G minus the base's, in (-pi, pi]
  double along_m = 0;           ///< signed distance of the base past G along x_G (< 0 before it)
  double lateral_m = 0;         ///< signed distance of the base from the line (left of x_G > 0)
};
ApproachPoints approachPoints(const Pose& wMb, const Pose& wMg, double lookahead_m,
                              double waypoint_m);

/// The space an object occupies as its definition tells it: the axis-aligned box, in the object
/// frame (metres), around a planar object's pattern quadrilateral (flat: z from 0 to 0), a
/// cylinder's solid (the label's height along y, x within the radius, z from 0 to the diameter:
/// the label lies on the side of a solid cylinder, whatever part of the round it covers), or the
/// union of a several-view object's views moved by their oMv (a box defined by its faces: the box).
struct ObjectExtent {
  Eigen::Vector3d min_o = Eigen::Vector3d::Zero(), max_o = Eigen::Vector3d::Zero();
  /// The point the head keeps centred: the box's centre (a cylinder's axis at the label's
  /// centre height, a box's centre, a plane's pattern centre).
  Eigen::Vector3d centre() const { return 0.5 * (min_o + max_o); }
  /// Distance from the origin of oMg back along -z_g (the approach axis, out of the object) to
  /// where that line leaves the box; 0 when the origin is outside it.
  double depthBehind(const Pose& oMg) const;
};
/// Throws std::invalid_argument for an object without metric geometry (2D only), naming it.
ObjectExtent objectExtent(const detector::ObjectModel& object);

/// Smallest distance of q to a joint limit as a fraction of that joint's range (0 at a limit).
double jointMargin(const robot::ArmModel& arm, const Eigen::VectorXd& q);

/// Heading (rad, counter-clockwise from x) of a pose's x axis projected on the floor.
double planarHeading(const Pose& wMb);

}  // namespace refgrasp::servo
