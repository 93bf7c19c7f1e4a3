#pragma once
// The classic OpenCV pipeline that refgrasp is compared with: cv::SIFT, brute-force
// 2-NN with Lowe's ratio 0.8, cv::findHomography (RANSAC, 3 px), accepted with >= 10 inliers,
// pose by IPPE + Levenberg-Marquardt (cv::solvePnP SOLVEPNP_IPPE, cv::solvePnPRefineLM) on the
// homography inliers. The reference features are those inside the object's pattern region.
//
// Pixels: H maps reference px -> scene px (both as in the images; the scene's distortion is
// honoured by the pose only). cMo: object frame in the scene camera frame, metres, radians.
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"
#include "detector/object.h"

namespace refgrasp::eval {

struct ClassicOptions {
  double ratio = 0.8;
  double ransac_reproj_px = 3.0;
  int min_inliers = 10;
};

struct ClassicResult {
  bool found = false;
  Eigen::Matrix3d H = Eigen::Matrix3d::Identity();
  std::optional<Pose> cMo;  ///< empty for 2D-only objects or when the PnP fails
  int inliers = 0;
};

/// Scene features computed once and shared by several objects (cv::SIFT, or given).
struct ClassicFeatures {
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;  ///< CV_32F N x 128
};

/// cv::SIFT with OpenCV's defaults (what the 20-line pipeline calls).
ClassicFeatures classicSift(const cv::Mat& gray);

class ClassicPipeline {
 public:
  /// Extracts the reference's cv::SIFT features inside the pattern region.
  explicit ClassicPipeline(const detector::ObjectModel& object, ClassicOptions opt = {});
  ClassicResult detect(const ClassicFeatures& scene, const Intrinsics& camera) const;
  ClassicResult detect(const cv::Mat& gray, const Intrinsics& camera) const {
    return detect(classicSift(gray), camera);
  }

 private:
  detector::ObjectModel object_;
  ClassicOptions opt_;
  std::vector<cv::KeyPoint> ref_keypoints_;
  cv::Mat ref_descriptors_;
};

}  // namespace refgrasp::eval
