#pragma once
// The vision pipeline after detection, per frame, for one or several objects, mono or stereo:
// the one the robot's controller, pose_replay and `vision_component --track` all run.
//
//   detect   whole-frame detection while nothing is tracked (every frame with track = false);
//   confirm  a detection is CONFIRMED once `confirm_detections` consecutive detections agree
//            within the tolerances: each new detection is compared with the previous one moved
//            to this frame (by the tracker when it runs, else by the camera motion between the
//            captures when the frames carry bMc (and wMb_odom), else as is, in the camera
//            frame). While a target is unconfirmed, every frame is detected again (in its
//            predicted region). An unconfirmed target must never move the robot.
//   track    between detections a FrameTracker (servo/tracker.h) follows each target from the
//            previous frame, starting from the pose predicted by the camera motion when known
//            (else the tracker's own prediction); an object without metric geometry (2D-only:
//            no cMo) is followed by its homography (servo/homography_tracker.h, left or only
//            eye), predicted by the last frame-to-frame change of H, and agreement is measured
//            on its corners (confirm_max_corner_fraction);
//   re-detect when the tracker loses the target (quality degrades, it leaves the view, an
//            occluder), the same frame is detected first in the predicted region and scale
//            (detector::ObjectPrior) and then, if that fails, in the whole frame; for
//            `prior_frames` frames after a loss the prior is tried first;
//   lost     nothing found: no pose.
// Stereo: detection in both eyes (fused in the left camera frame, as Detector::detectStereo),
// tracking in both eyes (one tracker per eye, fused the same way when both track).
//
// Frames and units: cMo = object frame in the (LEFT, for stereo) camera frame AT CAPTURE of the
// frame processed (metres, radians); the frame's CaptureState is returned with it so that a
// controller can move it to the camera pose at use (transportPose). Deterministic: the same
// frames and options give the same results, bit for bit (time_ms aside). process() never
// throws: a frame the detector rejects gives ok = false, a one-line error, every target lost.
#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"
#include "core/types.h"
#include "detector/detector.h"
#include "robot/camera.h"
#include "servo/tracker.h"

