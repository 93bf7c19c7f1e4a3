#pragma once
// Verification of an accepted instance (issue 7): a wrong geometry that found enough consistent
// matches (a shared logo, a repeated motif, clutter) must still be refused. The reference,
// warped into the scene by the instance's homography, must look like the scene there:
// zero-mean normalised cross-correlation over the pattern polygon, both sides smoothed and
// compared at a coarse common resolution (so blur, noise, JPEG and a residual misalignment of a
// pixel or two barely matter; gain and offset do not matter at all).
//
// Pixels: H maps reference px -> scene px (x_s ~ H x_r), both ideal pinhole pixels.
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

#include "core/camera.h"

namespace refgrasp::detector {

struct VerifyOptions {
  bool enabled = true;
  /// Refuse an instance whose warped reference correlates less than this with the scene.
  double min_correlation = 0.25;
  /// Comparison resolution: the pattern is compared on at most this many pixels on its longer side.
  int compare_px = 48;
  /// Of the pattern's 3 x 3 cells with texture, at least min_strong_cells (or all of them when
  /// fewer have texture) must correlate >= strong_correlation on their own: a true instance agrees
  /// strongly over most of the pattern even when partly occluded (>= 4 cells on the realistic
  /// sets), a shared logo or word over the cell or two it covers (<= 2 on photo clutter).
  double strong_correlation = 0.7;
  int min_strong_cells = 3;
  /// ... and at least this many (or all with texture) for a reference with repeat periods
  /// (repeatPeriods: a facade's windows, a printed grid). On a repeated motif a homography that
  /// maps the lattice onto itself wrongly (a period off, or turned onto it) has cells agreeing
  /// by chance wherever the motif repeats. On the development seeds (bench_realistic
  /// --clutter 0: 3D seeds 33-45, 2D-only seeds 1-21, before the rule) the reports of periodic
  /// references with 3 strong cells were all wrong (2: facades 20 and 110 px off), those with 4
  /// right 5 times in 8, with 5 or more 642 times in 648; a reference without periods keeps
  /// min_strong_cells (its reports with 3 strong cells: 3 right, 3 wrong). <= min_strong_cells
  /// changes nothing.
  int periodic_min_strong_cells = 4;
  /// Photometric re-alignment before the checks (3D objects with a dense-usable reference): when
  /// the dense refinement of an instance converges but moves the pattern further than
  /// DenseRefineOptions::max_corner_shift_px, the instance is aligned again photometrically with
  /// room to move (half its diagonal), its features matched again there (matchUnderHomography),
  /// and the result replaces it when the features support it as well (as many inliers, or a
  /// log10 NFA as low) and it correlates better. A consensus one period off on a repeated motif
  /// (a facade's windows) fits a stretched homography that passes every other check. Then, for a
  /// reference with repeat periods (repeatPeriods), the instance moved by each period is matched
  /// again too, and a distinct alignment with a more significant consensus (lower log10 NFA)
  /// that correlates at least as well replaces it.
  bool realign = true;
  /// When the re-alignment keeps (or ends with) a candidate whose dense refinement is refused for
  /// moving a corner too far, that refinement is run again with room to move (half the pattern's
  /// diagonal), and its alignment becomes the instance's (homography and pose) when its ECC
  /// correlation is at least this. Few features on a small, oblique target fit a homography a
  /// few pixels off that ECC, started there, corrects: on the development seeds such a wide
  /// alignment at >= 0.9 had the better corners 3 times in 4 (typically from 2-8 px to under 1),
  /// and fixed a magazine reported 11 px off. 1: never (the features' alignment is kept).
  double realign_trusted_correlation = 0.9;
  /// ... or, below that ECC correlation, when its warped reference verifies clearly better than
  /// the features' alignment: verifyInstance at the wide alignment correlates at least
  /// realign_verified_correlation, with at least realign_verified_cells strong cells, and at
  /// least realign_verified_gain more than at the features' homography. A far target's few
  /// features fit a homography 5-25 px off that ECC, started there, brings within a pixel or two
  /// at correlation 0.7-0.9: on the development seeds (bench_realistic --clutter 0, 3D seeds
  /// 33-45, 2D-only seeds 1-21, 6720 frames) the rule moved 28 reports, 27 of them closer (a
  /// right one 3.8 -> 4.6 px), took 7 wrong reports to within 3.5 px, found one more and lost
  /// none; on the same reports a correlation floor of 0.8 would have moved one right report
  /// off, a gain of 0.05 two. Not for a reference with repeat periods (a facade): there a
  /// consensus one period off verifies as well as the right one, and on the report split the
  /// rule took a facade a period off (21 px) from refused to reported. > 1: never.
  double realign_verified_correlation = 0.85;
  double realign_verified_gain = 0.08;
  int realign_verified_cells = 8;
  /// The re-alignment (and the repeat-period and peak tests that come with it) only for an
  /// instance with at least this fraction of its projected pattern inside the frame: its trigger
  /// and its acceptance are measured at the pattern's corners, which a close-up (a pattern
  /// larger than the frame) puts far outside it, where a photometric alignment of the part in
  /// view extrapolates poorly. On photo pairs zoomed 1.3-2.9x (bench_pairs) the re-alignment
  /// moved features' corners within 1.5 px to 4-13 px off. 0: always.
  double realign_min_in_view = 0.7;
  /// When every candidate the matcher returned (match.max_instances of them) fails the checks,
  /// ask it for one more and check the new one too: the search stops at its first candidates,
  /// and on a facade the first can be a consensus one window off that the pose check refuses
  /// while the right one, with fewer matches, comes next.
  bool spare_candidate = true;
  /// Repeat-period ambiguity (3D objects whose reference has repeat periods, with realign): an
  /// instance that passed every check is moved by each repeat period, aligned there
  /// photometrically (dense refinement with room to move, 0.3 x its diagonal) and verified
  /// (verifyInstance). When one of those alignments agrees with the scene clearly better than
  /// the instance itself (correlation higher by more than period_ambiguity_margin and at least
  /// period_ambiguity_cells more strong cells), the features' alignment is in doubt and the
  /// instance is refused (a miss, "not verified"): on a facade a consensus one window off passes
  /// every other check, and a confident wrong answer is worse than a miss. On the development
  /// seeds every such wrong report had fewer strong cells than the truth. period_ambiguity_cells
  /// > 9: never.
  double period_ambiguity_margin = 0.01;
  int period_ambiguity_cells = 2;
  /// ... unless that alignment agrees strongly everywhere (9 strong cells, correlation >= this),
  /// the features match again under it (matchUnderHomography) and it passes every check: then it
  /// replaces the instance (homography and pose from the alignment). 1.01: never (refuse only).
  double period_switch_correlation = 0.95;
  /// Photometric peak search (with realign, any 3D object with a dense-usable reference): the
  /// instance that passed every check is compared, by masked zero-mean NCC of its warped
  /// reference (48 px on the diagonal), with the scene at every translation up to
  /// peak_search_reach x its diagonal; the best peak_search_count local maxima more than 3 px
  /// away that correlate better than the instance's own place by more than peak_search_margin
  /// join the repeat periods' moves in the ambiguity test above (aligned by ECC there, refused or
  /// replaced by the same rules). A few features on a small target fit a homography several
  /// pixels off that passes every check while a better alignment lies beside it, out of ECC's
  /// reach from there (development seed 19 photos/47: fruits 11 px off, refused). 0: off.
  /// A pose fitted to the matched features (the refined method when the dense alignment was
  /// refused) whose reprojection RMS exceeds this is refused: the consensus does not come from
  /// one rigid plane. On the development splits (2700 right reports, 250 of them with such a pose)
  /// every right one was <= 1.49 px; a facade consensus spanning two windows, 47 px off, 2.1 px.
  double max_feature_pose_rms_px = 1.75;
  int peak_search_count = 2;
  double peak_search_reach = 0.7;
  double peak_search_margin = 0.05;
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
