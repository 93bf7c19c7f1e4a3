#include "detector/realign.h"

#include <algorithm>
#include <cmath>

#include "detector/periods.h"
#include "detector/verify.h"

namespace refgrasp::detector {

namespace {

// How much coarser than the features' localisation (their fit's RMS residual) the template of a
// dense alignment may be and still question the features' fit by a shift within its own pixel.
// A template whose pixel is more than ten times coarser belongs to a large pattern under the
// template size cap in a sharp scene, where hundreds of features place it to a tenth of a
// template pixel and the alignment does no better than half of one; under blur the features'
// residuals grow and a coarse template, which loses nothing to blur, still questions them
// (results.md "Near-identity pairs at full resolution": the ratios measured there, 22-60 against
// 2-6).
constexpr double kMaxDensePixelOverFeatureRms = 10;

// A dense refinement that converged well but was refused for moving a corner too far, and says
// that the features' fit (rms_px: its RMS residual) is off by that much: by more than a pixel of
// its template, or with a template not much coarser than the features' residuals.
bool refusedForDistance(const RegisteredObject& obj, const DenseRefineResult& d, const DenseRefineOptions& opt,
                        double rms_px) {
  if (d.ok || d.corner_shift_px <= opt.max_corner_shift_px || d.correlation < opt.min_correlation) return false;
  const double pixel = densePixelInScene(obj, d);
  return d.corner_shift_px > pixel || pixel <= kMaxDensePixelOverFeatureRms * rms_px;
}

// The dense refinement from H with room to move: half the pattern's diagonal (ok = false when
// that room is not finite).
DenseRefineResult wideRefine(const RegisteredObject& obj, const DetectorOptions& opt, const Eigen::Matrix3d& H,
                             const cv::Mat& image, const Intrinsics& camera) {
  DenseRefineOptions wide = opt.dense;
  wide.max_corner_shift_px = std::max(wide.max_corner_shift_px, 0.5 * patternDiagonal(obj, H));
  if (!std::isfinite(wide.max_corner_shift_px)) return DenseRefineResult{};
  return refineDense(obj, H, image, camera, wide);
}

// cand, aligned by its wide refinement `wide` when that is trusted: by its ECC correlation, or
// because its warped reference verifies clearly better than cand's (never on a reference with
// repeat periods: there a consensus one period off verifies as well). *dense gets `wide` when
// it is taken.
MatchCandidate adoptWideAlignment(const RegisteredObject& obj, const VerifyOptions& vo, const MatchCandidate& cand,
                                  const DenseRefineResult& wide, const cv::Mat& image, const Intrinsics& camera,
                                  DenseRefineResult* dense) {
  if (!wide.ok) return cand;
  bool take = vo.realign_trusted_correlation < 1 && wide.correlation >= vo.realign_trusted_correlation;
  if (!take && vo.realign_verified_correlation <= 1 && movedByPeriods(obj, cand.H).empty()) {
    const std::vector<Eigen::Vector2d> region = verificationRegion(obj, cand);
    const VerifyResult at_wide = verifyInstance(obj.pyramid, region, image, camera, wide.H, vo);
    if (at_wide.ok && at_wide.correlation >= vo.realign_verified_correlation &&
        at_wide.strong_cells >= vo.realign_verified_cells) {
      const VerifyResult at_cand = verifyInstance(obj.pyramid, region, image, camera, cand.H, vo);
      take = at_wide.correlation >= at_cand.correlation + vo.realign_verified_gain;
    }
  }
  if (!take) return cand;
  MatchCandidate out = cand;
  out.H = wide.H;
  *dense = wide;
  return out;
}

}  // namespace

MatchCandidate realign(const RegisteredObject& obj, const DetectorOptions& opt, const MatchCandidate& cand,
                       const Features& scene, const GridIndex& grid, const Intrinsics& camera,
                       DenseRefineResult* dense) {
  const cv::Mat& image = scene.image;
  *dense = refineDense(obj, cand.H, image, camera, opt.dense);
  if (!refusedForDistance(obj, *dense, opt.dense, inlierRmsPx(obj.index, scene, cand))) return cand;
  const DenseRefineResult wide = wideRefine(obj, opt, cand.H, image, camera);
  if (!wide.ok) return cand;
  const std::optional<MatchCandidate> again = matchUnderHomography(obj.index, scene, grid, opt.match, wide.H);
  if (!again) return adoptWideAlignment(obj, opt.verify, cand, wide, image, camera, dense);
  const bool supported = again->inliers.size() >= cand.inliers.size() ||
                         (std::isfinite(cand.log10_nfa) && again->log10_nfa <= cand.log10_nfa);
  if (!supported) return adoptWideAlignment(obj, opt.verify, cand, wide, image, camera, dense);
  const VerifyResult before =
      verifyInstance(obj.pyramid, verificationRegion(obj, cand), image, camera, cand.H, opt.verify);
  const VerifyResult after =
      verifyInstance(obj.pyramid, verificationRegion(obj, *again), image, camera, again->H, opt.verify);
  if (!(after.ok && after.correlation > before.correlation))
    return adoptWideAlignment(obj, opt.verify, cand, wide, image, camera, dense);
  *dense = refineDense(obj, again->H, image, camera, opt.dense);
  if (!refusedForDistance(obj, *dense, opt.dense, inlierRmsPx(obj.index, scene, *again))) return *again;
  return adoptWideAlignment(obj, opt.verify, *again, wideRefine(obj, opt, again->H, image, camera), image,
                            camera, dense);
}

}  // namespace refgrasp::detector
