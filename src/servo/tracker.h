#pragma once
// Frame-to-frame tracking of one object with a pose after a detection.
//
// FrameTracker is the seam: the per-frame pipeline (servo/target_tracker.h) starts a tracker on
// the frame of a detection at the detected pose and asks it for the pose in each next frame.
// makePlanarTracker() builds the project's trackers on a detector::ObjectModel with a pose: a
// planar pattern, a label on a cylinder, or an object of several views (its textured surfaces in
// the object frame: servo/surface_model.h):
//
//   kKlt  KLT features (OpenCV's pyramidal Lucas-Kanade, as ViSP's vpKltOpencv) inside the
//         projected textured surfaces that face the camera, each anchored to the point of the
//         surface its pixel's ray meets first (object frame: on the pattern plane, on the can's
//         label, on the box face it lies on);
//         per frame: features moved from the predicted pose (initial flow), pose by robust
//         (Huber) Levenberg-Marquardt on all the 2D-3D pairs, features beyond
//         inlier_threshold_px dropped; for a planar object with a PoseAligner (the detector's
//         Detector::alignPose), the pose is then aligned photometrically with the object's
//         reference image and the features re-anchored on it, so that the pose does not drift
//         (cylinders and several-view objects: features alone); features are re-seeded in the
//         visible textured region when too few are left (on a box, the face that came into view).
//   kMbt  ViSP's vpMbGenericTracker (KLT, optionally + moving edges on the pattern outline) on a
//         one-face model built from the pattern polygon, initialised with initFromPose; planar
//         objects only (a cylinder or several views: std::invalid_argument at start-up).
//
// Quality per frame: surviving features and their RMS projection error, the fraction of the
// textured surfaces facing the camera projected inside the image and, with the aligner, the
// fraction of the reference it found in view and unoccluded (robust ECC: occluded blocks left
// out). The tracker reports "lost" when one of them falls past its threshold (TrackerOptions),
// when the aligner refuses max_unaligned_frames frames in a row (features that slid onto an
// occluder's edge can agree on a wrong pose; the reference does not), or the pose is not
// finite/in front of the camera.
//
// Frames and units: cMo = object frame in the camera frame of the image tracked (metres,
// radians); images 8-bit gray of the camera's size; pixels with the centre of the top-left pixel
// at (0, 0). Deterministic: the same frames give the same poses.
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "core/camera.h"
#include "core/pose.h"
#include "detector/detector.h"
#include "detector/object.h"

