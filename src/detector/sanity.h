#pragma once
// Final plausibility check of a detection (the paper's last step, extended to the corners).
#include <Eigen/Core>
#include <array>
#include <optional>

#include "core/pose.h"

namespace refgrasp::detector {

struct SanityOptions {
  double min_distance_m = 0.2;   ///< |t| of cMo, the paper's range [0.2, 10]
  double max_distance_m = 10.0;
  double min_area_px2 = 400;     ///< projected pattern area in the image
  double max_area_fraction = 16;   ///< of the image area (a close-up shows a pattern up to 4x the frame)
  /// A pose whose pattern corners lie farther than this (px; or 10 % of the pattern's diagonal
  /// in the image when larger) from the matched homography's is refused: a pose caught in the
  /// wrong one of a plane's two solutions, or pulled off by a few bad points, is not the instance
  /// the features found. Alignments farther apart than this are distinct. 1e9: never.
  double max_pose_gap_px = 4;
  void check() const;
};

enum class SanityStatus { kOk, kBehindCamera, kTooClose, kTooFar, kNotConvex, kAreaTooSmall,
                          kAreaTooLarge, kNotFinite,
                          kPoseDisagrees  ///< the pose's pattern corners far from the homography's
};
const char* sanityStatusName(SanityStatus s);

/// corners: TL, TR, BR, BL in image px. cMo: empty for 2D-only objects (corner checks only).
SanityStatus checkDetection(const std::array<Eigen::Vector2d, 4>& corners,
                            const std::optional<Pose>& cMo, int image_width, int image_height,
                            const SanityOptions& opt);

/// True when the quadrilateral is strictly convex (either winding).
bool isConvexQuad(const std::array<Eigen::Vector2d, 4>& q);
/// Signed area (shoelace), px^2.
double quadArea(const std::array<Eigen::Vector2d, 4>& q);

}  // namespace refgrasp::detector
