#pragma once
// The repeat-period tests. A reference with repeat periods (repeatPeriods: a facade's window
// spacing, a printed grid) can be matched one period off: a consensus of look-alike features
// fits a homography that passes the other checks. Two tests look a period away:
// - alignAcrossPeriods: the features matched again with the candidate moved by each period; a
//   distinct alignment with a more significant consensus is offered in its place;
// - periodAmbiguity: the instance that passed every check, moved by each period and aligned
//   there by ECC; when one of those alignments agrees with the scene clearly better, the instance is refused, or replaced when that alignment
//   agrees strongly everywhere (VerifyOptions::period_ambiguity_*, period_switch_correlation).
//
// H: undistorted reference px -> undistorted scene px. Periods are displacements in the
// reference's rectified pattern plane (ReferenceIndex::rectify_px).
#include <optional>
#include <vector>

#include "detector/registered_object.h"

namespace refgrasp::detector {

/// H moved by each of the reference's repeat periods; empty without periods or with a singular
/// rectification.
std::vector<Eigen::Matrix3d> movedByPeriods(const RegisteredObject& obj, const Eigen::Matrix3d& H);

/// A repeated motif's other alignments: cand moved by each repeat period, its features matched
/// again there. Returns a distinct alignment (corners farther apart than distinctAlignmentPx)
/// whose consensus is more significant (lower log10 NFA), or nullopt. The matcher's
/// search stops at its first candidate, which on a facade can be the consensus one window off;
/// the caller checks the alternative like any candidate and keeps it only if it correlates at
/// least as well.
std::optional<MatchCandidate> alignAcrossPeriods(const RegisteredObject& obj, const DetectorOptions& opt,
                                                 const MatchCandidate& cand, const Features& scene,
                                                 const GridIndex& grid);

struct PeriodAmbiguity {
  /// An alignment a period away agrees clearly better than the instance: correlation higher by
  /// more than period_ambiguity_margin and at least period_ambiguity_cells more strong cells.
  bool ambiguous = false;
  /// The best such alignment when it agrees strongly everywhere (9 strong cells, correlation >=
  /// period_switch_correlation): the caller matches the features there and checks it.
  std::optional<DenseRefineResult> better;
};

/// The ambiguity test of an instance that passed every check (see the header comment).
/// Alignments are ECC refinements with room to move (0.3 x the pattern's diagonal).
PeriodAmbiguity periodAmbiguity(const RegisteredObject& obj, const DetectorOptions& opt, const MatchCandidate& cand,
                                const Features& scene, const Intrinsics& camera);

}  // namespace refgrasp::detector
