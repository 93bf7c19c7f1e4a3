#pragma once
// SIFT extraction and the 2D grid index over keypoints ("2D map of pointers", paper III-B).
//
// Pixel convention: keypoint positions are in input-image pixels, centre of the top-left pixel at
// (0, 0). OpenCV's internal 2x up-sampling shifts its reported positions by +0.25 px; extractSift
// removes that bias. Keypoint angle is OpenCV's (degrees, measured in image coordinates from +u
// towards +v); size is the diameter of the keypoint neighbourhood in pixels.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <utility>
#include <opencv2/core.hpp>
#include <vector>

namespace refgrasp::detector {

/// Which SIFT computes the features. kOpenCV: cv::SIFT (OpenCV 4.6), the reference. kFast: the
/// project's own SIMD re-implementation of the same algorithm (sift_fast.h), proven equivalent by
/// tests/detector/test_sift_fast.cpp and several times faster.
enum class SiftImplementation { kOpenCV, kFast };

/// The default SiftOptions::implementation: kFast, unless the environment variable
/// REFGRASP_SIFT=opencv is set (read once; for A/B runs of a whole test suite or app on the
/// reference). Any other value than "opencv" or "fast" is ignored.
SiftImplementation defaultSiftImplementation();

struct SiftOptions {
  SiftImplementation implementation = defaultSiftImplementation();
  /// kFast only: 1 = the extraction runs on the calling thread only (frames pipelined one per
  /// core); any other value = its keypoint stages also use OpenCV's thread pool
  /// (cv::getNumThreads() threads). cv::SIFT always uses OpenCV's pool.
  int threads = 0;
  int max_features = 0;             ///< keep the strongest N by response; 0 = all
  int octave_layers = 3;            ///< scales per octave
  double contrast_threshold = 0.04;
  double edge_threshold = 10;
  double sigma = 1.6;               ///< Gaussian sigma of the base octave
  /// The paper's initial 2x up-sampling (OpenCV always up-samples internally; false runs SIFT on
  /// the image down-sampled by 2 so that its first octave has the input's resolution).
  bool upsample = true;
  /// Throws std::invalid_argument on nonsense.
  void check() const;
};

struct Features {
  std::vector<cv::KeyPoint> keypoints;  ///< pt in input-image pixels
  cv::Mat descriptors;                  ///< CV_32F, N x 128, row i describes keypoints[i]
  cv::Size image_size;                  ///< size of the image the features were extracted from
  /// The 8-bit gray image itself (shared, not copied) when the caller kept it (Detector::extract
  /// does, for the dense homography refinement); may be empty.
  cv::Mat image;
  int size() const { return static_cast<int>(keypoints.size()); }
};

/// Where to look: a region of interest and a keypoint size range (re-detection around a predicted
/// target). Keypoints are still reported in full-image pixels. An extractor may use the region to
/// skip work (crop, skip octaves); the result is the full-image extraction restricted to keypoints
/// whose centre lies in `roi` and whose size lies in [min_size_px, max_size_px], up to border
/// effects within a few keypoint sizes of the ROI's edge (plus inner_margin_px).
struct ExtractRegion {
  cv::Rect roi;                 ///< input-image pixels; empty = the whole image
  double min_size_px = 0;       ///< keypoint size (diameter, input px) range
  double max_size_px = 1e30;
  /// The region's own margin (px): the keypoints that must come out as in the whole image lie at
  /// least this far inside roi (e.g. a predicted pattern's box grown by a margin), so the
  /// context the crop adds around roi for them is reduced by it. 0: every keypoint in roi.
  double inner_margin_px = 0;
  /// >= 1: the crop is resampled to 1/downsample of its size (area average) before SIFT, for a
  /// region whose pattern is predicted larger than its features need (ObjectPrior::max_scale).
  /// Positions and sizes are still reported in input px; 1 = the input's resolution.
  double downsample = 1;
  bool whole() const { return roi.area() == 0 && min_size_px <= 0 && max_size_px >= 1e30 && downsample == 1; }
};

/// Deterministic SIFT on an 8-bit grayscale image (CV_8UC1; colour is converted).
/// Throws std::invalid_argument on an empty image, opt.check() failure or a non-finite / inverted
/// size range. A ROI is clipped to the image; one outside it gives no features.
Features extractSift(const cv::Mat& gray, const SiftOptions& opt, const ExtractRegion& region = {});
/// extractSift without opt.check(), for callers that checked opt once (the Detector, per frame).
Features extractSiftUnchecked(const cv::Mat& gray, const SiftOptions& opt,
                              const ExtractRegion& region = {});

/// Uniform grid of keypoint indices for radius queries. Keypoints outside the image are clamped
/// into the border cells (still found by an exact distance test).
class GridIndex {
 public:
  GridIndex() = default;
  GridIndex(const std::vector<cv::KeyPoint>& kps, cv::Size image_size, int cell_px = 16);
  /// Appends (after clearing *out) the indices i with |kps[i].pt - centre| <= radius_px.
  void radiusSearch(const Eigen::Vector2d& centre, double radius_px, std::vector<int>* out) const;
  /// Replaces *out with the k indices i with accept(i), nearest to keypoint `self` first (ties by
  /// index, `self` before every other point at distance 0): exactly the first k of a full sort by
  /// (squared distance, index) filtered by accept. Walks the cells in rings around `self` and
  /// stops once k accepted points lie closer than every unvisited cell.
  template <class Accept>
  void nearest(int self, int k, Accept accept, std::vector<int>* out) const;
  int cellPx() const { return cell_px_; }

