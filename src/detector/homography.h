#pragma once
// Plane-to-plane homographies. Convention: x_to ~ H * x_from (homogeneous pixels).
#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace refgrasp::detector {

struct HomographyOptions {
  double ransac_reproj_px = 3.0;  ///< inlier threshold on the transfer error, pixels
  int max_iterations = 2000;
  double confidence = 0.999;
  uint64_t seed = 0;
  /// Throws std::invalid_argument on nonsense.
  void check() const;
};

struct HomographyResult {
  bool ok = false;
  Eigen::Matrix3d H = Eigen::Matrix3d::Identity();  ///< x_to ~ H x_from, H(2,2) = 1
  std::vector<int> inliers;                          ///< indices into from/to
  double rms_px = 0;                                 ///< transfer error over the inliers
};

/// Robust estimate (seeded RANSAC on 4-point samples) then least-squares refinement on the
/// inliers. ok = false (never a throw) for fewer than 4 points, non-finite input, degenerate
/// (collinear) configurations or a near-singular result. Throws std::invalid_argument only when
/// opt.check() fails.
HomographyResult estimateHomography(const std::vector<Eigen::Vector2d>& from,
                                    const std::vector<Eigen::Vector2d>& to,
                                    const HomographyOptions& opt);
/// estimateHomography for callers that checked opt once (the matchers): never throws.
HomographyResult estimateHomographyUnchecked(const std::vector<Eigen::Vector2d>& from,
                                             const std::vector<Eigen::Vector2d>& to,
                                             const HomographyOptions& opt);

/// Normalised DLT followed by Gauss-Newton on the transfer error sum |x_to - H(x_from)|^2.
/// Needs >= 4 points in general position; returns a non-finite matrix when it cannot fit.
Eigen::Matrix3d fitHomographyLeastSquares(const std::vector<Eigen::Vector2d>& from,
                                          const std::vector<Eigen::Vector2d>& to);

/// Least-squares affine map (6 parameters, last row 0 0 1) minimising sum |x_to - A(x_from)|^2.
/// Needs >= 3 points not all collinear; returns a non-finite matrix when it cannot fit.
Eigen::Matrix3d fitAffineLeastSquares(const std::vector<Eigen::Vector2d>& from,
                                      const std::vector<Eigen::Vector2d>& to);

/// x_to for one point (no check for the point at infinity).
Eigen::Vector2d applyHomography(const Eigen::Matrix3d& H, const Eigen::Vector2d& x);

/// True when H is finite, well conditioned and maps the polygon (reference px, >= 3 vertices,
/// convex, any orientation) to a convex polygon with the same orientation (not flipped), all in
/// front of its vanishing line (one sign of homogeneous w), with image area >= min_area_px2.
bool homographyPlausible(const Eigen::Matrix3d& H, const std::vector<Eigen::Vector2d>& polygon,
                         double min_area_px2 = 16.0);

}  // namespace refgrasp::detector
