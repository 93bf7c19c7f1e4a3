#pragma once
// The detector facade: the small stable API a tracker, a replay tool or a DDS node calls.
//
//   Detector det(loadDetectorOptions("config/detector.yaml"));   // detector_config.h, or {}
//   int id = det.addObject(loadObjectDefinition("config/objects/poster.yaml"));
//   DetectionResult r = det.detect(gray, camera, {t_s, index});  // one SIFT extraction for all objects
//   if (const std::optional<Detection> d = r.find(id)) use(d->cMo);
//
// Errors: Detector's constructor and addObject() throw (start-up: std::invalid_argument for bad
// options, ConfigError for a bad object); options are checked there, once. detect() and
// detectStereo() never throw: a frame they cannot use (empty image, unsupported pixel type, image
// size different from the camera's, invalid camera, bad query) and any failure inside (OpenCV,
// out of memory) give ok = false and a one-line `error`. Colour frames are converted to gray.
//
// Distortion: keypoints are undistorted (reference with the reference camera, scene with the
// scene camera) before matching, so Detection::H maps UNDISTORTED reference px to UNDISTORTED
// scene px (plain reference px -> image px when neither camera has distortion). Detection::corners
// and every cv::Rect here are in the real (distorted) image.
//
// Building blocks for benchmarks and method comparisons: detector/detector_internal.h.
#include <Eigen/Core>
#include <array>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"
#include "core/types.h"
#include "detector/dense.h"     // DenseRefineOptions
#include "detector/features.h"  // SiftOptions
#include "detector/matching.h"  // MatchOptions, MatchRejects
#include "detector/object.h"    // ObjectModel
#include "detector/pose.h"      // PoseMethod, PoseOptions
#include "detector/sanity.h"    // SanityOptions, SanityStatus
#include "detector/stereo.h"    // FusedPose
#include "detector/verify.h"    // VerifyOptions

