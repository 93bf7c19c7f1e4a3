#pragma once
// Dense photometric refinement of a matched homography: ECC (cv::findTransformECC,
// MOTION_HOMOGRAPHY, zero-mean normalised so gain/offset invariant) between the reference image at
// the pyramid level whose resolution best matches the target's size in the scene and a crop of the
// scene around the projected pattern, started from the feature homography. Every pixel of the
// pattern contributes, so small targets (few keypoints) get a far better H than from SIFT alone.
//
// Pixels: H maps reference px -> scene px (centre of the top-left pixel at (0,0)). Both images must
// be ideal pinhole images: Detector::refineDense resamples a distorted scene around the pattern
// onto the undistorted grid first.
#include <Eigen/Core>
#include <array>
#include <opencv2/core.hpp>
#include <vector>

namespace refgrasp::detector {

struct DenseRefineOptions {
  bool enabled = true;               ///< refine H photometrically (before the refined pose; 2D-only objects: their H)
  int max_iterations = 20;           ///< ECC iterations
  double epsilon = 1e-4;             ///< ECC stop: change of the correlation coefficient per iteration
  int max_template_px = 16384;       ///< coarser pyramid level until the template fits (speed)
  double max_corner_shift_px = 3.0;  ///< reject (keep the feature H) if a corner moves more
  double min_correlation = 0.5;      ///< reject below this final ECC correlation coefficient
  int gauss_filter_size = 1;         ///< ECC pre-smoothing kernel (odd, >= 1)
  /// Second attempt on locally normalised intensities when the raw alignment is refused or
  /// correlates less than raw_trusted_correlation: both the template and the scene become
  /// (I - local mean) / sqrt(local variance + 5^2) (Gaussian window of this sigma, template px at
  /// the level used; the 5 gray levels keep flat areas' noise from being amplified). ECC absorbs
  /// one gain and offset only; a photographed reference's light gradient, highlight and
  /// vignetting pull the raw alignment off while it still converges. Only a retry: on clean
  /// renders the raw alignment is the more precise one. 0: no retry.
  double normalize_sigma_px = 2.0;
  /// A raw alignment correlating at least this is kept without the retry (the gain-and-offset
  /// model explains the scene).
  double raw_trusted_correlation = 0.9;
  /// The retry's result replaces the raw one only when its correlation (of normalised
  /// intensities, lower than raw ones for the same fit) reaches this, besides min_correlation:
  /// lower, a partly occluded pattern can be aligned several degrees off.
  double normalized_min_correlation = 0.7;
  /// 2D-only objects: the dense H gives the corners only when the template it was aligned at (the
  /// pyramid level max_template_px allows) is at most this many times coarser, linearly, than
  /// the pattern in the scene (2: one octave); a large target's many features fit its 8
  /// parameters better than the capped template does.
  double max_2d_coarsening = 2.0;
  int pose_grid = 8;                 ///< pose from a pose_grid x pose_grid grid mapped by the H
  /// Robust to occluders: after ECC converges, template blocks of robust_block_px whose residual
  /// (normalised intensities) exceeds max(robust_min_residual, 3 x the median block's), and
  /// their neighbours (partly covered), are left out and ECC runs again from there (twice);
  /// refused when less than robust_min_kept of the template is left. Off in detection (the
  /// detector's results stay as they are); the tracker's alignment turns it on.
  bool robust = false;
  int robust_block_px = 8;
  double robust_min_residual = 0.5;
  double robust_min_kept = 0.3;
  /// Throws std::invalid_argument "DenseRefineOptions.<field>: <problem>".
  void check() const;
};

/// Reference pyramid: level 0 = the image, level k = cv::pyrDown of level k-1 (a level-k pixel
/// (u, v) sits at level-0 (2^k u, 2^k v)). Stops when a side would drop below min_side_px.
std::vector<cv::Mat> buildReferencePyramid(const cv::Mat& gray, int min_side_px = 16);

struct DenseRefineResult {
  bool ok = false;
  Eigen::Matrix3d H = Eigen::Matrix3d::Identity();  ///< refined (== input when !ok)
  int level = -1;                ///< pyramid level used
  double correlation = 0;        ///< final ECC coefficient
  double corner_shift_px = 0;    ///< largest corner displacement refined vs input H
  /// robust: fraction of the template found off the image or occluded (the fit leaves a band
  /// of blocks around the occluded ones out as well)
  double masked_fraction = 0;
};

/// Refines H (reference px -> scene px) over the axis-aligned pattern rectangle `pattern_rect`
/// (reference px, corners TL, TR, BR, BL; the template is its bounding box). Returns ok = false
/// (and the input H) when ECC fails, diverges, moves a corner more than max_corner_shift_px or ends
/// below min_correlation. scene: CV_8UC1.
/// mask_polygon (reference px, inside pattern_rect): only the template pixels inside it count
/// (a pattern region that is not a rectangle, e.g. traced on an oblique photo); null: all.
DenseRefineResult refineHomographyDense(const std::vector<cv::Mat>& ref_pyramid,
                                        const cv::Mat& scene, const Eigen::Matrix3d& H,
                                        const std::array<Eigen::Vector2d, 4>& pattern_rect,
                                        const DenseRefineOptions& opt,
                                        const std::vector<Eigen::Vector2d>* mask_polygon = nullptr);

}  // namespace refgrasp::detector
