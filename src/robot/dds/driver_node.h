#pragma once
// The robot's side of the bus: serves any robot::RobotHardware + robot::StereoSource on the
// topics of robot/dds/robot_topics.h, as a ROS 2 robot driver would. sim_robot_node runs it on the
// simulated enon; the same node would serve the real enon's controller.
//
// Per step(time): read the hardware and publish joint_states and odom (stamped `time`, the robot's
// clock); take the newest commands and write them to the hardware; every 1 / camera_rate_hz grab a
// stereo frame and publish left/right image_raw (mono8) and camera_info (stamped at capture).
// Each command is dropped when it gets older than the watchdog period (for a trajectory: its
// time_from_start, if shorter), counted from its writing (the sample's source timestamp), not its
// arrival: a silent controller stops the robot, and a driver that stalled does not take a
// command that waited in its reader for new. Across machines the controller's and the robot's
// clocks must agree to well within the watchdog period (NTP, chrony); a controller clock ahead
// of the robot's counts as age 0.
#include <atomic>
#include <memory>
#include <string>

#include "robot/enon_model.h"
#include "robot/hal.h"

namespace refgrasp::dds {

struct DriverNodeOptions {
  int domain = 0;
  std::string ns = "/enon";
  /// Stereo frames published per second at most (0: every frame the source delivers).
  double camera_rate_hz = 0;
  /// Throws std::invalid_argument "DriverNodeOptions.<field>: <problem>".
  void check() const;
};

struct DriverNodeStats {
  long steps = 0;
  long commands = 0;          ///< command messages taken (all topics)
  long bad_commands = 0;      ///< non-finite or malformed, ignored
  long frames_published = 0;  ///< stereo pairs
  long hardware_errors = 0;   ///< read/write/grab calls that did not return kOk
};

class RobotDriverNode {
 public:
  /// Creates the DDS endpoints (throws DdsError). `camera` may be null (no images).
  RobotDriverNode(const robot::EnonModel& model, robot::RobotHardware& hardware,
                  robot::StereoSource* camera, const DriverNodeOptions& options);
  ~RobotDriverNode();
  RobotDriverNode(const RobotDriverNode&) = delete;
  RobotDriverNode& operator=(const RobotDriverNode&) = delete;

  /// configure() + activate() of the hardware, then a first camera grab (at time 0).
  robot::ReturnType start();
  /// One control cycle at robot time `time` (seconds, increasing).
  robot::ReturnType step(Seconds time);
  /// Zero command, then deactivate().
  void stop(Seconds time);

  /// A snapshot (thread-safe: a test or a monitor may poll it while another thread steps).
  DriverNodeStats stats() const;
  const robot::RobotState& state() const;  ///< as last read from the hardware

 private:
  struct Impl;
  std::unique_ptr<Impl> p_;
};

/// Steps `node` every period_s of wall-clock time (robot time starts at 0) until `stop` becomes
/// true or duration_s (> 0) has elapsed; then stops the node. Returns kError if start() failed.
robot::ReturnType runRealTime(RobotDriverNode& node, double period_s, const std::atomic<bool>& stop,
                              double duration_s = 0);

}  // namespace refgrasp::dds
