#pragma once
// Bridges refgrasp's Pose (x_in_a = R x_in_b + t, metres, radians) and ViSP's
// vpHomogeneousMatrix, which uses the same convention (cMo: object frame in camera frame).
#include <visp3/core/vpHomogeneousMatrix.h>

#include "core/pose.h"

namespace refgrasp::servo {

vpHomogeneousMatrix toVisp(const Pose& aMb);
Pose fromVisp(const vpHomogeneousMatrix& aMb);

}  // namespace refgrasp::servo
