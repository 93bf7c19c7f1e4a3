#pragma once
// The detector facade: the small stable API a tracker, a replay tool or a DDS node calls.
//
//   Detector det(DetectorOptions{});
//   int id = det.addObject(loadObjectDefinition("config/objects/poster.yaml"));
//   DetectionResult r = det.detect(gray, camera);   // one SIFT extraction for all objects
//
// Errors: Detector's constructor and addObject() throw (start-up: std::invalid_argument for bad
// options, ConfigError for a bad object). detect()/detectStereo() never throw for bad frames: they
// return ok = false and a one-line `error` (empty image, unsupported pixel type, image size
// different from the camera's). Colour frames are converted to gray.
//
// Distortion: keypoints are undistorted (reference with the reference camera, scene with the
// scene camera) before matching, so Detection::H maps UNDISTORTED reference px to UNDISTORTED
// scene px (plain reference px -> image px when neither camera has distortion). Detection::corners
// are in the real (distorted) image.
#include <Eigen/Core>
#include <array>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"
#include "detector/dense.h"
#include "detector/features.h"
#include "detector/matching.h"
#include "detector/object.h"
#include "detector/pose.h"
#include "detector/sanity.h"
#include "detector/stereo.h"

namespace refgrasp::detector {

struct DetectorOptions {
  SiftOptions sift;
  MatchOptions match;
  /// Default: the more accurate method on Detector.PoseAccuracyBothMethods (test_detector.cpp).
  PoseMethod pose = PoseMethod::kRefined;
  PoseOptions pose_options;
  /// Refined method only: photometric (ECC) refinement of the matched H, pose from a grid mapped
  /// by it. Used when the reference camera is distortion-free and the pattern region is a
  /// rectangle (a distorted scene is resampled around the pattern only); falls back to the feature correspondences when ECC fails or moves a corner too far.
  DenseRefineOptions dense;
  SanityOptions sanity;
  void check() const;
};

struct Detection {
  int object = -1;    ///< id returned by addObject()
  int instance = 0;   ///< 0 = best
  bool found = false;
  Eigen::Matrix3d H = Eigen::Matrix3d::Identity();  ///< undistorted reference px -> scene px
  std::array<Eigen::Vector2d, 4> corners{Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(),
                                         Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero()};
  ///< pattern corners TL, TR, BR, BL, image px
  std::optional<Pose> cMo;  ///< object frame in camera frame (m, rad); empty for 2D-only objects
  int inliers = 0;
  double score = 0;         ///< matcher score (eq. 3), lower is better
  double pose_rms_px = 0;   ///< reprojection RMS of the pose method's own points
  SanityStatus sanity = SanityStatus::kOk;  ///< why the best candidate was rejected, if it was
};

struct DetectionTimings {
  double extract = 0, match = 0, pose = 0, total = 0;  ///< milliseconds
};

struct DetectionResult {
  bool ok = true;
  std::string error;  ///< one line when !ok
  /// Per object in id order: its found instances (best first), or one entry with found = false.
  std::vector<Detection> detections;
  DetectionTimings time_ms;
  int scene_features = 0;
  /// The given instance of the object if found, else nullptr.
  const Detection* find(int object, int instance = 0) const;
};

struct StereoDetection {
  int object = -1;
  FusedPose fused;          ///< eyes that succeeded + fused lMo (left camera frame)
  Detection left, right;    ///< best instance per eye (found = false when that eye missed)
};

struct StereoDetectionResult {
  bool ok = true;
  std::string error;
  std::vector<StereoDetection> objects;  ///< one per object, id order
  DetectionResult left, right;
};

class Detector {
 public:
  /// Throws std::invalid_argument when opt.check() fails.
  explicit Detector(DetectorOptions opt = {});

  /// Computes the reference features once. Returns the object id (0, 1, ...).
  int addObject(const ObjectModel& object);
  int objectCount() const { return static_cast<int>(objects_.size()); }
  const ObjectModel& object(int id) const { return objects_.at(id).model; }
  const ReferenceIndex& referenceIndex(int id) const { return objects_.at(id).index; }
  const DetectorOptions& options() const { return opt_; }

  /// \param image 8-bit gray (colour is converted), size camera.width x camera.height
  /// \param camera intrinsics of this image (distortion honoured)
  DetectionResult detect(const cv::Mat& image, const Intrinsics& camera) const;

  /// Detects in each eye independently (each with its own intrinsics) and fuses the best
  /// instance of every object (fuseStereo). Poses in the LEFT camera frame.
  StereoDetectionResult detectStereo(const cv::Mat& left, const cv::Mat& right,
                                     const StereoRig& rig) const;

  // Building blocks (used by detect(); public for benchmarks and method comparisons).
  /// SIFT on the (validated) image with keypoints undistorted by `camera`.
  Features extract(const cv::Mat& gray, const Intrinsics& camera) const;
  /// Pose of a match candidate with the chosen method; empty result for 2D-only objects.
  PoseResult estimatePose(int object, const MatchCandidate& match, const Features& scene,
                          const Intrinsics& camera, PoseMethod method) const;
  /// Empty string when the image can be used with this camera, else the problem.
  static std::string validateImage(const cv::Mat& image, const Intrinsics& camera);

 private:
  struct Entry {
    ObjectModel model;
    ReferenceIndex index;
    std::array<Eigen::Vector2d, 4> corners_und_px;  ///< pattern corners, undistorted ref px
    std::vector<cv::Mat> pyramid;  ///< reference pyramid for dense refinement (empty: not usable)
  };
  DetectionResult detectGray(const cv::Mat& gray, const Intrinsics& camera) const;
  /// Dense refinement of H (undistorted reference px -> undistorted scene px) on `image`.
  DenseRefineResult refineDense(const Entry& e, const Eigen::Matrix3d& H, const cv::Mat& image,
                                const Intrinsics& camera) const;

  DetectorOptions opt_;
  std::vector<Entry> objects_;
};

}  // namespace refgrasp::detector
