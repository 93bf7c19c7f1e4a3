#pragma once
// Stereo fusion of two independent single-eye pose estimates (the paper's rule: average the
// positions and the rotation vectors), expressed in the LEFT camera frame.
#include <optional>

#include "core/camera.h"
#include "core/pose.h"

namespace refgrasp::detector {

enum class EyesUsed { kNone, kLeft, kRight, kBoth };
const char* eyesUsedName(EyesUsed e);

struct FusedPose {
  EyesUsed eyes = EyesUsed::kNone;
  std::optional<Pose> lMo;  ///< object frame in the left camera frame (metres, radians)
};

/// left_cMo: lMo from the left eye; right_cMo: rMo from the right eye (moved to the left frame
/// with rig.lMr). Both: mean position, mean rotation vector taken on the same branch (the right
/// vector is re-expressed as the equivalent one closest to the left, so near pi the average does
/// not jump). One: that estimate. None: empty.
FusedPose fuseStereo(const std::optional<Pose>& left_cMo, const std::optional<Pose>& right_cMo,
                     const StereoRig& rig);

/// Rotation vector equivalent to `r` (same rotation) closest to `near` (angle may exceed pi).
Eigen::Vector3d closestRotationVector(const Eigen::Vector3d& r, const Eigen::Vector3d& near);

}  // namespace refgrasp::detector
