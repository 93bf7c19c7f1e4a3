#pragma once
// View-synthesised label features of a cylinder object: SIFT features of the label as a camera
// sees it wrapped on its cylinder, turned about the axis and at smaller scales, mapped back to
// label px. Internal to the detector library; why: docs/detector.md "Cylinders".
//
// SIFT is invariant to scale and rotation, not to the foreshortening of a surface turning away:
// a feature 40-60 deg round the axis from the column facing the camera is squeezed across the
// axis by cos(angle), and a label seen from 1 m shows only its coarse structure. The flat label
// alone gives few matches there. Each synthesised view is the label seen from afar
// (orthographic) with the cylinder turned by a multiple of kTurnStep, at a scale of 1, 1/2 or
// 1/4 image px per label px along the axis; its features within kMaxAngle of the facing column
// are kept, those that repeat a feature already kept (same place, size and look) are dropped,
// so that the global ratio test is not spoiled by copies of one feature.
#include <opencv2/core.hpp>

#include "core/cylinder.h"
#include "detector/features.h"

namespace refgrasp::detector {

/// The synthesised features not already among `flat` (the label's own features, label px).
/// Keypoints in label px (u in [0, W), unwrapped: the caller rolls them for a seam index), size
/// in label px along the axis, angle as extracted (the views keep the label's axes). `label`:
/// the reference image (8-bit gray or colour), `region`: the pattern polygon in label px (empty:
/// the whole label) outside which nothing is kept.
Features synthesisedLabelFeatures(const CylinderLabel& L, const cv::Mat& label, const Features& flat,
                                  const std::vector<Eigen::Vector2d>& region, const SiftOptions& sift);

}  // namespace refgrasp::detector