namespace refgrasp::servo {

enum class TrackMode { kDetect, kTrack, kLost };
const char* toString(TrackMode m);  ///< "detect", "track", "lost"

/// The detection run for a target in a frame.
enum class SearchScope { kNone, kPrior, kWholeFrame };
const char* toString(SearchScope s);  ///< "none", "prior", "whole"

struct TargetTrackerOptions {
  bool track = true;  ///< false: detection on every frame (pose_replay --no-track)
  /// Consecutive agreeing detections that confirm a target (1: every detection is confirmed).
  int confirm_detections = 2;
  double confirm_max_translation_fraction = 0.05;  ///< agreement: position difference / distance
  double confirm_max_rotation_rad = 0.2;           ///< agreement: rotation difference
  /// Agreement of a 2D-only object's homographies: largest pattern corner difference / the
  /// pattern's diagonal in the image (0.05: as the position's 5 % of the distance, for a
  /// pattern seen square-on).
  double confirm_max_corner_fraction = 0.05;
  /// An unconfirmed target is dropped after this many frames without confirmation.
  int confirm_max_frames = 6;
  /// Frames after a loss during which the predicted region is searched before the whole frame.
  int prior_frames = 4;
  double prior_roi_margin = 0.5;    ///< detector::ObjectPrior::roi_margin of a re-detection
  double prior_scale_margin = 2.0;  ///< detector::ObjectPrior::scale_margin of a re-detection
  /// detector::ObjectPrior::max_scale of a re-detection (scene px per reference px): a predicted
  /// pattern larger than that is extracted downsampled, so a large frame costs about what a small
  /// one does (0.4: results.md "Detection with a prior region at 1280x720"). 0 (default): never
  /// downsampled, since a reference no sharper than the scene keeps too few features when
  /// downsampled (same page).
  double prior_max_scale = 0;
  /// > 0: a tracked target is also detected in its predicted region every N frames and, when the
  /// detection agrees, the tracker restarts from it (bounds drift). A confirmed track that a
  /// detection disagrees with goes on, the next frames are detected too, and confirm_detections
  /// + 1 of them in a row that agree with each other replace it. 0: never.
  int redetect_every_frames = 0;
  /// Without camera motion in the frames: predict the next pose by the last frame-to-frame motion.
  bool constant_velocity = true;
  TrackerOptions tracker;  ///< for the default trackers (planarTrackerFactory, the homography tracker)
  /// Throws std::invalid_argument "TargetTrackerOptions.<field>: <problem>".
  void check() const;
};

/// One object in one frame.
struct TargetState {
  int object = -1;  ///< detector object id
  std::string name;
  TrackMode mode = TrackMode::kLost;
  /// Confirmed by consecutive agreeing detections and followed since. Only a confirmed target
  /// may move the robot.
  bool confirmed = false;
  int agreeing_detections = 0;  ///< consecutive agreeing detections so far
  std::optional<Pose> cMo;      ///< detect/track: object in the (left) camera frame at capture
  /// Pattern corners TL, TR, BR, BL in the (left) image: detected, projected from cMo, or (a
  /// tracked 2D-only object) under the tracked homography.
  std::optional<std::array<Eigen::Vector2d, 4>> corners;
  /// mode track, a 2D-only object: the tracked homography (undistorted reference px ->
  /// undistorted image px, as detector::Detection::H); detect: see `detection`.
  std::optional<Eigen::Matrix3d> H;
  /// mode detect: the detection (best instance; the left eye's for stereo, found = false when
  /// only the right eye found it). Otherwise found = false.
  detector::Detection detection;
  /// Eyes that measured the pose this frame (detect or track); mono: kLeft when found.
  detector::EyesUsed eyes = detector::EyesUsed::kNone;
  TrackQuality quality;        ///< mode track: the (left or only) tracking eye's numbers
  TrackQuality quality_right;  ///< stereo, mode track: the right eye's
  SearchScope searched = SearchScope::kNone;  ///< the detection run for it this frame
  /// When the detector ran for it this frame: what it saw in the left (or only) eye (features,
  /// matches, candidates, the furthest stage a hypothesis reached and why it stopped there), and
  /// the instance it reported there, even one the pipeline then overruled or did not confirm.
  std::optional<detector::ObjectStats> detector_stats;
  std::optional<detector::Detection> detector_best;
  std::string lost_reason;  ///< the tracker's, on the frame it lost the target
};

struct TargetFrame {
  FrameStamp stamp;             ///< capture time and device counter
  robot::CaptureState capture;  ///< camera state at capture (as the frame carried it)
  bool ok = true;
  std::string error;            ///< one line when the frame could not be processed
  std::vector<TargetState> objects;  ///< one per detector object, id order
  int detector_calls = 0;       ///< detector runs this frame (0 when every target was tracked)
  double time_ms = 0;           ///< processing time: NOT deterministic
  const TargetState* find(int object) const;
};

class TargetTracker {
 public:
  /// \param detector with every object registered; it must outlive the tracker.
  /// \param trackers makes the FrameTracker of an object (nullptr: planarTrackerFactory of
  /// options.tracker, aligned through this detector). Throws std::invalid_argument for bad
  /// options (start-up).
  TargetTracker(const detector::Detector& detector, const TargetTrackerOptions& options = {},
                TrackerFactory trackers = nullptr);
  ~TargetTracker();
  TargetTracker(TargetTracker&&) noexcept;
  TargetTracker& operator=(TargetTracker&&) noexcept;

  /// Processes the next frame (frames in capture order). Never throws.
  TargetFrame process(const robot::MonoFrame& frame, const Intrinsics& camera);
  TargetFrame process(const robot::StereoFrame& frame, const StereoRig& rig);
  /// A frame that could not be delivered or used: ok = false, every target lost and its tracker
  /// stopped (the next frame is detected in the whole frame).
  TargetFrame failed(const FrameStamp& stamp, const std::string& error);
  /// Forgets every target (trackers stopped, confirmations cleared).
  void reset();

  /// Whether frames are tracked between detections (options.track and at least one object).
  bool tracking() const;
  const TargetTrackerOptions& options() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> p_;
};

/// The pose of a static object, known at capture `from`, in the camera at `to`:
/// c2Mo = (wMb2 bMc2)^-1 (wMb1 bMc1) c1Mo. Without odometry in both states the base is taken as
/// fixed (c2Mo = bMc2^-1 bMc1 c1Mo). Empty when either state lacks bMc.
std::optional<Pose> transportPose(const Pose& c1Mo, const robot::CaptureState& from,
                                  const robot::CaptureState& to);

/// The pattern corners (TL, TR, BR, BL) of an object with a pose projected with cMo into
/// `camera`: a planar object's, a cylinder's flat label on its tangent plane, or the view a
/// several-view object shows most squarely (servo/surface_model.h facingQuad). Empty for a
/// 2D-only object.
std::optional<std::array<Eigen::Vector2d, 4>> projectPattern(const detector::ObjectModel& object,
                                                             const Pose& cMo, const Intrinsics& camera);

}  // namespace refgrasp::servo
