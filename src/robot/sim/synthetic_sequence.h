#pragma once
// Rendered camera sequences with ground truth for tracking tests and benchmarks: a planar target
// fixed in the world in front of a textured wall, seen by a camera that moves around it (distance,
// viewing angle, roll, off-centre framing), with motion blur along each frame's image motion and
// fresh sensor noise per frame. Frames carry the ground truth (ObjectTruth "target") and, when
// asked, the camera pose at capture (CaptureState::bMc with the base fixed at the world origin).
// Deterministic given the spec.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"
#include "robot/camera.h"
#include "robot/sim/render.h"

namespace refgrasp::testing {

/// Camera placement relative to the target at one instant (object frame: the target's centre,
/// x along its texture columns, y along its rows, z into the plane; the camera on the -z side).
struct ViewPoint {
  double distance_m = 1.0;   ///< camera centre to the target centre
  double tilt_rad = 0;       ///< angle between the plane normal and the ray to the camera
  double tilt_dir_rad = 0;   ///< direction of the tilt about the normal (0: towards +x)
  double roll_rad = 0;       ///< camera roll about its optical axis
  double look_x_m = 0, look_y_m = 0;  ///< point looked at on the plane (off-centre framing)
};

struct TrackingSequenceSpec {
  int frames = 90;
  int render_frames = -1;  ///< render only the first N of the frames (-1: all; tests save time)
  double fps = 30;
  std::string texture = "targets/cereal_box.png";  ///< media path (testing::loadMedia)
  double width_m = 0.25;                            ///< height from the texture's aspect
  std::string wall = "clutter/clutter_05.png";     ///< media texture of the wall behind
  double wall_behind_m = 0.8;                       ///< wall plane this far behind the target
  /// The camera's placement over time, t in [0, 1] (first frame 0, last frame 1).
  std::function<ViewPoint(double t)> path;
  /// Panels fixed in the world between the camera and the target (each plane's cMp holds its
  /// pose in the object frame, oMp), e.g. an occluder the target passes behind.
  std::vector<sim::TexturedPlane> occluders;
  /// Whether the target is in frame k (empty: always); without it only the wall and occluders.
  std::function<bool(int frame)> target_shown;
  double noise_sigma = 2.0;         ///< gray levels, new in every frame
  double exposure_fraction = 0.3;   ///< motion blur = this x the target centre's image motion
  bool capture_state = false;       ///< fill CaptureState::bMc (camera in the world/base frame)
  /// The camera of both eyes; empty: sceneCamera() (640x480, f 550 px).
  std::optional<Intrinsics> camera;
  uint64_t seed = 1;
};

/// The default path: distance 1.8 -> 0.4 -> 1.8 m, tilt swinging up to 50 deg, roll +-20 deg,
/// the target drifting off-centre.
ViewPoint orbitPath(double t);

/// A slow hand-held-like path, `cycles` periods over t in [0, 1]: distance 0.55-0.95 m, tilt to
/// 20 deg in a turning direction, roll +-14 deg, the target a few cm off-centre.
ViewPoint swayPath(double t, double cycles);

/// Camera in the object frame for a view point (oMc: camera frame in the object frame).
Pose viewPointPose(const ViewPoint& v);
/// A camera at (x_m, y_m, -distance_m) in the object frame looking along +z (a sideways move).
ViewPoint sidewaysView(double x_m, double y_m, double distance_m);

struct TrackingSequence {
  Intrinsics camera;          ///< sceneCamera() (both eyes with a rig)
  StereoRig rig;              ///< right eye 0.12 m to the right of the left one
  std::vector<robot::MonoFrame> mono;      ///< left eye (mono sequences)
  std::vector<robot::StereoFrame> stereo;  ///< with renderTrackingSequence(.., stereo = true)
  std::vector<Pose> truth;    ///< cMo per frame (left eye)
  std::vector<double> visible;  ///< fraction of the target's area in the image and not occluded
};

/// Renders the sequence (mono, or stereo with both eyes).
TrackingSequence renderTrackingSequence(const TrackingSequenceSpec& spec, bool stereo = false);

}  // namespace refgrasp::testing
