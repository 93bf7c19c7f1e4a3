#pragma once
// The simulated enon: a shipped backend of the HAL (robot/hal.h), not test code.
//
// read(time) integrates the commands in force from the previous read up to `time` in closed form:
// unicycle arcs for the base, constant-rate joint motion stopped at the limits for head and arm,
// the head moving at top speed in position mode. A command sent by write(t) applies from
// t + faults.command_latency_s for at most the watchdog period (valid_for_s), then zero velocity.
// Faults per scenario: command latency, frame drops, frame delay, odometry noise (std of the error
// grows with the square root of the distance / angle travelled), a stuck joint. Same seed and same
// calls: same trajectory and bit-identical images.
//
// Collisions (geometry: robot/enon_model.h, robot/sim/collision.h). Checked: the capsules of the
// upper arm, forearm, palm and both fingers against every solid of the world (every scenario
// object, the target included, the table, the walls, the floor); the base body (vertical
// cylinder) against the table, the scenario objects and the walls. Not checked: the arm against
// the robot's own body and head, the base against the floor it stands on, anything against the
// held object (it moves with the hand and is not checked against the world either), and the
// fingers against the object they close on (from the close command until the gripper is fully
// open again: the item whose grasp frame is nearest the gripper frame e, within open_width_m,
// when the close command takes effect). The solids are boxes and cylinders (scenario shape:
// cylinder). Distances are exact (capsule-box and capsule-cylinder by a bracketed convex 1-D
// minimisation, base-box in closed form for boxes with a vertical axis, base-cylinder for upright
// cylinders; for the base, a tilted solid gives a lower bound of its distance). They are checked
// at the start (activate(), setJointPositions()) and along every integration step at sub-steps
// over which no point of the robot moves more than 2 mm (bounded from the base and joint speeds),
// so nothing tunnels and a reported depth is at most ~2 mm more than the first contact. A
// collision is an emergency stop, latched for the life of the SimEnon: the state stays where the
// contact was found, every actuator stops (the gripper too), write() ignores every command and
// returns kError, read() fills the state and returns kError, and lastError() says
// "collision at t=3.21 s: forearm with table (4.0 mm)" (the deepest contact). collisions() lists
// every contact found at that check. Camera frames keep coming.
//
// Grasping: the gripper closes in close_time_s (the fingers' gap shrinks linearly from
// open_width_m to 0; it opens in open_time_s). When it has closed it holds the item (not a
// fixture: table, floor, walls) whose grasp frame (wMo * oMg) is nearest the gripper frame e among
// those (1) within grasp_tolerance_m and grasp_tolerance_rad of e and (2) whose width along x_e
// (the closing direction: the extent of its solids, a cylinder's diameter when x_e crosses its
// axis) is at most open_width_m; the fingers then stop that width apart. Else it is closed
// on nothing (kClosedEmpty). A held object moves with the hand (wMo = wMe * eMo); opening releases
// it where it is (no gravity). An object heavier than gripper.max_payload_kg (SimObject::mass_kg,
// scenario field mass_kg) slips: as soon as the hand has moved its grasp frame more than 5 mm or
// 0.05 rad from where it was grasped, it drops back to where it was grasped and the gripper is
// closed on nothing (kClosedEmpty).
//
// Camera frames are rendered by SyntheticStereoCamera from the TRUE left camera pose
// wMc = wMb_true * bMc(pan, tilt) at the capture time (linear interpolation between reads);
// the odometry in RobotState carries the noise. Each frame's `truth` holds the true pose of every
// world object that has a detector definition, in both eyes. With setRenderImages(false) (backend
// setting `render: false`) frames come at the same rate with the same stamp, index, capture state
// and truth, and empty images (oracle runs and fast tests: rendering is most of a frame's cost).
//
// Ground truth accessors (wMe, graspError, jointLimitMargins, collisions, ...) are for tests, logs
// and evaluation, never for control.
#include <deque>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "robot/enon_model.h"
#include "robot/hal.h"
#include "robot/kinematics.h"
#include "robot/sim/collision.h"
#include "robot/sim/scenario.h"
#include "robot/sim/synthetic_camera.h"
#include "robot/backend.h"

