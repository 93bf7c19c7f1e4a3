#pragma once
// Matching reference features to a scene: the paper's local-geometric-consistency matcher
// (Section III-B) and the usual ratio-test + robust homography baseline. Both start from the
// global 2-NN (knn.h) against the object's reference index (reference_index.h).
//
// Frames: "reference px" are pixels of the reference image (possibly undistorted by the caller),
// "scene px" pixels of the scene image. Every homography maps reference px to scene px:
// x_s ~ H x_r.
#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "detector/features.h"
#include "detector/reference_index.h"

namespace refgrasp::detector {

enum class MatcherType { kPaper, kRatio };

/// Weak regions a match result keeps (MatchResult::weak).
constexpr int kMaxWeakRegions = 4;

struct MatchOptions {
  MatcherType matcher = MatcherType::kPaper;
  double global_ratio = 0.8;           ///< Lowe ratio for global matches (seeds / baseline)
  double local_ratio = 0.7;            ///< ratio between best and second-best local candidate
  /// Local search radius = factor x expected localisation error of the hypothesis (see
  /// matchObject: 2 px + 0.1 x scene distance from the seed under T^k).
  double search_radius_factor = 2.0;
  double orientation_tolerance_rad = M_PI / 3;  ///< |o_s - predicted o| bound
  double scale_tolerance = 0.5;        ///< |s_s - predicted s| <= scale_tolerance * predicted s
  int max_hypotheses = 200;            ///< cap on hypotheses given a local search
  int max_reference_features = 1000;   ///< cap: strongest by response, round robin over octaves
  /// Floor on the homography inliers of an instance; above it the a-contrario test decides.
  int min_inliers = 8;
  /// A-contrario acceptance (AC-RANSAC / ORSA, Moisan and Stival): an instance is accepted when
  /// its consensus has log10 NFA <= max_log10_nfa, the number of false alarms of k matches within
  /// eps px of their prediction among the n reference features tested, when scene features fall
  /// at random (their number and the area they fall in give the density) and pass the local
  /// match's orientation, scale and descriptor tests by chance (frequencies measured per frame).
  /// +inf: min_inliers alone decides (the count rule). -6, not the textbook 0: the model's
  /// independence assumptions overstate the significance of a few matches on real images, and
  /// right 8-inlier consensuses score well below -6 while chance ones reach (-6, 0]
  /// (docs/detector.md).
  double max_log10_nfa = -6.0;
  double ransac_reproj_px = 3.0;
  int max_instances = 1;               ///< disjoint instances reported per object
  /// Local matches farther than this in descriptor space are never accepted (OpenCV SIFT
  /// descriptors have L2 norm ~512; unrelated features are typically 350-450 apart, true matches
  /// of small blurred targets up to ~350).
  double max_descriptor_distance = 350;
  /// An instance's inliers must spread over at least this fraction of the area spanned by all
  /// reference features (convex hulls, reference px): a shared word or logo is not the object.
  double min_inlier_spread = 0.05;
  /// Small instances get the plane-affine homography: when the pattern spans less than this
  /// (square root of its projected area, scene px), the reference's pattern plane (rectified with
  /// the reference pose; the reference itself for 2D-only objects) maps affinely into the scene
  /// (6 parameters), unless the inliers need the homography's 2 perspective parameters (F test
  /// at 0.1 %). Over a small pattern the perspective is below ~2 px at f = 500 px, and a few
  /// matches leave it poorly determined (corners several px off). 0: always the full homography.
  double affine_below_px = 64;
  /// Cylinder objects (cylinder model): the label's features also as the label looks turned away
  /// and from further off, view-synthesised (detector/cylinder_views.h), in both of its indices.
  bool cylinder_views = true;
  /// Planar objects: the reference's features also as the pattern looks tilted (45 and 60 deg
  /// about axes in its plane, and fronto-parallel) and from further off (80 and 40 px large),
  /// view-synthesised (detector/plane_views.h), in a second index matched when the object's own
  /// features find nothing in a frame. On: far and oblique faces share few descriptors with a
  /// reference photographed at another angle; second: where the own features find the object,
  /// their fit is the more precise (docs/detector.md).
  bool plane_views = true;
  /// Weak evidence looked at again: when nothing is accepted in a frame, the predicted pattern
  /// boxes of up to this many hypotheses with a few local matches (MatchResult::weak) get SIFT
  /// again at weak_contrast_threshold, and those features are matched and checked as the
  /// frame's. 0: off. A small, blurred pattern's DoG extrema fall below the frame's contrast
  /// threshold; a lower one over the whole frame costs about a fifth more extraction time
  /// (docs/detector.md), over a box only where something already points.
  int weak_regions = 2;
  /// SIFT contrast threshold (gray levels / 255, as SiftOptions) of the weak regions' extraction,
  /// (0, 1); half the frame's default 0.04: the extrema of a 30-50 px pattern after blur.
  double weak_contrast_threshold = 0.02;
  uint64_t seed = 0;
  /// Throws std::invalid_argument on nonsense.
  void check() const;
};

struct Correspondence {
  int ref;                    ///< index into ReferenceIndex::features
  int scene;                  ///< index into the scene Features
  float descriptor_distance;  ///< L2 distance between the SIFT descriptors
};

struct MatchCandidate {
  std::vector<Correspondence> inliers;  ///< homography inliers
  Eigen::Matrix3d H = Eigen::Matrix3d::Identity();  ///< reference px -> scene px: x_s ~ H x_r
  /// eq. 3 over the inliers: mean of |x_s - H x_r| (px) x descriptor distance; lower is better.
  double score = 0;
  double log10_nfa = 0;  ///< a-contrario significance of the consensus (lower is stronger)
};

/// How many hypotheses (paper) or robust fits (ratio; re-fits in the selection) ended at each
/// stage without giving a candidate.
struct MatchRejects {
  int too_few_local_matches = 0;   ///< paper: the local search found too few consistent matches
  int too_few_inliers = 0;         ///< robust homography with < min_inliers inliers, or none
  int not_significant = 0;         ///< consensus with log10 NFA > max_log10_nfa
  int implausible_homography = 0;  ///< flipped, non-convex, near-singular or tiny pattern
  int narrow_inlier_spread = 0;    ///< inliers span < min_inlier_spread of the reference
};

/// A hypothesis that reached 5 or more local matches but gave no candidate, for a pattern
/// predicted at most 128 px across (diagonal): where it put the pattern.
struct WeakRegion {
  cv::Rect2d box;         ///< scene px: the pattern's bounding square under the seed's similarity, grown by half
  int local_matches = 0;  ///< local matches its search reached (the most over its passes)
};

struct MatchResult {
  /// Best first, disjoint in the scene, each with >= min_inliers and a plausible H.
  std::vector<MatchCandidate> instances;
  /// paper matcher: weak evidence, most local matches first, none centred in a stronger one's
  /// box, at most kMaxWeakRegions (the detector looks again at opt.weak_regions of them).
  std::vector<WeakRegion> weak;
  int hypotheses_evaluated = 0;  ///< hypotheses given a local search (paper) / 1 (ratio)
  int global_matches = 0;        ///< scene features passing the global ratio test
  MatchRejects rejected;
};

/// Finds up to opt.max_instances instances of the reference in the scene. grid must index
/// scene.keypoints. An empty result is the normal "not found".
///
/// kRatio: global matches (scene -> reference nearest neighbour, ratio < global_ratio), robust
/// homography, accepted by the same rules as step 3 below; for more instances remove the
/// inliers and repeat.
///
/// kPaper (Section III-B):
///  1. Global matches as above seed hypotheses T^k (eq. 1-2: scale s' = size_s/size_r, rotation
///     o' = angle_s - angle_r, T^k(x) = s'R(o')(x - x_r) + x_s). Scene features whose two nearest
///     reference features are both close but too alike for the ratio test (twins in repeated or
///     symmetric patterns) seed one hypothesis per twin, tried after all unambiguous seeds.
///     Seeds are ordered by the size of their Hough cluster (predicted centre, scale octave,
///     30 degree orientation), then by ratio.
///  2. Local search for a hypothesis: each reference feature is predicted in the scene; among
///     scene features within radius = search_radius_factor x expected error, with orientation
///     within orientation_tolerance_rad and size within scale_tolerance x predicted size, the
///     descriptor-nearest is taken if it is closer than max_descriptor_distance and passes
///     local_ratio against the second. "Expected error" of T^k is 2 px + 0.1 x the scene
///     distance from the seed (one keypoint's scale/orientation error and perspective grow
///     with distance). The search grows: a quick test on the seed's 40 nearest detectable
///     reference neighbours (>= 4 local matches), pass 1 on its 200 nearest (>= 6), then two
///     passes over all features under the homography fitted to the previous pass (expected
///     error max(2 px, rms) + 0.03 x distance from the seed, then max(2 px, rms)).
///  3. The last pass's matches give a robust homography (inliers then tightened to 3 sigma of
///     the fit, min 1 px, and re-fitted); it is a candidate when it has
///     >= min_inliers inliers, a significant consensus (log10 NFA <= max_log10_nfa, see
///     MatchOptions), a plausible H (homographyPlausible on the pattern hull) and
///     inliers spanning >= min_inlier_spread of the reference. Its score is eq. 3.
///  4. Collapse: seeds whose scene feature is an inlier of a candidate, or that a candidate's H
///     already explains (within 2 x ransac_reproj_px), are not tried again. At most
///     max_hypotheses seeds are tried; once max_instances candidates exist, lone seeds (and
///     twin seeds, unless every candidate came from twins) end the search.
///  5. Selection: a candidate overlapping (> 25% of the smaller projected pattern) another with
///     more than twice its inliers is dropped, so few matches never beat many; the rest are
///     ranked by eq. 3 (lower first) and taken greedily without overlap, scene features used
///     once (a candidate losing features is re-fitted and re-checked).
/// Throws std::invalid_argument when opt.check() fails.
MatchResult matchObject(const ReferenceIndex& ref, const Features& scene, const GridIndex& grid,
                        const MatchOptions& opt);
/// matchObject for callers that checked opt once (the Detector, per frame): never checks.
MatchResult matchObjectUnchecked(const ReferenceIndex& ref, const Features& scene,
                                 const GridIndex& grid, const MatchOptions& opt);

/// The paper matcher's local search (step 2) from a given alignment H (reference px -> scene px,
/// e.g. a photometric one) instead of a seed's hypothesis, over all reference features, twice:
/// one pass within search_radius_factor x 1 px of the predictions under H (a precise alignment;
/// a wider radius takes the neighbours one period away on a repeated motif, and their consensus
/// comes back), and evaluateHypothesis's last two passes (x 2 px, a homography fitted to those
/// matches, then x max(2 px, its rms)) for an alignment right but not everywhere precise. Each
/// gives a candidate by step 3's rules (min_inliers, a-contrario test, plausibility, spread);
/// the more significant (lower log10 NFA) is returned, nullopt when the features support no
/// instance there (or H is not finite). Never checks opt.
std::optional<MatchCandidate> matchUnderHomography(const ReferenceIndex& ref, const Features& scene,
                                                   const GridIndex& grid, const MatchOptions& opt,
                                                   const Eigen::Matrix3d& H);
/// RMS distance (scene px) between cand's inlier scene features and their reference features
/// mapped by cand.H: how precisely the features locate the pattern; 0 without inliers.
double inlierRmsPx(const ReferenceIndex& ref, const Features& scene, const MatchCandidate& cand);
/// A feature fit refitted to more features (checks.cpp: a 2D-only pattern's corners).
struct FeatureRefit {
  Eigen::Matrix3d H = Eigen::Matrix3d::Identity();  ///< reference px -> scene px
  int matches = 0;                                  ///< the matches it was fitted to
};
/// The final fit of an alignment H that is already precise (its features' own fit), over every
/// feature of `ref` (ReferenceIndex::uncapped when given: the strongest features alone are few
/// of the fine, best localised ones on a large reference): the local search within radius_px of
/// the predictions under H (the matcher's orientation, scale, descriptor and local-ratio tests,
/// one reference feature per scene feature), the homography least-squares fitted to those
/// matches (plane-affine for a small pattern, as the matcher fits), tightened to 3 sigma of that
/// fit and fitted again. nullopt under opt.min_inliers matches or when a fit fails.
std::optional<FeatureRefit> refitUnderHomography(const ReferenceIndex& ref, const Features& scene,
                                                 const GridIndex& grid, const MatchOptions& opt,
                                                 const Eigen::Matrix3d& H, double radius_px);
/// matchUnderHomography for several alignments at once (the frame's background model is
/// measured once); out[k] for Hs[k].
std::vector<std::optional<MatchCandidate>> matchUnderHomographies(const ReferenceIndex& ref, const Features& scene,
                                                                  const GridIndex& grid, const MatchOptions& opt,
                                                                  const std::vector<Eigen::Matrix3d>& Hs);

}  // namespace refgrasp::detector
