#pragma once
// Photometric refinement of a cylinder's pose: the label, sampled over its part facing the
// camera, aligned with the scene by Gauss-Newton on the 6 pose parameters plus a gain and an
// offset (Huber-weighted, so a partial occlusion or a highlight does not pull it), coarse to
// fine on the scene smoothed by 2 px then 1 px. Every pixel of the visible label constrains the
// pose, not the few dozen keypoints of a far can: the rotation is what it fixes. Internal to the
// detector library (cylinder_detection.cpp).
//
// Frames: cMo = the cylinder's object frame (core/cylinder.h) in the scene camera frame; the
// scene is the camera's real (distorted) image, sampled through Intrinsics::project.
#include <opencv2/core.hpp>
#include <vector>

#include "core/camera.h"
#include "core/cylinder.h"
#include "core/pose.h"

namespace refgrasp::detector {

struct CylinderDenseResult {
  bool ok = false;                ///< converged to a finite pose
  Pose cMo;                       ///< refined (the input when !ok)
  double correlation_before = 0;  ///< zero-mean NCC of label and scene samples, at the input pose
  double correlation_after = 0;   ///< ... at the refined pose (both on the finest smoothing)
  int samples = 0;                ///< label samples compared (visible, in the image)
};

/// label_pyramid: level 0 the label image (CV_8UC1), each next one pyrDown. scene: CV_8UC1 of
/// camera's size. facing_cos: the samples' surface faces the camera by more than this
/// (CylinderLabel::facesCamera). max_samples bounds the work (a near can is sampled coarser).
CylinderDenseResult refineCylinderPoseDense(const CylinderLabel& label, const std::vector<cv::Mat>& label_pyramid,
                                            const cv::Mat& scene, const Intrinsics& camera, const Pose& cMo,
                                            double facing_cos, int max_samples = 4000);

}  // namespace refgrasp::detector
