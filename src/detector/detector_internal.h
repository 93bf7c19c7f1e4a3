#pragma once
// The Detector's building blocks, for benchmarks, method comparisons and tests. Not the facade
// (detector.h): these signatures follow the implementation and may change with it.
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "detector/detector.h"
#include "detector/features.h"
#include "detector/matching.h"
#include "detector/pose.h"
#include "detector/reference_index.h"

namespace refgrasp::detector {

struct DetectorInternals {
  /// SIFT on an 8-bit gray image of `camera`'s size, keypoints undistorted by `camera`; the
  /// image is kept in Features::image (the refined pose uses it). As detect() extracts.
  static Features extract(const Detector& det, const cv::Mat& gray, const Intrinsics& camera,
                          const ExtractRegion& region = {});
  /// The object's reference features and index (reference px undistorted by its camera).
  static const ReferenceIndex& referenceIndex(const Detector& det, int object);
  /// Pose of a match candidate with the given method, as detect() computes it; ok = false for
  /// 2D-only objects.
  static PoseResult estimatePose(const Detector& det, int object, const MatchCandidate& match,
                                 const Features& scene, const Intrinsics& camera,
                                 PoseMethod method);
};

}  // namespace refgrasp::detector