namespace refgrasp::servo {

/// Quality of one tracking step (or of a start).
struct TrackQuality {
  int features = 0;                ///< features that survived this step (pose inliers)
  int features_started = 0;        ///< features at the last (re)seeding
  double projection_error_px = 0;  ///< RMS reprojection error of the surviving features (px)
  double visible_fraction = 0;     ///< fraction of the pattern's area projected inside the image
  bool aligned = false;            ///< the pose was aligned with the reference this step
  double correlation = 0;          ///< the alignment's ECC correlation coefficient (when tried)
  /// Fraction of the reference the alignment used (the rest off the image or occluded).
  double aligned_fraction = 0;
};

/// The outcome of start() or track().
struct TrackStep {
  bool ok = false;           ///< false: the target is lost (or could not be started)
  Pose cMo;                  ///< ok: object frame in the camera frame of this image (m, rad)
  TrackQuality quality;
  std::string lost_reason;   ///< !ok: one line, e.g. "too few features (5 < 12)"
};

/// Frame-to-frame tracking of one object. Gray CV_8UC1 frames of the camera's size.
class FrameTracker {
 public:
  virtual ~FrameTracker() = default;
  /// Starts on the frame a detection was made in, at the detected pose. ok = false when it
  /// cannot track from there (e.g. too few features on the visible pattern). Never throws.
  virtual TrackStep start(const cv::Mat& gray, const Intrinsics& camera, const Pose& cMo) = 0;
  /// The pose in the next frame. predicted_cMo: the pose expected in this frame (e.g. the last
  /// one moved by the camera motion between the captures); empty: the tracker's own
  /// prediction. ok = false: lost; the tracker stays stopped until the next start(). Never throws.
  virtual TrackStep track(const cv::Mat& gray, const Intrinsics& camera,
                          const std::optional<Pose>& predicted_cMo = std::nullopt) = 0;
};

/// A tracker for an object (objects with a pose only).
using TrackerFactory =
    std::function<std::unique_ptr<FrameTracker>(const detector::ObjectModel& object)>;

enum class TrackerMethod {
  kKlt,  ///< KLT features anchored on the object's surfaces + robust pose (default)
  kMbt,  ///< vpMbGenericTracker on the pattern polygon (KLT, + edges with mbt_edges); planar only
};
const char* trackerMethodName(TrackerMethod m);  ///< "klt", "mbt"

struct TrackerOptions {
  TrackerMethod method = TrackerMethod::kKlt;
  // Losing the target.
  int min_features = 12;                ///< lost below this many surviving features
  double min_feature_fraction = 0.2;    ///< lost when fewer than this x features_started survive
  double max_projection_error_px = 2.0; ///< lost when the RMS error of the survivors is larger
  double min_visible_fraction = 0.2;    ///< lost when less of the textured surface facing the camera
                                        ///< projects in the image
  // KLT features.
  int max_features = 200;               ///< seeded in the projected pattern
  /// Features are seeded only where a surface faces the camera by more than this (cos of the
  /// angle between its outward normal and the ray to the camera; 0.26: within 75 deg): a texture
  /// seen at grazing angles is compressed into a few pixels and its features slide.
  double seed_min_facing_cos = 0.26;
  double feature_quality = 0.01;        ///< goodFeaturesToTrack quality level
  /// Spacing of seeded features; where that leaves fewer than min_features (a small target),
  /// they are seeded 3 px apart.
  double feature_min_distance_px = 8;
  int klt_window_px = 15;               ///< odd, >= 5
  /// 0..6. Few: the features start at the predicted positions, and at coarse levels a window
  /// on a small target is dominated by a background that moves differently.
  int klt_pyramid_levels = 2;
  /// When fewer than half the features fit the pose, KLT again with this many levels (a sudden
  /// change of motion the prediction missed); <= klt_pyramid_levels: never.
  int klt_retry_pyramid_levels = 4;
  /// ... and then from the shift the prediction missed: the previous frame's pattern region
  /// matched (normalised correlation, coarse pyramid level) within shift_search_px of where the
  /// prediction puts it; a best match below shift_min_score (0..1) is not used.
  bool shift_retry = true;
  double shift_search_px = 64;
  double shift_min_score = 0.5;
  double pattern_border_px = 6;         ///< features this far inside the projected outline only
  double inlier_threshold_px = 2.5;     ///< features with a larger residual are dropped
  /// Features whose KLT error (mean absolute gray difference of the window) exceeds
  /// max(this, 3 x the median feature's) are dropped: an occluder's edge dragged them.
  double klt_max_error = 8;
  /// Re-seed features in the visible pattern when fewer than this x max_features are left.
  double reseed_fraction = 0.5;
  int pose_iterations = 10;             ///< robust LM iterations per frame
  /// Without an aligner (KLT alone, a cylinder, several views): each feature is moved to where
  /// its appearance in the frame it was seeded in, warped to the pose through its tangent plane,
  /// correlates best within appearance_search_px of where KLT put it (correlation 0..1 at least
  /// appearance_min_score, else KLT's position stays), and the pose is solved again; KLT alone
  /// slides a little every frame and the pose drifts with it.
  bool appearance_match = true;
  double appearance_search_px = 3;
  double appearance_min_score = 0.7;
  bool mbt_edges = false;               ///< kMbt: add moving edges on the pattern outline
  bool align_to_reference = true;       ///< kKlt: align each pose with the reference (if given)
  /// The alignment is refused when a pattern corner moves more (corners out of the view move
  /// far for a small rotation of a partly visible pattern) or the correlation ends lower.
  double align_max_corner_shift_px = 20;
  double align_min_correlation = 0.8;
  /// 2D-only objects (servo/homography_tracker.h): the alignment's template is at most this many
  /// reference px (DenseRefineOptions::max_template_px; a coarser pyramid level until it fits).
  /// 65536 (256 x 256) where the detector caps it at 16384: a 400 px reference seen 180-250 px
  /// wide is then aligned one level finer, and the tracked corners are 2-6 times closer to the
  /// truth (90th percentile 0.04 px instead of 0.25 px on the drift test) for about 7 ms more a
  /// frame.
  int align_max_template_px = 65536;
  /// ... or when the surviving features' RMS reprojection error under the aligned pose is larger.
  double align_max_feature_rms_px = 1.0;
  /// With an aligner: lost after this many frames in a row that could not be aligned (features
  /// that slid onto an occluder's edge can agree on a wrong pose; the reference does not).
  int max_unaligned_frames = 1;
  /// Lost when the alignment used less of the reference (a partial view leaves the rotation
  /// poorly determined: at half the pattern hidden, several degrees).
  double min_aligned_fraction = 0.6;
  /// Throws std::invalid_argument "TrackerOptions.<field>: <problem>".
  void check() const;
};

/// Aligns a pose of one object with its reference image (Detector::alignPose bound to it).
using PoseAligner = std::function<detector::PoseAlignment(const cv::Mat& gray, const Intrinsics& camera,
                                                          const Pose& cMo)>;

/// The project's tracker for `object` (throws std::invalid_argument for a 2D-only object, kMbt on
/// a non-planar object, or bad options: start-up). align: see TrackerMethod::kKlt (nullptr: KLT
/// alone; not used for a cylinder or several views).
std::unique_ptr<FrameTracker> makePlanarTracker(const detector::ObjectModel& object,
                                                const TrackerOptions& options = {},
                                                PoseAligner align = nullptr);
/// A factory making makePlanarTracker(object, options, ...) (options checked here, once). With a
/// detector (which must outlive the trackers), objects registered in it are aligned through
/// Detector::alignPose.
TrackerFactory planarTrackerFactory(const TrackerOptions& options = {},
                                    const detector::Detector* detector = nullptr);

/// SurfaceModel::visibleFraction of the object's textured surfaces at cMo (0 for a 2D-only object).
double visibleFraction(const detector::ObjectModel& object, const Pose& cMo, const Intrinsics& camera);

}  // namespace refgrasp::servo
