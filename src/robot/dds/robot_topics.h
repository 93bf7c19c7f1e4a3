#pragma once
// The robot on the DDS bus: topic names, joint names and encodings shared by the "dds" backend
// (the controller's side, robot/dds/dds_robot.h) and the driver node (the robot's side,
// robot/dds/driver_node.h). ROS names under a namespace (default /enon); on DDS "rt" + name.
//
//   <ns>/cmd_vel            geometry_msgs/Twist        base: linear.x = v (m/s), angular.z = w (rad/s)
//   <ns>/head/command       trajectory_msgs/JointTrajectory  [head_pan, head_tilt], one point:
//                           velocities (rad/s) or positions (rad); time_from_start = how long the
//                           command is valid (the HAL's watchdog deadline)
//   <ns>/arm/command        trajectory_msgs/JointTrajectory  arm joints (enon.yaml DH names), one
//                           point of velocities (rad/s), time_from_start = validity
//   <ns>/gripper/command    trajectory_msgs/JointTrajectory  [gripper], positions [1 open | 0 close]
//   <ns>/joint_states       sensor_msgs/JointState     head_pan, head_tilt, arm joints, gripper
//   <ns>/odom               nav_msgs/Odometry          odom -> base_link; twist in base_link
//   <ns>/{left,right}/image_raw, camera_info           the stereo camera (mono8; same stamps)
// The gripper in joint_states: position 1 open, 0 closed; velocity +1 opening, -1 closing;
// effort 1 while it holds an object. The driver drops every command when it gets older than the
// watchdog period (Twist carries no time, so from its arrival), so a robot never keeps moving on
// a controller that went silent; the backend reports an error and commands zero when the robot's
// state is older than the watchdog period.
#include <string>
#include <vector>

#include "robot/enon_model.h"
#include "robot/hal.h"

namespace refgrasp::dds {

struct RobotTopics {
  explicit RobotTopics(const std::string& ns);
  std::string cmd_vel, head_command, arm_command, gripper_command, joint_states, odom;
  std::string left_image, left_info, right_image, right_info;
};

inline const char* kHeadPanJoint = "head_pan";
inline const char* kHeadTiltJoint = "head_tilt";
inline const char* kGripperJoint = "gripper";
inline const char* kOdomFrame = "odom";
inline const char* kBaseFrame = "base_link";
inline const char* kLeftOpticalFrame = "left_camera_optical_frame";
inline const char* kRightOpticalFrame = "right_camera_optical_frame";

/// Arm joint names on the wire: the DH joint names of the model.
std::vector<std::string> armJointNames(const robot::EnonModel& model);

struct GripperJoint {
  double position = 1, velocity = 0, effort = 0;
};
GripperJoint encodeGripper(robot::GripperPhase phase);
robot::GripperPhase decodeGripper(const GripperJoint& j);

}  // namespace refgrasp::dds
