#pragma once
// Photometric verification of an instance: the reference, warped into the scene by the
// instance's homography, must look like the scene there. Zero-mean normalised cross-correlation
// over the pattern polygon, both sides smoothed and compared at a coarse common resolution (so
// blur, noise, JPEG and a residual misalignment of a pixel or two barely matter; gain and offset
// do not matter at all), over the whole pattern and over each of its 3 x 3 cells.
// VerifyOptions also holds the options of the rest of the verification stage (detector/checks.h):
// re-alignment, repeat periods, the spare candidate. Why each rule exists and
// what it pays: docs/detector.md.
//
// Pixels: H maps reference px -> scene px (x_s ~ H x_r), both ideal pinhole pixels.
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

#include "core/camera.h"

namespace refgrasp::detector {

struct VerifyOptions {
  /// false: no photometric check, and none of the re-alignment and period rules below.
  bool enabled = true;
  /// Refuse an instance whose warped reference correlates less than this with the scene (and
  /// count a cell as agreeing from this on: at least half the textured cells must).
  double min_correlation = 0.25;
  /// Comparison resolution: the pattern is compared on at most this many pixels on its longer
  /// side (coarse: a pixel or two of misalignment must not decorrelate fine texture).
  int compare_px = 48;
  /// Of the pattern's 3 x 3 cells with texture, at least min_strong_cells (all of them when
  /// fewer have texture) must correlate >= strong_correlation on their own: a true instance
  /// agrees strongly over most of the pattern even when partly occluded, a shared logo or word
  /// over the cell or two it covers.
  double strong_correlation = 0.7;
  int min_strong_cells = 3;
  /// ... at least this many for a reference with repeat periods (a facade's windows, a printed
  /// grid): under a lattice map one period off, cells agree by chance wherever the motif repeats.
  /// <= min_strong_cells: no extra rule.
  int periodic_min_strong_cells = 4;

  /// Photometric re-alignment before the checks (detector/realign.h; objects whose reference
  /// allows the dense refinement): a dense alignment that converges but moves a corner further
  /// than DenseRefineOptions::max_corner_shift_px is refined with room to move, the features
  /// matched again there, and that candidate kept when the features and the scene support it
  /// better. false: off, with the period rules that follow it.
  bool realign = true;
  /// A refused dense refinement re-run with room to move (half the pattern's diagonal) becomes
  /// the instance's alignment at this ECC correlation or more: few features on a small oblique
  /// target fit a homography a few pixels off that ECC, started there, corrects. 1: never.
  double realign_trusted_correlation = 0.9;
  /// ... or below that when its warped reference verifies clearly better than the features'
  /// alignment: at least realign_verified_correlation, with realign_verified_cells strong cells,
  /// and realign_verified_gain more than at the features' homography. Never on a reference with
  /// repeat periods, where one period off verifies as well. > 1: never.
  double realign_verified_correlation = 0.85;
  double realign_verified_gain = 0.08;
  int realign_verified_cells = 8;
  /// Re-align (and run the period rules) only an instance with at least this fraction
  /// of its projected pattern inside the frame: they are measured at the pattern's corners, which
  /// a close-up puts far outside it. 0: always.
  double realign_min_in_view = 0.7;
  /// For a reference with repeat periods: the features matched again with the instance moved by
  /// each period (detector/periods.h alignAcrossPeriods); a distinct alignment with a more
  /// significant consensus that passes every check and correlates at least as well replaces it.
  bool period_rematch = true;
  /// When every candidate the matcher returned (match.max_instances) fails the checks, ask it
  /// for one more: its search stops at its first candidates, and on a facade the first can be a
  /// consensus one window off while the object comes next.
  bool spare_candidate = true;
  /// Ambiguity test (detector/periods.h periodAmbiguity): an instance that passed every check is
  /// moved by each repeat period and aligned there by ECC; when an
  /// alignment correlates more than period_ambiguity_margin better with at least
  /// period_ambiguity_cells more strong cells, the instance is refused: a confident wrong answer
  /// is worse than a miss. > 9 cells: never.
  double period_ambiguity_margin = 0.01;
  int period_ambiguity_cells = 2;
  /// ... unless that alignment agrees strongly everywhere (9 strong cells, correlation >= this)
  /// and passes every check with its features matched there: then it replaces the instance.
  /// 1.01: never (refuse only).
  double period_switch_correlation = 0.95;
  /// A pose fitted to the matched features (the dense alignment refused) whose reprojection RMS
  /// (px) exceeds this is refused: the consensus does not come from one rigid plane. 1000: never.
  double max_feature_pose_rms_px = 1.75;
  /// A candidate from the second pass (view-synthesised features, a weak region looked at again)
  /// is reported only when the dense alignment places it, for a 2D-only object and for a
  /// reference with repeat periods: there a few synthesised features fit corners several px (or
  /// a period) off while the warped reference still correlates at the verification's coarse
  /// resolution, and no other check refuses it (a 2D-only object has no pose checks; on a
  /// repeated motif a pose a period off passes them). Other 3D objects keep their feature pose,
  /// checked by the pose gap and max_feature_pose_rms_px. false: off.
  bool second_pass_needs_dense = true;
  /// Throws std::invalid_argument "VerifyOptions.<field>: <problem>".
  void check() const;
};

struct VerifyResult {
  bool ok = false;           ///< correlation >= min_correlation (false also when not computable)
  double correlation = 0;    ///< zero-mean NCC over the pattern pixels that land in the scene
  double visible_fraction = 0;  ///< of the compared pixels of the part in view, those inside the scene image
  int strong_cells = 0;      ///< 3 x 3 cells correlating >= strong_correlation on their own
  int textured_cells = 0;    ///< 3 x 3 cells with texture on both sides (those compared)
};

/// Compares the reference (pyramid: level 0 = the reference image, each next one pyrDown) inside
/// `polygon` (reference px) with the scene (CV_8UC1) under H. With a distorting scene camera H
/// ends in undistorted scene px and the scene is sampled through the distortion. Only the part of
/// the polygon in view is compared (the scene's frame mapped into the reference by H^-1, when
/// the frame lies wholly on the plane's side of its vanishing line): a pattern seen larger than
/// the frame (a close-up) is verified where it is seen, its 3 x 3 cells cut from that part. Not
/// computable (ok = false, correlation 0): an empty pyramid or scene, a non-finite H, the pattern
/// crossing the vanishing line, less in view than a quarter of the pattern (of the frame, for a
/// pattern larger than the frame), or a flat (textureless) comparison.
VerifyResult verifyInstance(const std::vector<cv::Mat>& ref_pyramid, const std::vector<Eigen::Vector2d>& polygon,
                            const cv::Mat& scene, const Intrinsics& scene_camera, const Eigen::Matrix3d& H,
                            const VerifyOptions& opt);

}  // namespace refgrasp::detector
