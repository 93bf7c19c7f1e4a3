#pragma once
// Hardware abstraction for the enon, modelled on ros2_control (lifecycle configure / activate /
// deactivate; read(time, period) then write(time, period) once per cycle; a status, never an
// exception, inside the loop) and on ViSP's vpRobot::setVelocity(frame, twist).
//
// Layers:
//   RobotHardware, StereoSource (robot/camera.h)  device backends, one folder each under
//                                        src/robot/<backend>/: sim/ (the simulated enon), dds/
//                                        (a robot driver on the DDS bus, e.g. the real enon's),
//                                        dc1394/ (the Bumblebee2), files/ (recordings, images,
//                                        videos, webcams: frame sources only)
//   Robot                                the aggregate a controller uses: Base, Head, Arm, Gripper,
//                                        StereoCamera views, limits, arm DLS, the watchdog, stop().
// Backends are built by name through robot/backend.h; nothing here knows any backend type.
// Every error path commands zero velocity. Frames and units: robot/enon_model.h.
#include <Eigen/Core>
#include <deque>
#include <memory>
#include <optional>
#include <string>

#include "core/camera.h"
#include "core/pose.h"
#include "core/types.h"
#include "robot/camera.h"
#include "robot/enon_model.h"
#include "robot/kinematics.h"
#include "robot/status.h"
#include "robot/watchdog.h"

namespace refgrasp::robot {

enum class HeadMode { kVelocity, kPosition };
enum class GripperCommand { kNone, kOpen, kClose };
enum class GripperPhase { kOpen, kClosing, kClosedEmpty, kHolding, kOpening };
const char* toString(GripperPhase p);

/// What is sent to the hardware each cycle (already limited by the Robot layer).
struct RobotCommand {
  double base_v_mps = 0, base_w_radps = 0;
  HeadMode head_mode = HeadMode::kVelocity;
  double pan = 0, tilt = 0;         ///< rad/s in velocity mode, rad in position mode
  Eigen::VectorXd arm_qdot_radps;   ///< one per arm joint
  GripperCommand gripper = GripperCommand::kNone;

  /// Zero velocity everywhere (gripper left as it is).
  static RobotCommand zero(int arm_dof);
  bool isFinite() const;
};

/// Everything read back in one cycle; one flat record so a run can be logged and replayed.
struct RobotState {
  Seconds stamp = 0;
  Pose wMb_odom;                    ///< base pose from odometry (carries odometry noise)
  double base_v_mps = 0, base_w_radps = 0;
  double pan_rad = 0, tilt_rad = 0, pan_radps = 0, tilt_radps = 0;
  Eigen::VectorXd arm_q_rad, arm_qdot_radps;
  GripperPhase gripper = GripperPhase::kOpen;
  std::string held_object;          ///< name of the held object, "" when none
  bool watchdog_tripped = false;

  static std::string csvHeader(int arm_dof);
  std::string csvRow() const;
};

/// Device backend of base, head, arm and gripper.
class RobotHardware {
 public:
  virtual ~RobotHardware() = default;
  virtual ReturnType configure() = 0;
  virtual ReturnType activate() = 0;
  virtual ReturnType deactivate() = 0;
  /// \param time current time; \param period time since the previous read.
  /// Fills `state` with the joint / odometry state at `time`.
  virtual ReturnType read(Seconds time, Seconds period, RobotState* state) = 0;
  /// Sends `cmd`, valid from `time` (plus any device latency) for at most `valid_for_s`
  /// (the watchdog period): a device never keeps moving on a stale command.
  virtual ReturnType write(Seconds time, Seconds period, const RobotCommand& cmd,
                           Seconds valid_for_s) = 0;
  /// One line saying why the last read() or write() returned kError ("" when the backend does not
  /// say), e.g. the simulated enon's "collision at t=3.21 s: forearm with table (4.0 mm)".
  virtual std::string lastError() const { return {}; }
};

/// Frame of an arm velocity command (vpRobot::setVelocity idiom). Reference point: e's origin.
enum class ArmFrame {
  kBase,        ///< bVe: linear and angular velocity expressed in the base frame
  kEndEffector  ///< eVe: expressed in the gripper frame
};

class Robot;

/// \brief Differential-drive base. Odometry pose wMb in the world frame.
class Base {
 public:
  /// \param v_mps forward speed; \param w_radps turn rate (counter-clockwise seen from above).
  /// Clipped to the base limits (robot/kinematics.h clipBaseVelocity).
  void setVelocity(double v_mps, double w_radps);
  Pose wMb() const;  ///< odometry
  const BaseModel& model() const;