namespace refgrasp::detector {

struct RegisteredObject;  // detector/registered_object.h: model, reference index, pyramid

/// Fusion of a several-view object's views (detector/multiview.h). Two views' poses of the
/// object agree when their origins lie within max_gap_m + max_gap_fraction x distance and their
/// rotations within max_rotation_gap_rad: a verified single face is within about 1 cm + 2 % and
/// 3 deg at 0.5-2 m (docs/results.md "Several-view objects"), so two right faces differ by up to
/// twice that, and a face placed on the wrong side of a box (0.1 m or 90 deg off) does not agree.
struct MultiViewOptions {
  double max_gap_m = 0.02;
  double max_gap_fraction = 0.05;
  double max_rotation_gap_rad = 0.1745;  ///< 10 deg
  /// Throws std::invalid_argument "MultiViewOptions.<field>: <problem>".
  void check() const;
};

/// Every field can be set in a YAML file (config/detector.yaml, loadDetectorOptions).
struct DetectorOptions {
  SiftOptions sift;
  MatchOptions match;
  /// Default: the more accurate method on Detector.PoseAccuracyBothMethods (test_detector.cpp).
  PoseMethod pose = PoseMethod::kRefined;
  PoseOptions pose_options;
  /// Refined method only: photometric (ECC) refinement of the matched H, pose from a grid mapped
  /// by it. Used when the reference camera is distortion-free and the pattern region is a
  /// rectangle (a distorted scene is resampled around the pattern only); falls back to the
  /// feature correspondences when ECC fails or moves a corner too far.
  DenseRefineOptions dense;
  SanityOptions sanity;
  /// Last check of an instance: the reference warped by its H must correlate with the scene.
  VerifyOptions verify;
  MultiViewOptions multiview;
  /// Throws std::invalid_argument "<Options.field>: <problem>".
  void check() const;
};

/// Where to look for one object, e.g. the tracker's prediction after it lost the target.
struct ObjectPrior {
  int object = -1;  ///< id returned by addObject()
  /// Predicted cMo (object frame in the scene camera frame, metres, radians). For objects with a
  /// reference pose (a several-view object: each view, at cMo * oMv) it gives the region (the
  /// projected pattern's bounding box grown by roi_margin) and the keypoint size range (the
  /// reference keypoint sizes times the predicted local scale, divided and multiplied by
  /// scale_margin). Ignored for 2D-only objects.
  std::optional<Pose> cMo;
  cv::Rect roi;               ///< image px; non-empty: search here instead of the projection
  double roi_margin = 0.25;   ///< added on each side, fraction of the projection's larger side
  double scale_margin = 2.0;  ///< >= 1, see cMo
  /// Predicted H (undistorted reference px -> undistorted scene px) of an object with a single
  /// planar reference, for one without a pose (2D-only, e.g. the homography tracker's): the
  /// region and the keypoint size range as cMo gives them. Ignored when cMo is used.
  std::optional<Eigen::Matrix3d> H;
  /// > 0: largest scale (scene px per reference px) at which a predicted region (cMo or H) is
  /// extracted: when the prediction puts some of the pattern larger, the region is downsampled
  /// by that factor first (ExtractRegion::downsample), matched there, and the dense alignment
  /// refines the result on the full-resolution image with a template downsample^2 larger (the
  /// pixels the extraction saved). A pattern twice as large then costs about the same as one at
  /// this scale. 0.4 is the value measured in docs/results.md "Detection with a prior region at
  /// 1280x720" (SIFT doubles the scene, so its first octave still sees the pattern at 0.8 of the
  /// reference's pixels, enough for a reference sharper than the scene, e.g. a rendered
  /// texture). 0 (default): never downsampled; a reference no sharper than the scene (a frame of
  /// the same video) keeps too few matches when the region is downsampled (same page). Not
  /// applied to a several-view object's views.
  double max_scale = 0;
};

/// What to search in one frame. Default: every object in the whole image, one shared extraction.
/// Each distinct region is extracted once (SIFT on an aligned crop: cheaper than the whole image).
struct DetectionQuery {
  std::optional<cv::Rect> roi;      ///< image px: restricts the search of every object
  std::vector<ObjectPrior> priors;  ///< at most one per object
  bool only_priors = false;         ///< true: objects without a prior are not searched
};

struct Detection {
  int object = -1;    ///< id returned by addObject()
  int instance = 0;   ///< 0 = best
  bool found = false;
  /// undistorted reference px -> scene px (undistorted); 2D-only objects: the dense alignment's
  /// when it converged (DenseRefineOptions), else the matched features'
  Eigen::Matrix3d H = Eigen::Matrix3d::Identity();
  std::array<Eigen::Vector2d, 4> corners{Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(),
                                         Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero()};
  ///< pattern corners TL, TR, BR, BL, image px
  std::optional<Pose> cMo;  ///< object frame in camera frame (m, rad); empty for 2D-only objects
  int inliers = 0;
  double score = 0;         ///< matcher score (eq. 3), lower is better
  double pose_rms_px = 0;   ///< reprojection RMS of the pose method's own points
  double log10_nfa = 0;     ///< a-contrario significance of the matches (MatchOptions::max_log10_nfa)
  double correlation = 0;   ///< photometric agreement of the warped reference (VerifyOptions)
  SanityStatus sanity = SanityStatus::kOk;  ///< why the best candidate was rejected, if it was
  /// Several-view objects: the views fused into this instance, most inliers first (cMo is their
  /// joint pose when there are two or more; inliers their sum), and `view` the first of them,
  /// whose H, corners, score, log10_nfa and correlation these are. Empty for other objects.
  std::vector<std::string> views;
  std::string view;
};

/// Why an object has no accepted instance in a frame: the furthest stage a hypothesis reached.
enum class MissReason {
  kNone,                   ///< found
  kNotSearched,            ///< DetectionQuery::only_priors and no prior for it
  kTooFewFeatures,         ///< fewer than 4 scene features in its region
  kNoGlobalMatches,        ///< no scene feature passed the global ratio test
  kTooFewLocalMatches,     ///< paper matcher: no hypothesis found enough consistent matches
  kTooFewInliers,          ///< the best robust homography had < min_inliers inliers
  kImplausibleHomography,  ///< flipped, non-convex, near-singular or tiny projected pattern
  kNarrowInlierSpread,     ///< inliers covered too little of the reference (a shared logo)
  kPoseFailed,             ///< no candidate's pose could be estimated
  kSanity,                 ///< every candidate failed the sanity check (ObjectStats::sanity)
  kNotSignificant,         ///< the best consensus was not significant (log10 NFA too high)
  kNotVerified,            ///< every candidate's warped reference disagreed with the scene (or agreed clearly better a repeat period away)
};
const char* missReasonName(MissReason r);

/// Per object and frame: what the matcher saw and, when nothing was accepted, why.
struct ObjectStats {
  int object = -1;
  cv::Rect roi;                  ///< image px searched (the whole image unless restricted)
  double min_keypoint_px = 0;    ///< keypoint size range searched (diameter, image px)
  double max_keypoint_px = 1e30;
  double downsample = 1;         ///< the region was extracted at 1/downsample of the resolution
  int scene_features = 0;        ///< scene features the matcher saw (those of its region)
  int global_matches = 0;        ///< of them, passing the global ratio test
  int hypotheses_evaluated = 0;
  int candidates = 0;            ///< homographies the matcher accepted (before pose and sanity)
  /// The object's own features found nothing and its view-synthesised features were matched too
  /// (match.plane_views); the counts above then add both passes (global_matches: the larger).
  bool views_matched = false;
  /// Nothing accepted: boxes of weak hypotheses extracted again at the lower contrast threshold
  /// and matched (match.weak_regions); the counts above include their matching.
  int weak_regions = 0;
  MatchRejects rejected;         ///< hypotheses / fits that ended at each matcher stage
  MissReason miss = MissReason::kNone;
  SanityStatus sanity = SanityStatus::kOk;  ///< with kSanity: the best candidate's status
};

struct DetectionTimings {
  double extract = 0, match = 0, pose = 0, total = 0;  ///< milliseconds
};

struct DetectionResult {
  bool ok = true;
  std::string error;  ///< one line when !ok
  FrameStamp frame;   ///< as given to detect()
  /// Per object in id order: its found instances (best first), or one entry with found = false.
  /// Empty when !ok, like stats.
  std::vector<Detection> detections;
  std::vector<ObjectStats> stats;  ///< one per object, id order
  DetectionTimings time_ms;
  int scene_features = 0;  ///< features extracted in this frame (all regions)
  /// A copy of the given instance of the object when it was found (safe on a temporary result).
  std::optional<Detection> find(int object, int instance = 0) const;
};

struct StereoDetection {
  int object = -1;
  FusedPose fused;          ///< eyes that succeeded + fused lMo (left camera frame)
  Detection left, right;    ///< best instance per eye (found = false when that eye missed)
};

struct StereoDetectionResult {
  bool ok = true;
  std::string error;
  FrameStamp frame;                      ///< as given to detectStereo(), also in left and right
  std::vector<StereoDetection> objects;  ///< one per object, id order
  DetectionResult left, right;
};

/// Photometric alignment of a pose (Detector::alignPose).
struct PoseAlignment {
  bool ok = false;
  Pose cMo;                    ///< aligned object frame in the camera frame (metres, radians)
  double correlation = 0;      ///< final ECC correlation coefficient
  double corner_shift_px = 0;  ///< largest pattern corner move, aligned vs given pose
  /// Fraction of the reference the alignment used (dense.robust: the rest was off the image or
  /// occluded; 1 otherwise).
  double used_fraction = 1;
};

/// Photometric alignment of a homography (Detector::alignHomography).
struct HomographyAlignment {
  bool ok = false;
  /// aligned H: undistorted reference px -> undistorted scene px (x_s ~ H x_r); the given H when !ok
  Eigen::Matrix3d H = Eigen::Matrix3d::Identity();
  std::array<Eigen::Vector2d, 4> corners{};  ///< ok: pattern corners TL, TR, BR, BL, image px
  double correlation = 0;      ///< final ECC correlation coefficient
  double corner_shift_px = 0;  ///< largest pattern corner move, aligned vs given H
  double used_fraction = 1;    ///< as PoseAlignment::used_fraction
};

class Detector {
 public:
  /// Throws std::invalid_argument when opt.check() fails.
  explicit Detector(DetectorOptions opt = {});
  ~Detector();
  Detector(const Detector&);
  Detector(Detector&&) noexcept;
  Detector& operator=(const Detector&);
  Detector& operator=(Detector&&) noexcept;

