#include "detector/stereo.h"

#include <cmath>

namespace refgrasp::detector {

const char* eyesUsedName(EyesUsed e) {
  switch (e) {
    case EyesUsed::kNone: return "none";
    case EyesUsed::kLeft: return "left";
    case EyesUsed::kRight: return "right";
    case EyesUsed::kBoth: return "both";
  }
  return "?";
}

Eigen::Vector3d closestRotationVector(const Eigen::Vector3d& r, const Eigen::Vector3d& near) {
  const double a = r.norm();
  if (a < 1e-12) return r;
  const Eigen::Vector3d u = r / a;
  // Same rotation: u (a + 2 pi k) for any integer k; try the nearest few.
  Eigen::Vector3d best = r;
  double best_d = (r - near).norm();
  for (int k = -2; k <= 2; ++k) {
    const Eigen::Vector3d c = u * (a + 2 * M_PI * k);
    if ((c - near).norm() < best_d) {
      best_d = (c - near).norm();
      best = c;
    }
  }
  return best;
}

FusedPose fuseStereo(const std::optional<Pose>& left_cMo, const std::optional<Pose>& right_cMo,
                     const StereoRig& rig) {
  FusedPose out;
  std::optional<Pose> r_in_l;
  if (right_cMo) r_in_l = rig.lMr * *right_cMo;
  if (left_cMo && r_in_l) {
    const Eigen::Vector3d rl = left_cMo->rotationVector();
    const Eigen::Vector3d rr = closestRotationVector(r_in_l->rotationVector(), rl);
    out.eyes = EyesUsed::kBoth;
    out.lMo = Pose::fromRotationVector(0.5 * (rl + rr), 0.5 * (left_cMo->t + r_in_l->t));
  } else if (left_cMo) {
    out.eyes = EyesUsed::kLeft;
    out.lMo = left_cMo;
  } else if (r_in_l) {
    out.eyes = EyesUsed::kRight;
    out.lMo = r_in_l;
  }
  return out;
}

}  // namespace refgrasp::detector
