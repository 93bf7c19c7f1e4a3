#include "detector/periods.h"

#include <algorithm>
#include <cmath>

#include "detector/checks.h"
#include "detector/homography.h"
#include "detector/verify.h"

namespace refgrasp::detector {

std::vector<Eigen::Matrix3d> movedByPeriods(const RegisteredObject& obj, const Eigen::Matrix3d& H) {
  std::vector<Eigen::Matrix3d> moved;
  const Eigen::Matrix3d& R = obj.index.rectify_px;
  const Eigen::Matrix3d Ri = R.inverse();
  if (obj.periods.empty() || !Ri.allFinite()) return moved;
  for (const Eigen::Vector2d& d : obj.periods) {
    Eigen::Matrix3d T = Eigen::Matrix3d::Identity();
    T(0, 2) = d.x();
    T(1, 2) = d.y();
    moved.push_back(H * Ri * T * R);
  }
  return moved;
}

std::optional<MatchCandidate> alignAcrossPeriods(const RegisteredObject& obj, const DetectorOptions& opt,
                                                 const MatchCandidate& cand, const Features& scene,
                                                 const GridIndex& grid) {
  const std::vector<Eigen::Matrix3d> moved = movedByPeriods(obj, cand.H);
  if (moved.empty()) return std::nullopt;
  std::array<Eigen::Vector2d, 4> corners;
  for (int i = 0; i < 4; ++i) corners[i] = applyHomography(cand.H, obj.corners_und_px[i]);
  const double distinct_px = distinctAlignmentPx(patternDiagonal(obj, cand.H));
  const std::optional<MatchCandidate>* best = nullptr;
  const auto found = matchUnderHomographies(obj.index, scene, grid, opt.match, moved);
  for (const auto& c : found) {
    if (!c || !(c->log10_nfa < cand.log10_nfa) || (best && !(c->log10_nfa < (*best)->log10_nfa))) continue;
    double gap = 0;
    for (int i = 0; i < 4; ++i)
      gap = std::max(gap, (applyHomography(c->H, obj.corners_und_px[i]) - corners[i]).norm());
    if (gap > distinct_px) best = &c;
  }
  if (!best) return std::nullopt;
  return **best;
}

PeriodAmbiguity periodAmbiguity(const RegisteredObject& obj, const DetectorOptions& opt, const MatchCandidate& cand,
                                const Features& scene, const Intrinsics& camera) {
  PeriodAmbiguity out;
  const VerifyOptions& vo = opt.verify;
  if (vo.period_ambiguity_cells > 9) return out;
  const std::vector<Eigen::Matrix3d> moved = movedByPeriods(obj, cand.H);
  if (moved.empty()) return out;
  const std::vector<Eigen::Vector2d> region = verificationRegion(obj, cand);
  const VerifyResult own = verifyInstance(obj.pyramid, region, scene.image, camera, cand.H, vo);
  // No alignment can have period_ambiguity_cells more strong cells than 9 - that many: nothing to try.
  if (!own.ok || own.strong_cells + vo.period_ambiguity_cells > 9) return out;
  DenseRefineOptions wide = opt.dense;
  wide.max_corner_shift_px = 0.3 * patternDiagonal(obj, cand.H);
  if (!std::isfinite(wide.max_corner_shift_px)) return out;
  VerifyResult best;
  for (const Eigen::Matrix3d& H_moved : moved) {
    VerifyResult there = verifyInstance(obj.pyramid, region, scene.image, camera, H_moved, vo);
    const DenseRefineResult aligned = refineDense(obj, H_moved, scene.image, camera, wide);
    bool refined = false;
    if (aligned.ok) {
      const VerifyResult at_aligned = verifyInstance(obj.pyramid, region, scene.image, camera, aligned.H, vo);
      if (at_aligned.correlation > there.correlation) {
        there = at_aligned;
        refined = true;
      }
    }
    if (!(there.ok && there.correlation > own.correlation + vo.period_ambiguity_margin &&
          there.strong_cells >= own.strong_cells + vo.period_ambiguity_cells))
      continue;
    if (out.ambiguous && !(there.correlation > best.correlation)) continue;
    out.ambiguous = true;
    best = there;
    out.better.reset();
    if (refined && there.strong_cells >= 9 && there.correlation >= vo.period_switch_correlation) out.better = aligned;
  }
  return out;
}

}  // namespace refgrasp::detector
