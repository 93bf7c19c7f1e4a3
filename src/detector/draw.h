#pragma once
// Drawing poses on pictures for people to check (the paper's Fig. 4 style): object axes x red,
// y green, z blue from the object origin. BGR images; pixel (0, 0) is the top-left pixel centre.
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/pose.h"

namespace refgrasp::detector {

/// Draws the axes of cMo (object frame in the camera frame), `length_m` long, projected with
/// `camera` (distortion included). Axes whose end lies behind the camera are left out.
void drawAxes(cv::Mat& bgr, const Intrinsics& camera, const Pose& cMo, double length_m, int thickness = 2);

}  // namespace refgrasp::detector
