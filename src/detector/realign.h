#pragma once
// Photometric re-alignment (VerifyOptions::realign): decides whether a candidate's homography,
// fitted to its matched features, is replaced by a photometric alignment before the checks run.
//
// The dense (ECC) refinement of a candidate normally moves the pattern by a pixel or two. When
// it converges well but wants to move a corner further than dense.max_corner_shift_px, the
// features' alignment is doubtful: on a repeated motif (a facade's windows) a consensus of
// matches one period off fits a stretched homography, and on a small oblique target a few
// features fit one a few pixels off. Then the alignment is refined again with room to move
// (half the pattern's diagonal), the features are matched again under it, and that candidate
// replaces the original when the features support it as well (at least as many inliers, or a
// consensus at least as significant: log10 NFA) and its warped reference agrees better with
// the scene (verifyInstance). Whichever candidate is kept, when its own dense refinement is
// still refused for the distance, the wide refinement from it becomes its alignment if it
// correlates at least verify.realign_trusted_correlation, or if its warped reference verifies
// clearly better (verify.realign_verified_*; not on a reference with repeat periods, where a
// consensus one period off verifies as well).
//
// H: undistorted reference px -> undistorted scene px.
#include "detector/registered_object.h"

namespace refgrasp::detector {

/// The candidate to check in place of `cand` (cand itself when nothing better was found).
/// *dense receives the dense refinement (opt.dense) of the returned candidate's H, or the wide
/// alignment that became its H; the refined pose reuses it.
MatchCandidate realign(const RegisteredObject& obj, const DetectorOptions& opt, const MatchCandidate& cand,
                       const Features& scene, const GridIndex& grid, const Intrinsics& camera,
                       DenseRefineResult* dense);

}  // namespace refgrasp::detector
