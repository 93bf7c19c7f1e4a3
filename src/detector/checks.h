#pragma once
// The verification stage: every check a matched candidate passes before it is reported, in
// order. A wrong geometry that found enough consistent matches (a shared logo, a repeated
// motif, clutter, a few features on a far target fitting a homography pixels off) must still be
// refused, and a right one placed as precisely as the image allows.
//   1. re-alignment (realign.h): the candidate's homography may be replaced by a photometric
//      alignment that the features and the scene support better;
//   2. pose (3D objects) and its plausibility: the pose's pattern corners within maxPoseGapPx of
//      the homography's, and a pose fitted to the features reprojecting them within
//      verify.max_feature_pose_rms_px; 2D-only objects: the dense alignment's corners;
//   3. sanity (sanity.h): distance, area, convexity;
//   4. photometric verification (verify.h): the warped reference correlates with the scene, over
//      the whole pattern and cell by cell (more cells for a reference with repeat periods);
//   5. alternatives a repeat period away (periods.h): a better one replaces the instance, an
//      ambiguous one refuses it.
// A cylinder on its cylinder model (RegisteredObject::cylinder_model) takes its own path instead:
// detector/cylinder_detection.h.
// Internal to the detector library.
#include "detector/registered_object.h"

namespace refgrasp::detector {

/// The largest distance (px) between a pose's pattern corners and the matched homography's for
/// the pose to be plausible: max(sanity.max_pose_gap_px, 10 % of the pattern's diagonal in the
/// image).
double maxPoseGapPx(const SanityOptions& opt, double pattern_diagonal_px);
/// Two alignments whose pattern corners lie farther apart than this (px) are distinct instances:
/// max(4 px, 10 % of the pattern's diagonal), the pose check's default bound.
double distinctAlignmentPx(double pattern_diagonal_px);

/// What the checks of one object's candidates in one frame share.
struct CandidateContext {
  const RegisteredObject& object;
  int id = -1;  ///< the object's id (Detection::object)
  const DetectorOptions& opt;
  const Features& scene;  ///< features of the object's search region, Features::image the frame
  const GridIndex* grid;  ///< their index; null when nothing was extracted
  const Intrinsics& camera;
  /// The candidate comes from the second pass (view-synthesised features or a weak region looked
  /// at again), not from the reference's own features in the frame.
  bool second_pass = false;
};

enum class CheckOutcome { kOk, kPoseFailed, kPoseDisagrees, kSanity, kNotVerified };

/// Steps 2-4 on one candidate; fills *out (geometry, scores, sanity status) as far as it got.
/// dense: the dense refinement of cand.H when the caller already ran it.
CheckOutcome checkCandidate(const CandidateContext& ctx, const MatchCandidate& cand, const DenseRefineResult* dense,
                            Detection* out);

struct Verdict {
  CheckOutcome outcome = CheckOutcome::kOk;
  Detection detection;  ///< the instance to report when outcome is kOk (found, instance unset)
};

/// Steps 1-5 on a candidate the matcher returned.
Verdict verifyCandidate(const CandidateContext& ctx, const MatchCandidate& matched);

}  // namespace refgrasp::detector
