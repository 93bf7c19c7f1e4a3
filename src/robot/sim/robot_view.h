#pragma once
// The simulated robot seen from outside: its parts as Lambert-shaded solids in a distinct colour
// each, drawn with the world by an external camera that follows the robot. The robot's own head
// camera never draws them (its frames are those of renderWorld, robot/sim/synthetic_camera.h).
//
// Frames: w the world (z up, metres); camera frames are optical (x right, y down, z forward);
// wMc is a camera's pose in the world. Images are BGR (CV_8UC3); the world, rendered in gray,
// is converted.
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"
#include "core/types.h"
#include "robot/enon_model.h"
#include "robot/kinematics.h"
#include "robot/sim/render.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"

namespace refgrasp::sim {

/// A solid of the robot in the world frame: the points within radius_m of the segment a-b
/// (a capsule), or with flat_ends the cylinder of that radius between the discs at a and b.
struct RobotPart {
  std::string name;
  Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();
  double radius_m = 0;
  bool flat_ends = false;
  cv::Vec3b bgr;  ///< colour of a surface lit head-on
};

/// The robot's parts now, from its collision shapes (SimEnon::shapes(): upper arm, forearm, palm,
/// fingers as capsules, the base body as a cylinder) plus the head: a capsule joining the two
/// cameras' centres (wMc: the left camera; the right one at wMc * rig.lMr) and a neck from the pan
/// frame up to the tilt axis. The base body is drawn up to the pan frame's height (where the
/// collision cylinder, taller, would hide the head). Names: "base", "neck", "head" and
/// Collision::link's names.
std::vector<RobotPart> robotParts(const robot::EnonModel& model, const RobotShapes& shapes,
                                  const Pose& wMb, const Pose& wMc);

/// The colour of a part by name (distinct per part; gray for an unknown name).
cv::Vec3b partColour(const std::string& name);

/// Lambert shading: bgr * (ambient + (1 - ambient) max(0, n . light)), n the unit outward normal,
/// light the unit direction towards the light, both in the world frame.
cv::Vec3b lambert(const cv::Vec3b& bgr, const Eigen::Vector3d& n_w, const Eigen::Vector3d& light_w,
                  double ambient = 0.35);

/// Direction towards the light of the external view (world frame, unit) for a camera at wMc:
/// from above, behind and left of the camera, so the sides the camera sees are lit and the
/// parts' shapes read from their shading.
Eigen::Vector3d viewLight(const Pose& wMc);

/// Ray-casts `parts` into `bgr` (CV_8UC3, the ideal pinhole image of K) seen from wMc, with a
/// depth test against inv_depth (CV_32F, 1 / camera z per pixel, 0 = nothing; updated). A pixel
/// takes the shaded colour of the nearest part its centre's ray hits (no anti-aliasing).
void drawRobotParts(cv::Mat& bgr, cv::Mat& inv_depth, const Eigen::Matrix3d& K, const Pose& wMc,
                    const std::vector<RobotPart>& parts, const Eigen::Vector3d& light_w, double near_m = 0.01);

/// The world and the robot's parts (lit from viewLight(wMc)) seen by a camera without lens
/// distortion at wMc (BGR).
/// Throws std::invalid_argument for a camera with distortion.
cv::Mat renderExternalView(const Intrinsics& cam, const World& world, const Pose& wMc,
                           const std::vector<RobotPart>& parts, const RenderOptions& opt = {});

/// The optical frame at `eye` looking at `target` (world), its image x axis horizontal
/// (perpendicular to world z). Requires target - eye not vertical.
Pose lookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target);

struct FollowCameraOptions {
  double behind_m = 1.8;           ///< eye this far behind the base along its heading (m)
  /// ... and this far to its right (m): the enon's arm is on its right and reaches forward, so a
  /// view from behind and right shows it beside the body, not behind it.
  double right_m = 2.2;
  double above_m = 2.0;            ///< eye height above the floor (m)
  double look_ahead_m = 0.4;       ///< the point looked at: this far ahead of the base centre (m) ...
  double look_at_height_m = 0.8;   ///< ... at this height (m, about where the hand works)
  double smoothing_s = 0.8;        ///< time constant of the exponential smoothing of the base pose
  /// 640 x 480, f = 560 px (about 60 degrees across): the robot and the table beside it in view.
  Intrinsics camera = Intrinsics::pinhole(640, 480, 560, 319.5, 239.5);
  void check() const;
};

/// An external camera that follows the robot: the base pose (position and unwrapped heading) is
/// smoothed exponentially with time constant smoothing_s, the eye placed behind, right of and
/// above the smoothed pose, looking at the point ahead of and above the true base. The first
/// update snaps to the base.
class FollowCamera {
 public:
  explicit FollowCamera(const FollowCameraOptions& o = {});
  /// The camera pose wMc for the true base pose at time t (seconds, non-decreasing).
  Pose update(const robot::PlanarPose& base_w, Seconds t);
  const FollowCameraOptions& options() const { return opt_; }

 private:
  FollowCameraOptions opt_;
  bool started_ = false;
  Seconds last_t_ = 0;
  Eigen::Vector2d xy_ = Eigen::Vector2d::Zero();
  double theta_ = 0;
};

}  // namespace refgrasp::sim
