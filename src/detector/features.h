#pragma once
// SIFT extraction and the 2D grid index over keypoints ("2D map of pointers", paper III-B).
//
// Pixel convention: keypoint positions are in input-image pixels, centre of the top-left pixel at
// (0, 0). OpenCV's internal 2x up-sampling shifts its reported positions by +0.25 px; extractSift
// removes that bias. Keypoint angle is OpenCV's (degrees, measured in image coordinates from +u
// towards +v); size is the diameter of the keypoint neighbourhood in pixels.
#include <Eigen/Core>
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
/// effects within a few keypoint sizes of the ROI's edge.
struct ExtractRegion {
  cv::Rect roi;                 ///< input-image pixels; empty = the whole image
  double min_size_px = 0;       ///< keypoint size (diameter, input px) range
  double max_size_px = 1e30;
  bool whole() const { return roi.area() == 0 && min_size_px <= 0 && max_size_px >= 1e30; }
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
  int cellPx() const { return cell_px_; }

 private:
  int cell_px_ = 16, cols_ = 0, rows_ = 0;
  std::vector<float> x_, y_;      ///< keypoint positions, indexed like the input
  std::vector<int> cell_start_;   ///< CSR: indices of cell c are order_[cell_start_[c] .. cell_start_[c+1])
  std::vector<int> order_;
};

}  // namespace refgrasp::detector
