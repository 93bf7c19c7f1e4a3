#include "detector/sanity.h"

#include <cmath>

#include "core/error.h"
#include "core/geometry.h"

namespace refgrasp::detector {

void SanityOptions::check() const {
  refgrasp::check(std::isfinite(min_distance_m) && min_distance_m >= 0,
                  "SanityOptions.min_distance_m", "must be finite and >= 0");
  refgrasp::check(std::isfinite(max_distance_m) && max_distance_m > min_distance_m,
                  "SanityOptions.max_distance_m", "must be finite and > min_distance_m");
  refgrasp::check(std::isfinite(min_area_px2) && min_area_px2 >= 0, "SanityOptions.min_area_px2",
                  "must be >= 0");
  refgrasp::check(std::isfinite(max_area_fraction) && max_area_fraction > 0,
                  "SanityOptions.max_area_fraction", "must be positive");
  refgrasp::check(std::isfinite(max_pose_gap_px) && max_pose_gap_px > 0 && max_pose_gap_px <= 1e9,
                  "SanityOptions.max_pose_gap_px", "must be in (0, 1e9] (1e9: never)");
}

const char* sanityStatusName(SanityStatus s) {
  switch (s) {
    case SanityStatus::kOk: return "ok";
    case SanityStatus::kBehindCamera: return "behind camera";
    case SanityStatus::kTooClose: return "too close";
    case SanityStatus::kTooFar: return "too far";
    case SanityStatus::kNotConvex: return "corners not convex";
    case SanityStatus::kAreaTooSmall: return "area too small";
    case SanityStatus::kAreaTooLarge: return "area too large";
    case SanityStatus::kNotFinite: return "not finite";
    case SanityStatus::kPoseDisagrees: return "pose disagrees with the homography";
  }
  return "?";
}

double quadArea(const std::array<Eigen::Vector2d, 4>& q) { return signedArea(q); }

bool isConvexQuad(const std::array<Eigen::Vector2d, 4>& q) {
  int pos = 0, neg = 0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d a = q[(i + 1) % 4] - q[i], b = q[(i + 2) % 4] - q[(i + 1) % 4];
    const double c = a.x() * b.y() - a.y() * b.x();
    if (c > 0) ++pos;
    if (c < 0) ++neg;
  }
  return pos == 4 || neg == 4;
}

SanityStatus checkDetection(const std::array<Eigen::Vector2d, 4>& corners,
                            const std::optional<Pose>& cMo, int image_width, int image_height,
                            const SanityOptions& opt) {
  for (const auto& c : corners)
    if (!c.allFinite()) return SanityStatus::kNotFinite;
  if (cMo) {
    if (!cMo->isFinite()) return SanityStatus::kNotFinite;
    if (cMo->t.z() <= 0) return SanityStatus::kBehindCamera;
    const double d = cMo->t.norm();
    if (d < opt.min_distance_m) return SanityStatus::kTooClose;
    if (d > opt.max_distance_m) return SanityStatus::kTooFar;
  }
  if (!isConvexQuad(corners)) return SanityStatus::kNotConvex;
  const double area = std::abs(quadArea(corners));
  if (area < opt.min_area_px2) return SanityStatus::kAreaTooSmall;
  if (area > opt.max_area_fraction * image_width * image_height)
    return SanityStatus::kAreaTooLarge;
  return SanityStatus::kOk;
}

}  // namespace refgrasp::detector
