#pragma once
// The simulated enon: a shipped backend of the HAL (robot/hal.h), not test code.
//
// read(time) integrates the commands in force from the previous read up to `time` in closed form:
// unicycle arcs for the base, constant-rate joint motion stopped at the limits for head and arm,
// the head moving at top speed in position mode. A command sent by write(t) applies from
// t + faults.command_latency_s for at most the watchdog period (valid_for_s), then zero velocity.
// The gripper closes in close_time_s; it then holds the nearest object whose grasp frame
// (wMo * oMg) is within grasp_tolerance_m and grasp_tolerance_rad of the gripper frame, else it is
// closed on nothing. A held object moves with the hand (wMo = wMe * eMo); opening releases it where
// it is (no gravity). Faults per scenario: command latency, frame drops, frame delay, odometry
// noise (std of the error grows with the square root of the distance / angle travelled), a stuck
// joint. Same seed and same calls: same trajectory and bit-identical images.
//
// Camera frames are rendered by SyntheticStereoCamera from the TRUE left camera pose
// wMc = wMb_true * bMc(pan, tilt) at the capture time (linear interpolation between reads);
// the odometry in RobotState carries the noise. Each frame's `truth` holds the true pose of every
// world object that has a detector definition, in both eyes.
#include <deque>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "robot/enon_model.h"
#include "robot/hal.h"
#include "robot/kinematics.h"
#include "robot/sim/scenario.h"
#include "robot/sim/synthetic_camera.h"
#include "robot/backend.h"

namespace refgrasp::sim {

class SimEnon : public robot::RobotHardware {
 public:
  /// \param model robot model; \param scenario world, start pose, faults, camera degradation, seed.
  /// Throws ConfigError naming the scenario file and faults.stuck_joint when that joint is unknown
  /// (names: head.pan, head.tilt, arm.<DH joint name>).
  SimEnon(const robot::EnonModel& model, const Scenario& scenario);
  ~SimEnon() override;

  robot::ReturnType configure() override;
  robot::ReturnType activate() override;
  robot::ReturnType deactivate() override;
  robot::ReturnType read(Seconds time, Seconds period, robot::RobotState* state) override;
  robot::ReturnType write(Seconds time, Seconds period, const robot::RobotCommand& cmd,
                          Seconds valid_for_s) override;

  /// The stereo camera of this simulation; it must not outlive the SimEnon.
  std::unique_ptr<robot::StereoSource> makeCamera();

  // Ground truth (for tests, logs and evaluation).
  Seconds time() const { return time_; }
  robot::PlanarPose trueBasePose() const { return base_true_; }
  robot::PlanarPose odometryPose() const { return base_odom_; }
  Pose wMb() const { return base_true_.toPose(); }
  Pose wMc() const;  ///< true left camera pose
  Pose wMe() const;  ///< true gripper pose
  double pan() const { return pan_; }
  double tilt() const { return tilt_; }
  const Eigen::VectorXd& q() const { return q_; }
  const World& world() const { return world_; }
  /// Index of the held object in world().objects, -1 when none.
  int heldObject() const { return held_; }
  robot::GripperPhase gripperPhase() const { return gripper_; }
  /// Whether frame `index` (captured at index / frame_rate_hz) is dropped by the fault model.
  bool frameDropped(long index) const;
  /// Ground truth of the last frame the camera delivered (poses of every world object in both
  /// eyes at its capture time); nullptr before the first frame.
  const SyntheticFrame* lastFrame() const { return last_frame_ ? &*last_frame_ : nullptr; }
  /// Teleports the arm (tests and scripted set-ups only; clamped to the limits).
  void setJointPositions(const Eigen::VectorXd& q);

 private:
  friend class SimStereoCamera;
  struct Queued {
    Seconds due;
    robot::RobotCommand cmd;
    Seconds valid_for;
  };
  struct Snapshot {
    Seconds t;
    Pose wMl;
    double pan, tilt;
    std::vector<Pose> wMo;
  };

  void applyDue(Seconds now);
  void integrate(Seconds dt);
  void finishGripper(Seconds now);
  void pushSnapshot();
  bool stuck(const std::string& joint) const;
  /// Interpolated true camera / object poses at t (held at the ends of the history).
  Snapshot snapshotAt(Seconds t) const;

  robot::EnonModel model_;
  robot::ArmKinematics kin_;
  Scenario scenario_;
  World world_;
  bool configured_ = false, active_ = false;

  Seconds time_ = 0;
  robot::PlanarPose base_true_, base_odom_;
  double v_ = 0, w_ = 0;
  double pan_ = 0, tilt_ = 0, pan_rate_ = 0, tilt_rate_ = 0;
  Eigen::VectorXd q_, qdot_;
  robot::GripperPhase gripper_ = robot::GripperPhase::kOpen;
  Seconds gripper_done_ = 0;
  int held_ = -1;
  Pose eMo_held_;

  std::deque<Queued> queue_;
  robot::RobotCommand active_cmd_;
  Seconds active_until_ = 0;
  std::mt19937_64 odom_rng_;
  std::deque<Snapshot> history_;
  std::optional<SyntheticFrame> last_frame_;
};

/// A Robot on the simulated enon for a scenario already in memory (tests, demos). Its hardware()
/// is the SimEnon (ground truth through dynamic_cast<SimEnon&>).
std::unique_ptr<robot::Robot> makeSimRobot(const robot::EnonModel& model, const Scenario& scenario);

/// The stereo camera of a simulated enon that stands still (no command is ever sent), owning its
/// SimEnon: each grab() advances the simulation by one frame period (1 / head.frame_rate_hz) and
/// renders that frame, whatever `time` (an offline source that never ends; a frame dropped by the
/// scenario's faults gives kOk without a frame). Frames carry capture.head and the ground truth.
/// For recording synthetic sequences (the record tool) and tests.
std::unique_ptr<robot::StereoSource> makeStandaloneSimCamera(const robot::EnonModel& model,
                                                             const Scenario& scenario);

/// Registers backend "sim" (robot/backend.h). Settings: `scenario` (required), the scenario YAML.
/// Throws ConfigError naming config.source (or the model file) and `scenario` when it is missing.
void registerSimBackend();

}  // namespace refgrasp::sim
