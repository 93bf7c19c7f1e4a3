#pragma once
// Backend "dds": an enon whose driver lives on the DDS bus (robot/dds/robot_topics.h), e.g. the
// real robot's driver or sim_robot_node. A robot::RobotHardware that publishes the commands and
// reads joint_states + odom, and a robot::StereoSource that pairs left/right image_raw by stamp.
//
// Clock: stamps on the bus are on the robot's clock. The first state read after activate() fixes
// the offset to the caller's clock (caller time - stamp - time since that state arrived); the
// caller's clock must run at the real-time rate (the robot does).
// Watchdog: read() and write() return kError (and write() sends zero commands) when the newest
// joint_states or odom arrived longer than the model's watchdog period ago; activate() waits up
// to connect_timeout_s for the first state. Errors are one line on the log (stderr by default).
// The stereo rig is the model's (enon.yaml): camera_info on the bus is for other consumers.
#include <functional>
#include <memory>
#include <string>

#include "robot/backend.h"
#include "robot/enon_model.h"
#include "robot/hal.h"

namespace refgrasp::dds {

struct DdsRobotOptions {
  int domain = 0;                  ///< DDS domain id, [0, 232]
  std::string ns = "/enon";        ///< ROS namespace of the robot's topics
  double connect_timeout_s = 5.0;  ///< activate() waits this long for the first state
  /// Throws std::invalid_argument "DdsRobotOptions.<field>: <problem>".
  void check() const;
};

/// Where the backend's one-line errors also go, once each (default: nowhere; the hardware's
/// lastError() holds the latest, and the caller reports it as its one line).
using LogSink = std::function<void(const std::string&)>;

/// A Robot on the DDS backend. Its hardware() and camera are DDS endpoints created at configure().
std::unique_ptr<robot::Robot> makeDdsRobot(const robot::EnonModel& model,
                                           const DdsRobotOptions& options, LogSink log = {});

/// Registers backend "dds" (robot/backend.h). Settings: `domain` (default 0), `ns` (default
/// /enon), `connect_timeout_s` (default 5). Throws ConfigError naming config.source (or the model
/// file) and the setting when one is malformed.
void registerDdsBackend();

}  // namespace refgrasp::dds
