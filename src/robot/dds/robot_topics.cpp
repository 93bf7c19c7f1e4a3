#include "robot/dds/robot_topics.h"

#include "robot/dds/transport.h"

namespace refgrasp::dds {

RobotTopics::RobotTopics(const std::string& ns)
    : cmd_vel(joinRosName(ns, "cmd_vel")),
      head_command(joinRosName(ns, "head/command")),
      arm_command(joinRosName(ns, "arm/command")),
      gripper_command(joinRosName(ns, "gripper/command")),
      joint_states(joinRosName(ns, "joint_states")),
      odom(joinRosName(ns, "odom")),
      left_image(joinRosName(ns, "left/image_raw")),
      left_info(joinRosName(ns, "left/camera_info")),
      right_image(joinRosName(ns, "right/image_raw")),
      right_info(joinRosName(ns, "right/camera_info")) {}

std::vector<std::string> armJointNames(const robot::EnonModel& model) {
  std::vector<std::string> names;
  for (const auto& j : model.arm.joints) names.push_back(j.name);
  return names;
}

GripperJoint encodeGripper(robot::GripperPhase p) {
  using robot::GripperPhase;
  switch (p) {
    case GripperPhase::kOpen: return {1, 0, 0};
    case GripperPhase::kClosing: return {0.5, -1, 0};
    case GripperPhase::kClosedEmpty: return {0, 0, 0};
    case GripperPhase::kHolding: return {0, 0, 1};
    case GripperPhase::kOpening: return {0.5, 1, 0};
  }
  return {};
}

robot::GripperPhase decodeGripper(const GripperJoint& j) {
  using robot::GripperPhase;
  if (j.velocity < 0) return GripperPhase::kClosing;
  if (j.velocity > 0) return GripperPhase::kOpening;
  if (j.position > 0.5) return GripperPhase::kOpen;
  return j.effort > 0 ? GripperPhase::kHolding : GripperPhase::kClosedEmpty;
}

}  // namespace refgrasp::dds