  /// Computes the reference features once. Returns the object id (0, 1, ...). A several-view
  /// object (ObjectModel::views) has one id; its views are registered inside, detected on the
  /// frame's shared extraction and fused (detector/multiview.h).
  int addObject(const ObjectModel& object);
  int objectCount() const;
  const ObjectModel& object(int id) const;
  const DetectorOptions& options() const { return opt_; }

  /// \param image 8-bit gray (colour is converted), size camera.width x camera.height
  /// \param camera intrinsics of this image (distortion honoured)
  /// \param frame capture stamp and index of the image, returned in the result
  /// \param query where to look (default: every object in the whole image)
  DetectionResult detect(const cv::Mat& image, const Intrinsics& camera,
                         const FrameStamp& frame = {}, const DetectionQuery& query = {}) const;

  /// Aligns the object's reference with `image` starting from the pose cMo (e.g. a tracker's):
  /// the dense ECC refinement of the refined pose method (options.dense), on the homography cMo
  /// predicts, then the pose from the grid it maps. ok = false (never a throw) when the object
  /// has no usable reference pyramid (2D-only, several-view, distorted reference camera; a
  /// pattern region that is not a rectangle masks the template), the pattern is behind the camera, the image is
  /// unusable, or ECC fails, moves a
  /// corner more than dense.max_corner_shift_px or ends below dense.min_correlation.
  /// dense: the refinement's options (nullptr: options().dense).
  PoseAlignment alignPose(const cv::Mat& image, const Intrinsics& camera, int object,
                          const Pose& cMo, const DenseRefineOptions* dense = nullptr) const;