namespace refgrasp::sim {

/// A contact that stopped the simulated enon.
struct Collision {
  Seconds time = 0;     ///< simulation time of the check that found it (s)
  std::string link;     ///< "upper_arm", "forearm", "palm", "finger_x+", "finger_x-" or "base"
  std::string object;   ///< world object: a scenario object's name, "table", "floor" or "walls"
  double depth_m = 0;   ///< penetration depth (m, > 0)
  /// "collision at t=3.21 s: forearm with table (4.0 mm)" (depth: 0 decimals from 10 mm, 2 below 1 mm)
  std::string message() const;
};

/// The gripper frame e against an object's grasp frame g (ground truth).
struct GraspError {
  double position_m = 0;    ///< |e origin - g origin| (the grasp rule's distance)
  double rotation_rad = 0;  ///< angle of the rotation between e and g (the grasp rule's angle)
  Pose eMg;                 ///< grasp frame in the gripper frame
};

/// The robot shape nearest the world (ground truth, for logs), among the pairs the collision
/// check considers; link and object as in Collision.
struct Proximity {
  std::string link, object;
  double distance_m = 1e300;  ///< signed distance (m): the gap, < 0 penetrating
};

/// The robot's collision shapes at one instant, in the world frame.
struct RobotShapes {
  std::vector<std::pair<std::string, Capsule>> capsules;  ///< link name, capsule (Collision::link)
  VerticalCylinder base;
};

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
  /// Why the last read() or write() failed: the collision, an inactive robot, a bad command.
  std::string lastError() const override;

  /// Frames with images (default) or without (empty left/right; stamps, capture state and truth
  /// as rendered ones). May change at any time.
  void setRenderImages(bool render) { render_images_ = render; }
  bool renderImages() const { return render_images_; }

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
  /// Teleports the arm (tests and scripted set-ups only; clamped to the limits). A pose in
  /// collision latches the collision.
  void setJointPositions(const Eigen::VectorXd& q);

  /// The contacts that stopped the robot, deepest first; empty while none happened.
  const std::vector<Collision>& collisions() const { return collisions_; }
  bool collided() const { return !collisions_.empty(); }
  /// Index in world().objects of the first scenario target, -1 when there is none.
  int targetObject() const;
  /// e against the grasp frame of world().objects[object]; nullopt for an unknown index.
  std::optional<GraspError> graspError(int object) const;
  /// Per arm joint, the distance to the nearer position limit (rad; 0 on a limit).
  Eigen::VectorXd jointLimitMargins() const;
  /// Clear gap between the fingers now (m): open_width_m open, 0 closed on nothing.
  double fingerGap() const { return fingerGapAt(time_); }
  /// The robot's collision shapes at the current state.
  RobotShapes shapes() const;
  /// The nearest pair now (exact; cheap enough for a log line every control period).
  Proximity nearest() const;

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

  // True kinematic state, what the collision check needs.
  struct Kinematic {
    robot::PlanarPose base;
    Eigen::VectorXd q;
    double gap;
  };

  void applyDue(Seconds now);
  void integrate(Seconds dt);
  /// The true kinematic state after s more seconds of the command in force.
  Kinematic kinematicAfter(Seconds s) const;
  RobotShapes shapesOf(const Kinematic& k) const;
  /// Calls f(link, object, signed distance) for every pair the collision check considers, except
  /// pairs the broad phase proves to be at least `below` apart.
  template <class F>
  void visitPairs(const RobotShapes& shapes, const double& below, F&& f) const;
  /// Every contact of the robot in state k at time t, deepest first.
  std::vector<Collision> contacts(const Kinematic& k, Seconds t) const;
  /// Latches the contacts of the current state, if any (start-up and teleports).
  void checkNow();
  void latch(std::vector<Collision> found);
  /// Upper bound of the displacement of any point of the robot's shapes over s seconds.
  double motionBound(Seconds s) const;
  double fingerGapAt(Seconds t) const;
  void moveFingers(Seconds start, double to_gap, Seconds duration);
  /// Width of the item along the unit direction u (extent of its solids).
  double widthAlong(const SimObject& o, const Eigen::Vector3d& u) const;
  void slipIfTooHeavy();
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
  Pose wMg_grasped_;        ///< grasp frame of the held object when it was grasped
  Pose wMo_grasped_;        ///< ... and the object
  int finger_exempt_ = -1;    ///< the item the fingers close on (not checked against the fingers)
  int stuck_arm_joint_ = -1;  ///< index of faults.stuck_joint among the arm joints, -1 if none
  double gap_from_ = 0, gap_to_ = 0;  ///< finger gap moves linearly between these ...
  Seconds gap_t0_ = 0, gap_t1_ = 0;   ///< ... over this time interval
  double arm_lever_m_ = 0;  ///< bound of the distance from any arm joint axis to any point beyond it
  std::vector<Collision> collisions_;
  std::string last_error_;
  bool render_images_ = true;

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

/// Registers backend "sim" (robot/backend.h). Settings: `scenario` (required), the scenario YAML;
/// `render` (optional, "true" or "false", default true): camera frames with or without images
/// (SimEnon::setRenderImages). Throws ConfigError naming config.source (or the model file) and
/// the setting when `scenario` is missing or `render` is neither true nor false.
void registerSimBackend();

}  // namespace refgrasp::sim
