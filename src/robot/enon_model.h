#pragma once
// The enon robot model (base, head with stereo camera, one arm, gripper), read from config/enon.yaml.
// Everything the HAL and the simulated enon need comes from here, so a real calibration can
// replace the file without code changes.
//
// Frames (all right-handed):
//   w  world: z up, origin on the floor.
//   b  base: on the floor midway between the wheels, x forward, y left, z up.
//   p  pan: head pan frame at pan = 0, given in b by head.mount (bMp); pan rotates about p.z.
//   t  tilt: t = Rz(pan) * Trans(0, 0, tilt_height) * Ry(tilt) in p; tilt > 0 looks down.
//   c  left camera optical frame (x right, y down, z forward); tMc = head.camera_mount.
//   0  arm base (first DH frame), bM0 = arm.mount; n last DH frame; e gripper frame, nMe = arm.tool.
//      z_e is the approach direction, the fingers close along x_e, e lies between the fingertips
//      (where an object's grasp frame must be for a grasp).
// Collision geometry (the simulated enon checks it; robot/sim/sim_enon.h): the base body is a
// vertical cylinder on the floor about z_b; upper arm and forearm are capsules (segment + radius)
// between DH frame origins; the hand is a palm capsule along x_e and two finger capsules along z_e.
// Units: metres, radians, seconds.
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"

namespace refgrasp::robot {

/// Position and speed limits of one revolute joint.
struct JointLimits {
  double min_rad = 0, max_rad = 0;
  double max_speed_radps = 0;
};

/// One row of a standard Denavit–Hartenberg table: i-1Mi = Rz(q + theta_offset) Tz(d) Tx(a) Rx(alpha).
struct DhJoint {
  std::string name;
  double a_m = 0, alpha_rad = 0, d_m = 0, theta_offset_rad = 0;
  JointLimits limits;
};

struct BaseModel {
  double track_width_m = 0.4;              ///< distance between the wheel contact points
  double max_linear_speed_mps = 0.83;      ///< 3 km/h
  double max_angular_speed_radps = 1.0;
  double max_wheel_speed_mps = 0.9;        ///< per wheel: |v +- w * track / 2|
  double body_radius_m = 0.25;             ///< collision body: vertical cylinder about z_b ...
  double body_height_m = 1.30;             ///< ... from the floor up to this height
};

struct HeadModel {
  Pose bMp;                   ///< pan frame at pan = 0 in the base frame
  double tilt_height_m = 0;   ///< tilt axis above the pan frame origin
  JointLimits pan, tilt;
  Pose tMc;                   ///< head-to-camera: left camera optical frame in the tilt frame
  std::string rig_path;       ///< stereo rig file (resolved)
  StereoRig rig;
  double frame_rate_hz = 48;
};

/// A collision capsule along the arm: the segment joining the origins of DH frames from_frame and
/// to_frame (0 = arm base frame, i = frame after joint i, n = last DH frame), radius_m around it.
struct LinkCapsule {
  int from_frame = 0, to_frame = 0;
  double radius_m = 0;
};

struct ArmModel {
  std::string side = "right";
  Pose bM0;                       ///< arm base (DH frame 0) in the base frame
  std::vector<DhJoint> joints;    ///< shoulder to wrist
  Pose nMe;                       ///< gripper frame e in the last DH frame
  double dls_damping = 0.05;      ///< lambda in qdot = J^T (J J^T + lambda^2 I)^-1 v
  LinkCapsule upper_arm{0, 3, 0.04};   ///< shoulder to elbow
  LinkCapsule forearm{3, 5, 0.03};     ///< elbow to wrist
  int dof() const { return static_cast<int>(joints.size()); }
};

struct GripperModel {
  double close_time_s = 0.5, open_time_s = 0.5;
  double grasp_tolerance_m = 0.02;    ///< |e origin - grasp frame origin| to hold an object
  double grasp_tolerance_rad = 0.3;   ///< rotation angle between e and the grasp frame
  double max_payload_kg = 0.5;
  // Geometry in the gripper frame e. Each finger is a capsule along z_e, its axis at
  // x_e = +-(gap / 2 + finger_radius_m), from the palm axis (z_e = -palm_offset_m) to the fingertip
  // (z_e = finger_length_m - palm_offset_m > 0, so e lies between the fingers); gap is
  // open_width_m when open, less while closing. The palm is a capsule along x_e at
  // z_e = -palm_offset_m joining the two finger axes.
  double open_width_m = 0.28;      ///< clear gap between the inner surfaces of the open fingers
  double finger_length_m = 0.115;  ///< palm axis to fingertip, along z_e
  double finger_radius_m = 0.012;
  double palm_offset_m = 0.085;    ///< palm axis behind e, along -z_e
  double palm_radius_m = 0.02;
};

struct EnonModel {
  std::string path;                 ///< file it came from ("" when built in code)
  double control_period_s = 0.02;
  double watchdog_period_s = 0.2;   ///< no command for longer: every actuator to zero velocity
  BaseModel base;
  HeadModel head;
  ArmModel arm;
  GripperModel gripper;
  /// Throws std::invalid_argument on inconsistent values (for models built in code).
  void check() const;
};

/// Reads config/enon.yaml. Throws ConfigError "<file>: <field>: <problem>" (one line).
EnonModel loadEnonModel(const std::string& path);

}  // namespace refgrasp::robot