  /// Aligns the object's reference with `image` starting from H (undistorted reference px ->
  /// undistorted scene px, e.g. a tracker's): the same dense ECC refinement as alignPose and the
  /// detection of a 2D-only object, for any object with a single planar reference (2D-only or
  /// planar with a pose). ok = false (never a throw) when the object has no usable reference
  /// pyramid (several-view, cylinder, distorted reference camera, inexact region), the image is
  /// unusable, or ECC fails, moves a corner more than dense.max_corner_shift_px or ends below
  /// dense.min_correlation. dense: nullptr: options().dense.
  HomographyAlignment alignHomography(const cv::Mat& image, const Intrinsics& camera, int object,
                                      const Eigen::Matrix3d& H, const DenseRefineOptions* dense = nullptr) const;

  /// Detects in each eye independently (each with its own intrinsics) and fuses the best
  /// instance of every object (fuseStereo). Poses in the LEFT camera frame.
  StereoDetectionResult detectStereo(const cv::Mat& left, const cv::Mat& right,
                                     const StereoRig& rig, const FrameStamp& frame = {}) const;

 private:
  friend struct DetectorInternals;  // detector/detector_internal.h
  /// detect() on a validated gray image; may throw what OpenCV throws.
  DetectionResult detectGray(const cv::Mat& gray, const Intrinsics& camera,
                             const DetectionQuery& query) const;
  DetectorOptions opt_;
  std::vector<RegisteredObject> objects_;  ///< per id; a several-view object's holds only its model
  /// Per id: the several-view object's views (empty for other objects), as objects_ entries.
  std::vector<std::vector<RegisteredObject>> views_;
};

}  // namespace refgrasp::detector