 private:
  int cell_px_ = 16, cols_ = 0, rows_ = 0;
  std::vector<float> x_, y_;      ///< keypoint positions, indexed like the input
  std::vector<int> cell_start_;   ///< CSR: indices of cell c are order_[cell_start_[c] .. cell_start_[c+1])
  std::vector<int> order_;
};

template <class Accept>
void GridIndex::nearest(int self, int k, Accept accept, std::vector<int>* out) const {
  out->clear();
  const int n = static_cast<int>(x_.size());
  if (self < 0 || self >= n || k <= 0) return;
  const double x = x_[self], y = y_[self];
  const int cx = std::clamp(static_cast<int>(std::floor(x / cell_px_)), 0, cols_ - 1);
  const int cy = std::clamp(static_cast<int>(std::floor(y / cell_px_)), 0, rows_ - 1);
  std::vector<std::pair<double, int>> cand;  // (squared distance, index)
  cand.reserve(static_cast<size_t>(4 * k));
  auto visit = [&](int gx, int gy) {
    const int c = gy * cols_ + gx;
    for (int q = cell_start_[c]; q < cell_start_[c + 1]; ++q) {
      const int i = order_[q];
      if (!accept(i)) continue;
      const double dx = x_[i] - x, dy = y_[i] - y;
      cand.emplace_back(dx * dx + dy * dy + (i == self ? -1.0 : 0.0), i);
    }
  };
  const int last_ring = std::max({cx, cols_ - 1 - cx, cy, rows_ - 1 - cy});
  for (int ring = 0; ring <= last_ring; ++ring) {
    for (int gy = cy - ring; gy <= cy + ring; ++gy) {
      if (gy < 0 || gy >= rows_) continue;
      const bool edge_row = gy == cy - ring || gy == cy + ring;
      for (int gx = cx - ring; gx <= cx + ring; gx += (edge_row || ring == 0) ? 1 : 2 * ring)
        if (gx >= 0 && gx < cols_) visit(gx, gy);
    }
    if (static_cast<int>(cand.size()) < k) continue;
    // Unvisited points lie outside the visited square of cells (clamping into border cells keeps
    // that true), so every candidate strictly closer than its border is final.
    const double safe = std::min({x - (cx - ring) * static_cast<double>(cell_px_),
                                  (cx + ring + 1) * static_cast<double>(cell_px_) - x,
                                  y - (cy - ring) * static_cast<double>(cell_px_),
                                  (cy + ring + 1) * static_cast<double>(cell_px_) - y});
    int final_count = 0;
    for (const auto& c : cand) final_count += (safe > 0 && c.first < safe * safe) ? 1 : 0;
    if (final_count >= k) break;
  }
  const size_t m = std::min(cand.size(), static_cast<size_t>(k));
  std::partial_sort(cand.begin(), cand.begin() + static_cast<std::ptrdiff_t>(m), cand.end());
  out->reserve(m);
  for (size_t q = 0; q < m; ++q) out->push_back(cand[q].second);
}

}  // namespace refgrasp::detector
