#include "detector/checks.h"

#include <algorithm>
#include <cmath>

#include "core/geometry.h"
#include "detector/cylinder_detection.h"
#include "detector/homography.h"
#include "detector/matching.h"
#include "detector/periods.h"
#include "detector/realign.h"
#include "detector/sanity.h"
#include "detector/verify.h"

namespace refgrasp::detector {

double maxPoseGapPx(const SanityOptions& opt, double pattern_diagonal_px) {
  return std::max(opt.max_pose_gap_px, 0.1 * pattern_diagonal_px);
}

double distinctAlignmentPx(double pattern_diagonal_px) { return std::max(4.0, 0.1 * pattern_diagonal_px); }

namespace {

// VerifyOptions::second_pass_needs_dense: a candidate of the second pass (views, weak regions)
// that the dense alignment could have placed but did not (dense_placed false) is not reported.
bool secondPassUnplaced(const CandidateContext& ctx, bool dense_placed) {
  const DetectorOptions& opt = ctx.opt;
  return opt.verify.enabled && opt.verify.second_pass_needs_dense && ctx.second_pass && !dense_placed &&
         opt.dense.enabled && ctx.object.dense_usable && !ctx.scene.image.empty();
}

// 3D objects: the pose, and whether it puts the pattern where the matches put it (a pose caught
// in the wrong one of a plane's two solutions, or pulled by a few bad points, does not).
CheckOutcome checkPose(const CandidateContext& ctx, const MatchCandidate& cand, const DenseRefineResult* dense,
                       Detection* d) {
  const RegisteredObject& obj = ctx.object;
  const DetectorOptions& opt = ctx.opt;
  bool from_features = false;
  const PoseResult p = estimatePose(obj, opt, cand, ctx.scene, ctx.camera, opt.pose, dense, &from_features);
  if (!p.ok) return CheckOutcome::kPoseFailed;
  d->cMo = p.cMo;
  d->pose_rms_px = p.rms_px;
  for (int i = 0; i < 4; ++i) d->corners[i] = ctx.camera.project(p.cMo * obj.model.target->corners_o[i]);
  std::array<Eigen::Vector2d, 4> matched;  // the corners the homography gives, image px
  for (int i = 0; i < 4; ++i)
    matched[i] = distortPixel(ctx.camera, applyHomography(cand.H, obj.corners_und_px[i]));
  const double diag = 0.5 * ((matched[2] - matched[0]).norm() + (matched[3] - matched[1]).norm());
  double gap = 0;
  for (int i = 0; i < 4; ++i) gap = std::max(gap, (matched[i] - d->corners[i]).norm());
  if (!(gap <= maxPoseGapPx(opt.sanity, diag))) return CheckOutcome::kPoseDisagrees;
  // A pose fitted to the features that reprojects them poorly: the consensus does not come from
  // one rigid plane (on a facade, matches spanning two windows).
  if (opt.verify.enabled && from_features && !(p.rms_px <= opt.verify.max_feature_pose_rms_px))
    return CheckOutcome::kNotVerified;
  // On a reference with repeat periods synthesised features one period off give a pose that
  // passes the checks above.
  if (!obj.periods.empty() && secondPassUnplaced(ctx, !from_features)) return CheckOutcome::kNotVerified;
  return CheckOutcome::kOk;
}

// 2D-only objects: H is the dense alignment's when it converged (every pixel of the pattern, not
// a few keypoints) on a template not much coarser than the scene, the features' otherwise,
// refitted to every reference feature (not only the strongest, index's cap) that agrees with it.
// Returns whether the dense alignment placed it.
bool placeTwoD(const CandidateContext& ctx, const MatchCandidate& cand, const DenseRefineResult* dense, Detection* d) {
  const RegisteredObject& obj = ctx.object;
  const DetectorOptions& opt = ctx.opt;
  bool dense_placed = false;
  if (opt.dense.enabled && obj.dense_usable && !ctx.scene.image.empty()) {
    const DenseRefineResult dr = dense ? *dense : refineDense(obj, cand.H, ctx.scene.image, ctx.camera, opt.dense);
    if (dr.ok && dr.level >= 0 && densePixelInScene(obj, dr) <= opt.dense.max_2d_coarsening) {
      d->H = dr.H;
      dense_placed = true;
    }
  }
  if (!dense_placed && obj.uncapped_index && ctx.grid && !cand.inliers.empty()) {
    // The search radius: 3 sigma of the features' fit, at least 1 px (SIFT's localisation), at
    // most the matcher's RANSAC threshold.
    const double radius =
        std::clamp(3 * inlierRmsPx(obj.index, ctx.scene, cand), 1.0, opt.match.ransac_reproj_px);
    const auto refit = refitUnderHomography(*obj.uncapped_index, ctx.scene, *ctx.grid, opt.match, cand.H, radius);
    // A refinement: features matched within `radius` of where H puts them cannot move the
    // pattern further than that; a refit that does fitted other features (a blurred scene's
    // fine ones mislocated) and is not used.
    double moved = 0;
    if (refit)
      for (int i = 0; i < 4; ++i)
        moved = std::max(moved, (applyHomography(refit->H, obj.corners_und_px[i]) -
                                 applyHomography(cand.H, obj.corners_und_px[i])).norm());
    if (refit && refit->matches > static_cast<int>(cand.inliers.size()) && moved <= radius) d->H = refit->H;
  }
  for (int i = 0; i < 4; ++i) d->corners[i] = distortPixel(ctx.camera, applyHomography(d->H, obj.corners_und_px[i]));
  return dense_placed;
}

// Step 4: the warped reference against the scene.
CheckOutcome checkPhotometry(const CandidateContext& ctx, const MatchCandidate& cand, Detection* d) {
  const RegisteredObject& obj = ctx.object;
  const VerifyOptions& vo = ctx.opt.verify;
  const VerifyResult v =
      verifyInstance(obj.pyramid, verificationRegion(obj, cand), ctx.scene.image, ctx.camera, cand.H, vo);
  d->correlation = v.correlation;
  if (!v.ok) return CheckOutcome::kNotVerified;
  // On a repeated motif cells agree by chance under a wrong lattice map: more must agree.
  if (!obj.periods.empty() && v.strong_cells < std::min(vo.periodic_min_strong_cells, v.textured_cells))
    return CheckOutcome::kNotVerified;
  return CheckOutcome::kOk;
}

// Step 5 on an instance that passed every check: the alternative a period away replaces it when
// it passes them too and correlates at least as well; then the kept one is refused when a
// period away (or at a photometric peak beside it) an alignment agrees clearly better, unless
// that alignment agrees strongly everywhere, its features match there and it passes every
// check: then it replaces it.
void checkAlternatives(const CandidateContext& ctx, const MatchCandidate& cand, Verdict* verdict) {
  const RegisteredObject& obj = ctx.object;
  const DetectorOptions& opt = ctx.opt;
  std::optional<MatchCandidate> other;
  if (opt.verify.period_rematch) other = alignAcrossPeriods(obj, opt, cand, ctx.scene, *ctx.grid);
  Detection other_detection;
  const MatchCandidate* kept = &cand;
  if (other && checkCandidate(ctx, *other, nullptr, &other_detection) == CheckOutcome::kOk &&
      other_detection.correlation >= verdict->detection.correlation) {
    verdict->detection = other_detection;
    kept = &*other;
  }
  const PeriodAmbiguity ambiguity = periodAmbiguity(obj, opt, *kept, ctx.scene, ctx.camera);
  if (!ambiguity.ambiguous) return;
  verdict->outcome = CheckOutcome::kNotVerified;
  std::optional<MatchCandidate> moved;
  if (ambiguity.better) moved = matchUnderHomography(obj.index, ctx.scene, *ctx.grid, opt.match, ambiguity.better->H);
  Detection moved_detection;
  if (moved) {
    moved->H = ambiguity.better->H;
    if (checkCandidate(ctx, *moved, &*ambiguity.better, &moved_detection) == CheckOutcome::kOk) {
      verdict->detection = moved_detection;
      verdict->outcome = CheckOutcome::kOk;
    }
  }
}

}  // namespace

CheckOutcome checkCandidate(const CandidateContext& ctx, const MatchCandidate& cand, const DenseRefineResult* dense,
                            Detection* out) {
  Detection& d = *out;
  d.object = ctx.id;
  d.H = cand.H;
  d.inliers = static_cast<int>(cand.inliers.size());
  d.score = cand.score;
  d.log10_nfa = cand.log10_nfa;
  if (ctx.object.model.target) {
    const CheckOutcome pose = checkPose(ctx, cand, dense, &d);
    if (pose != CheckOutcome::kOk) return pose;
  } else {
    // A 2D-only object's corners are its whole report, and a few synthesised features fit them
    // several px off (a 3D object's feature pose has the pose-gap check and the RMS bound instead).
    if (secondPassUnplaced(ctx, placeTwoD(ctx, cand, dense, &d))) return CheckOutcome::kNotVerified;
  }
  d.sanity = checkDetection(d.corners, d.cMo, ctx.camera.width, ctx.camera.height, ctx.opt.sanity);
  if (d.sanity != SanityStatus::kOk) return CheckOutcome::kSanity;
  if (ctx.opt.verify.enabled) return checkPhotometry(ctx, cand, &d);
  return CheckOutcome::kOk;
}

Verdict verifyCandidate(const CandidateContext& ctx, const MatchCandidate& matched) {
  const RegisteredObject& obj = ctx.object;
  if (obj.cylinder_model) return verifyCylinderCandidate(ctx, matched);
  const VerifyOptions& vo = ctx.opt.verify;
  // The re-alignment and the alternatives need the frame and a pattern mostly in view: they are
  // measured at the pattern's corners, which a close-up puts far outside the frame.
  const bool realigned = ctx.grid && obj.dense_usable && vo.enabled && vo.realign && !ctx.scene.image.empty() &&
                         inViewFraction(obj, matched.H, ctx.camera) >= vo.realign_min_in_view;
  DenseRefineResult dense;
  const MatchCandidate cand =
      realigned ? realign(obj, ctx.opt, matched, ctx.scene, *ctx.grid, ctx.camera, &dense) : matched;
  Verdict verdict;
  verdict.outcome = checkCandidate(ctx, cand, realigned ? &dense : nullptr, &verdict.detection);
  if (verdict.outcome == CheckOutcome::kOk && realigned) checkAlternatives(ctx, cand, &verdict);
  return verdict;
}

}  // namespace refgrasp::detector
