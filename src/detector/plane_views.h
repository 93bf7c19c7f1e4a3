#pragma once
// View-synthesised reference features of a planar object: SIFT features of the reference as a
// camera sees the pattern turned away (tilted about an axis in its plane) and from further off,
// mapped back to reference px. Internal to the detector library; why: docs/detector.md
// "Pipeline", step 1.
//
// SIFT is invariant to scale and rotation, not to foreshortening: a face 50 deg oblique is
// squeezed by cos 50 = 0.64 across its tilt axis, and the reference, itself a photo taken at
// another angle, is squeezed along another. Two such views of a small target share few
// descriptors (a far 30 px face: 0-5 of the 15-40 reference features large enough to be seen).
// Each synthesised view is the pattern seen from afar (affine: a plane's view over a small
// angle) fronto-parallel or tilted by 45 or 60 deg about axes every 180 / (5 t) deg (ASIFT's
// sampling, t = 1 / cos tilt), with the pattern 80 and 40 px large; its features in
// the pattern region are mapped back, and those that repeat a feature already kept (same place,
// size and look) are dropped, so that copies of one feature do not spoil the global ratio test.
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

#include "detector/features.h"

namespace refgrasp::detector {

/// cv::KeyPoint::class_id of a view-synthesised feature (a copy of a reference place as another
/// view sees it); the reference's own features keep SIFT's -1.
constexpr int kSynthesisedFeature = 1;

/// A synthesised feature k (descriptor d) repeats the kept feature o (descriptor od): it lies
/// within half the larger size of it, the sizes are within 1.5x and the descriptors within 250
/// (L2; OpenCV SIFT descriptors have norm ~512, unrelated ones are 350-450 apart). Shared by the
/// cylinder's views (cylinder_views.h).
bool repeatsFeature(const cv::KeyPoint& o, const cv::Mat& od, const cv::KeyPoint& k, const cv::Mat& d);

/// The synthesised features not already among `own` (the reference's own features, reference
/// px of `reference`). `reference`: the reference image (8-bit gray); `region`: the pattern
/// polygon in reference px (empty: the whole image); `frontal`: the linear map from reference px
/// to the pattern plane seen fronto-parallel near the pattern's centre (any scale; identity when
/// the reference's pose is unknown: the reference then stands for the frontal view). Keypoints
/// in reference px; size and angle as the view's feature maps back through the view's affine
/// (size scaled by the square root of its area change, angle along the mapped direction),
/// class_id kSynthesisedFeature.
Features synthesisedPlaneFeatures(const cv::Mat& reference, const Features& own,
                                  const std::vector<Eigen::Vector2d>& region, const Eigen::Matrix2d& frontal,
                                  const SiftOptions& sift);

}  // namespace refgrasp::detector