 private:
  friend class Robot;
  explicit Base(Robot* r) : r_(r) {}
  Robot* r_;
};

/// \brief Pan-tilt head carrying the stereo camera.
class Head {
 public:
  /// \param pan_radps, tilt_radps joint rates, clipped to the speed limits.
  void setVelocity(double pan_radps, double tilt_radps);
  /// \param pan_rad, tilt_rad targets (clipped to the limits), reached at top speed.
  void setPosition(double pan_rad, double tilt_rad);
  double pan() const;
  double tilt() const;
  /// bMc: left camera optical frame in the base frame at the current joint state.
  Pose bMc() const;
  const HeadModel& model() const;

 private:
  friend class Robot;
  explicit Head(Robot* r) : r_(r) {}
  Robot* r_;
};

/// \brief Serial arm (DH chain). Cartesian commands go through damped least squares at write().
class Arm {
 public:
  /// \param frame frame the twist is expressed in; \param v gripper-frame velocity (m/s, rad/s).
  void setVelocity(ArmFrame frame, const Twist& v);
  /// \param qdot_radps one rate per joint.
  void setJointVelocity(const Eigen::VectorXd& qdot_radps);
  const Eigen::VectorXd& q() const;
  Pose bMe() const;  ///< gripper frame in the base frame at the current joint state
  const ArmKinematics& kinematics() const;

 private:
  friend class Robot;
  explicit Arm(Robot* r) : r_(r) {}
  Robot* r_;
};

/// \brief One-DOF gripper.
class Gripper {
 public:
  void open();
  void close();
  GripperPhase phase() const;
  bool holding() const { return phase() == GripperPhase::kHolding; }

 private:
  friend class Robot;
  explicit Gripper(Robot* r) : r_(r) {}
  Robot* r_;
};

/// \brief The stereo camera on the head.
class StereoCamera {
 public:
  const StereoRig& rig() const;
  /// Head-to-camera transform from config: left optical frame in the tilt frame.
  const Pose& tMc() const;
  /// bMc: left camera in the base frame at the current head joint state.
  Pose bMc() const;
  /// See StereoCameraHardware::grab; an error stops the robot.
  ReturnType grab(Seconds time, std::optional<StereoFrame>* frame);

 private:
  friend class Robot;
  explicit StereoCamera(Robot* r) : r_(r) {}
  Robot* r_;
};

/// The aggregate a controller drives. Per cycle: read(t, dt); compute; set commands; write(t, dt).
/// Commands are latched until write(). The watchdog: when no command was set for longer than
/// model.watchdog_period_s, write() and read() send zero velocity to every actuator.
class Robot {
 public:
  Robot(const EnonModel& model, std::unique_ptr<RobotHardware> hardware,
        std::unique_ptr<StereoSource> camera);
  ~Robot();
  Robot(const Robot&) = delete;
  Robot& operator=(const Robot&) = delete;

  /// Another camera for this robot (e.g. a local Bumblebee2 beside a robot driven over DDS):
  /// only before configure(). Throws std::logic_error after it, std::invalid_argument for null.
  /// The new camera's stamps must be on the clock of read()'s time (robot/sources.h onCallerClock).
  void replaceCamera(std::unique_ptr<StereoSource> camera);

  ReturnType configure();
  ReturnType activate();
  ReturnType deactivate();  ///< stops the robot first
  Lifecycle lifecycle() const { return lifecycle_; }

  ReturnType read(Seconds time, Seconds period);
  ReturnType write(Seconds time, Seconds period);
  /// Zero velocity everywhere, sent to the hardware now and latched as the command.
  void stop();

  const RobotState& state() const { return state_; }
  const RobotCommand& lastCommand() const { return sent_; }
  const EnonModel& model() const { return model_; }
  Base& base() { return base_; }
  Head& head() { return head_; }
  Arm& arm() { return arm_; }
  Gripper& gripper() { return gripper_; }
  StereoCamera& camera() { return camera_; }
  RobotHardware& hardware() { return *hw_; }

 private:
  friend class Base;
  friend class Head;
  friend class Arm;
  friend class Gripper;
  friend class StereoCamera;
  void commanded() { fresh_ = true; }
  /// Robot state at `t` from history_ (linear interpolation, held at the ends).
  CaptureState captureAt(Seconds t) const;

  EnonModel model_;
  ArmKinematics kin_;
  std::unique_ptr<RobotHardware> hw_;
  std::unique_ptr<StereoSource> cam_;
  Lifecycle lifecycle_ = Lifecycle::kUnconfigured;
  Watchdog watchdog_;
  RobotCommand pending_, sent_;
  std::optional<std::pair<ArmFrame, Twist>> arm_twist_;  ///< Cartesian arm command, if any
  RobotState state_;
  struct Sample {
    Seconds t;
    Pose wMb_odom;
    double pan, tilt;
  };
  std::deque<Sample> history_;  ///< states read in the last two seconds, oldest first
  Seconds last_time_ = 0, last_period_ = 0;
  bool fresh_ = false;
  Base base_{this};
  Head head_{this};
  Arm arm_{this};
  Gripper gripper_{this};
  StereoCamera camera_{this};
};

}  // namespace refgrasp::robot
