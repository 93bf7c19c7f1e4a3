#pragma once
// Ablation of the detector's verification stage (detector/checks.h): each check switched off in
// turn on the project's development data, to show what it pays. Every frame is rendered once and
// given to every variant. Data:
// - realistic sets (realistic_eval.h), every set of each seed, objects registered with their
//   reference pose (3D) and without it (2D-only, scored on the corners);
// - photo pairs (pairs_eval.h), 2D, scored on the worst corner;
// - photo clutter with every object of the photos and procedural sets registered (false
//   detections only).
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "detector/detector.h"

namespace refgrasp::eval {

/// One rule of the verification stage switched off (the first variant: none).
struct AblationVariant {
  std::string name;  ///< short label, e.g. "no trusted wide alignment"
  std::string off;   ///< the option values that switch it off, e.g. "verify.realign_trusted_correlation: 1"
  std::function<void(detector::DetectorOptions*)> apply;
};

/// "all checks" first, then each rule of the verification stage off in turn, then the matcher's
/// view-synthesised reference features off (MatchOptions::plane_views; on top of `base`).
std::vector<AblationVariant> verificationAblation();

struct AblationData {
  std::vector<uint64_t> seeds = {1, 3, 5, 9};  ///< realistic-set splits (photos, procedural, far_oblique each)
  int frames_per_set = 160;
  bool two_d = true;           ///< also run every realistic frame with the object registered 2D-only
  int pair_seeds = 1;          ///< photo-pair splits, from pair_first_seed
  uint64_t pair_first_seed = 1;
  int clutter_frames = 100;    ///< photo clutter frames (seed: the first realistic seed)
  /// Throws std::invalid_argument "AblationData.<field>: <problem>".
  void check() const;
};

/// One variant's figures over the data (3D and 2D realistic frames, pairs, clutter).
struct AblationCounts {
  int frames_3d = 0, found_3d = 0, pose_ok_3d = 0, wrong_3d = 0;
  int frames_2d = 0, found_2d = 0, within_3px_2d = 0, wrong_2d = 0;  ///< within: worst corner <= 3 px
  int pairs = 0, pairs_within_3px = 0, pairs_wrong = 0;               ///< wrong: worst corner > 30 px
  int clutter_frames = 0, clutter_false = 0;
  /// Frames and pairs whose outcome (found, pose ok, wrong, within 3 px) differs from the first
  /// variant's, and reports whose homography differs from it (the rule acted there).
  int changed = 0, moved = 0;
  double median_ms = 0;       ///< thread CPU time per 3D realistic frame, median
  double mean_checks_ms = 0;  ///< of which the pose and the checks (DetectionTimings::pose), mean
};

/// Runs every variant on the data with `threads` worker threads (one OpenCV thread each: call
/// cv::setNumThreads(1) first). progress(done, total) after each frame or pair.
std::vector<AblationCounts> runAblation(const std::vector<AblationVariant>& variants, const AblationData& data,
                                        int threads, const std::function<void(int, int)>& progress = {});

/// A markdown table: one row per variant, the figures and their difference to the first row.
std::string formatAblation(const std::vector<AblationVariant>& variants, const std::vector<AblationCounts>& counts);

}  // namespace refgrasp::eval
