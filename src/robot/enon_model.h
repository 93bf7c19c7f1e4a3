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

struct ArmModel {
  std::string side = "right";
  Pose bM0;                       ///< arm base (DH frame 0) in the base frame
  std::vector<DhJoint> joints;    ///< shoulder to wrist
  Pose nMe;                       ///< gripper frame e in the last DH frame
  double dls_damping = 0.05;      ///< lambda in qdot = J^T (J J^T + lambda^2 I)^-1 v
  int dof() const { return static_cast<int>(joints.size()); }
};

struct GripperModel {
  double close_time_s = 0.5, open_time_s = 0.5;
  double grasp_tolerance_m = 0.02;    ///< |e origin - grasp frame origin| to hold an object
  double grasp_tolerance_rad = 0.3;   ///< rotation angle between e and the grasp frame
  double max_payload_kg = 0.5;
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
