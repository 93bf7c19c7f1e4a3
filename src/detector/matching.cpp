#include "detector/matching.h"

#include <Eigen/Dense>
#include <algorithm>
#include <climits>
#include <limits>
#include <cmath>
#include <cstdint>
#include <opencv2/imgproc.hpp>
#include <unordered_map>

#include "core/error.h"
#include "core/geometry.h"
#include "detector/homography.h"
#include "detector/plane_views.h"

namespace refgrasp::detector {
namespace {

using Vec2 = Eigen::Vector2d;
constexpr double kPi = M_PI;

// Local-search constants (the paper's "expected value" of the localisation error).
constexpr double kSimilarityErrorPx = 2.0;     // at the seed itself: SIFT localisation
constexpr double kSimilarityErrorPerPx = 0.1;  // growth with distance: ~10% scale/orientation error
constexpr double kHomographyErrorPx = 2.0;     // after a homography fit
constexpr double kHomographyErrorPerPx = 0.03; // extrapolating a fit from the seed's neighbourhood
constexpr double kAlignedErrorPx = 1.0;        // of a given (e.g. photometric) alignment: matchUnderHomography
constexpr int kQuickNeighbours = 40;           // detectable reference neighbours tried in the quick test
constexpr int kQuickMinMatches = 4;            // quick test passes with this many local matches
// Weak evidence: a hypothesis that reached this many local matches, one more than the quick test
// (at 4 no more far targets found, more time spent; at 6 fewer: docs/results.md).
constexpr int kWeakMinMatches = 5;
// Weak evidence is kept for patterns predicted at most this large (diagonal, scene px): a larger
// one has its features above the frame's contrast threshold, and its box would be most of a frame.
constexpr double kMaxWeakDiagonalPx = 128;
constexpr int kPass1MinMatches = 6;            // pass-1 matches needed to fit a homography
constexpr int kPass1Neighbours = 200;          // detectable reference neighbours tried in pass 1
constexpr double kOverlapFraction = 0.25;      // instances overlapping more than this conflict
constexpr double kMinAreaPx2 = 64.0;           // smallest projected pattern accepted
constexpr double kPerspectiveFalseAlarm = 1e-3;  // planeAffineUnlessPerspective's F test level
constexpr double kAmbiguousSeedFraction = 0.7; // twin seeds need d1, d2 < this x max_descriptor_distance
constexpr double kNfaMinEpsPx = 0.5;           // a-contrario: no consensus is tighter than SIFT's localisation
constexpr int kNfaSample = 4;                  // a-contrario: the homography's minimal sample
constexpr double kSamePlaceFraction = 0.5;     // two reference features within this x the larger size are one place

Vec2 pt(const cv::KeyPoint& k) { return Vec2(k.pt.x, k.pt.y); }
double deg2rad(double d) { return d * kPi / 180.0; }
double wrapPi(double a) {
  a = std::fmod(a + kPi, 2 * kPi);
  if (a < 0) a += 2 * kPi;
  return a - kPi;
}

/// Maps a reference keypoint to its predicted scene position, orientation (rad) and size (px):
/// either the similarity T^k of one match (eq. 1-2) or a homography with its local Jacobian.
struct Predictor {
  bool is_homography = false;
  Eigen::Matrix2d A = Eigen::Matrix2d::Identity();
  Vec2 xr0 = Vec2::Zero(), xs0 = Vec2::Zero();
  double dtheta = 0, dscale = 1;
  Eigen::Matrix3d H = Eigen::Matrix3d::Identity();

  static Predictor similarity(const cv::KeyPoint& r, const cv::KeyPoint& s) {
    Predictor p;
    p.dscale = s.size / r.size;
    p.dtheta = deg2rad(s.angle - r.angle);
    p.A << std::cos(p.dtheta), -std::sin(p.dtheta), std::sin(p.dtheta), std::cos(p.dtheta);
    p.A *= p.dscale;
    p.xr0 = pt(r);
    p.xs0 = pt(s);
    return p;
  }
  static Predictor homography(const Eigen::Matrix3d& H) {
    Predictor p;
    p.is_homography = true;
    p.H = H;
    return p;
  }
  bool predict(const cv::KeyPoint& r, Vec2* xs, double* angle_rad, double* size) const {
    const double ar = deg2rad(r.angle);
    if (!is_homography) {
      *xs = A * (pt(r) - xr0) + xs0;
      *angle_rad = ar + dtheta;
      *size = r.size * dscale;
      return true;
    }
    const Eigen::Vector3d y = H * pt(r).homogeneous();
    if (!(std::abs(y.z()) > 1e-12)) return false;
    const double u = y.x() / y.z(), v = y.y() / y.z();
    Eigen::Matrix2d J;
    J << H(0, 0) - u * H(2, 0), H(0, 1) - u * H(2, 1), H(1, 0) - v * H(2, 0), H(1, 1) - v * H(2, 1);
    J /= y.z();
    const Vec2 d = J * Vec2(std::cos(ar), std::sin(ar));
    *xs = Vec2(u, v);
    *angle_rad = std::atan2(d.y(), d.x());
    *size = r.size * std::sqrt(std::abs(J.determinant()));
    return std::isfinite(*size);
  }
};

struct LocalMatch {
  int ref, scene;
  float desc_dist;  // D_d
  float img_dist;   // D_i, scene px from the predicted position
};

/// Everything one matchObject call shares.
struct Context {
  const ReferenceIndex& ref;
  const Features& scene;
  const GridIndex& grid;
  const MatchOptions& opt;
  IntegerDescriptors scene_desc;  // scene.descriptors for the integer kernels
  MatchRejects* rejects;          // counts why hypotheses and fits ended
  double min_scene_size = 0;
  double max_dd2 = 0;
  cv::Rect2d bounds;
  /// A-contrario background model: log10 of the number of tests (hypotheses), and the density
  /// (per px^2) of scene features that would pass a local match's orientation, scale and
  /// descriptor tests by chance for one reference feature.
  double log10_tests = 0;
  double chance_per_px2 = 0;
};

double log10Binomial(int n, int k) {
  return (std::lgamma(n + 1.0) - std::lgamma(k + 1.0) - std::lgamma(n - k + 1.0)) / std::log(10.0);
}

/// log10 NFA of the best consensus among the residuals (px) of matches under a homography, n
/// reference features tested (AC-RANSAC: each k with eps = the k-th smallest residual).
double log10Nfa(const Context& cx, std::vector<double> residuals, int n) {
  std::sort(residuals.begin(), residuals.end());
  const int m = static_cast<int>(residuals.size());
  n = std::max(n, m);
  double best = std::numeric_limits<double>::infinity();
  const double base = cx.log10_tests + std::log10(std::max(1, n - kNfaSample));
  for (int k = kNfaSample + 1; k <= m; ++k) {
    const double eps = std::max(kNfaMinEpsPx, residuals[k - 1]);
    const double p = -std::expm1(-cx.chance_per_px2 * kPi * eps * eps);
    if (!(p > 0)) continue;
    const double v = base + log10Binomial(n, k) + log10Binomial(k, kNfaSample) + (k - kNfaSample) * std::log10(std::min(1.0, p));
    best = std::min(best, v);
  }
  return best;
}

/// The paper's local search: for each listed reference feature, among scene features within the
/// radius of its predicted position, with orientation within +-tol and size within +-tol*s of the
/// prediction, take the nearest in descriptor space if it passes the local ratio.
/// radius_px(i, predicted xs) gives the search radius. One scene feature keeps its best match.
template <class Radius>
void localSearch(const Context& cx, const Predictor& pred, const std::vector<int>* list,
                 const Radius& radius_px, std::vector<LocalMatch>* out, int* tested = nullptr) {
  out->clear();
  if (tested) *tested = 0;
  const auto& rk = cx.ref.features.keypoints;
  const auto& sk = cx.scene.keypoints;
  const double lr2 = cx.opt.local_ratio * cx.opt.local_ratio;
  std::vector<int> cand;
  const int n = list ? static_cast<int>(list->size()) : static_cast<int>(rk.size());
  for (int li = 0; li < n; ++li) {
    const int i = list ? (*list)[li] : li;
    Vec2 xs;
    double ang, size;
    if (!pred.predict(rk[i], &xs, &ang, &size)) continue;
    if (size < cx.min_scene_size) continue;  // too small to have been detected in the scene
    const double r = radius_px(xs);
    if (xs.x() < cx.bounds.x - r || xs.y() < cx.bounds.y - r ||
        xs.x() > cx.bounds.x + cx.bounds.width + r || xs.y() > cx.bounds.y + cx.bounds.height + r)
      continue;
    if (tested) ++*tested;
    cx.grid.radiusSearch(xs, r, &cand);
    int best = -1, d1 = INT_MAX, d2 = INT_MAX;
    const int16_t* rd = cx.ref.descriptors.s16.ptr<int16_t>(i);
    for (int j : cand) {
      const cv::KeyPoint& k = sk[j];
      if (std::abs(wrapPi(deg2rad(k.angle) - ang)) > cx.opt.orientation_tolerance_rad) continue;
      if (std::abs(k.size - size) > cx.opt.scale_tolerance * size) continue;
      const int d = squaredDistance(rd, cx.scene_desc.s16.ptr<int16_t>(j));
      if (d < d2) {
        if (d < d1) {
          d2 = d1;
          d1 = d;
          best = j;
        } else {
          d2 = d;
        }
      }
    }
    if (best < 0 || d1 > cx.max_dd2) continue;
    if (d2 != INT_MAX && !(d1 < lr2 * d2)) continue;
    out->push_back({i, best, static_cast<float>(std::sqrt(static_cast<double>(d1))),
                    static_cast<float>((pt(sk[best]) - xs).norm())});
  }
  // One-to-one in the scene: keep the descriptor-nearest reference feature.
  std::sort(out->begin(), out->end(), [](const LocalMatch& a, const LocalMatch& b) {
    return a.scene != b.scene ? a.scene < b.scene : a.desc_dist < b.desc_dist;
  });
  out->erase(std::unique(out->begin(), out->end(),
                         [](const LocalMatch& a, const LocalMatch& b) { return a.scene == b.scene; }),
             out->end());
}

struct Candidate {
  std::vector<Correspondence> inliers;
  Eigen::Matrix3d H;
  double score = 0;
  std::vector<cv::Point2f> quad;  // projected convex hull of the pattern, scene px
  double area = 0;
  int tested = 0;                 // reference features the last local search tested
  double log10_nfa = 0;
};

HomographyOptions homographyOptions(const MatchOptions& opt) {
  HomographyOptions h;
  h.ransac_reproj_px = opt.ransac_reproj_px;
  h.seed = opt.seed;
  return h;
}

/// The homography of a small instance: below opt.affine_below_px (the reference hull's projected
/// size), the plane-affine map (rectify_px, then 6 parameters) unless the homography's two
/// perspective parameters reduce the residual significantly: F = ((RSS_A - RSS_H) / 2) /
/// (RSS_H / (2n - 8)) against F(2, 2n - 8)'s upper 0.1 % point, (d/2) (0.001^(-2/d) - 1) in closed
/// form. Over a small pattern the perspective is below ~2 px at f = 500 px (its depth range over
/// its distance is at most its size over f), while a few matches leave the homography's
/// perspective terms poorly determined and its corners several px off.
Eigen::Matrix3d planeAffineUnlessPerspective(const Context& cx, const Eigen::Matrix3d& H, const std::vector<Vec2>& a,
                                             const std::vector<Vec2>& b) {
  const int n = static_cast<int>(a.size());
  if (!(cx.opt.affine_below_px > 0) || n <= 4) return H;
  std::vector<Vec2> q;
  for (const Vec2& p : cx.ref.hull_px) q.push_back(applyHomography(H, p));
  if (!(std::sqrt(std::abs(signedArea(q))) < cx.opt.affine_below_px)) return H;
  std::vector<Vec2> r;
  r.reserve(a.size());
  for (const Vec2& x : a) r.push_back(applyHomography(cx.ref.rectify_px, x));
  Eigen::Matrix3d A = fitAffineLeastSquares(r, b) * cx.ref.rectify_px;
  if (!A.allFinite() || std::abs(A(2, 2)) < 1e-15) return H;
  A /= A(2, 2);
  double rss_h = 0, rss_a = 0;
  for (int k = 0; k < n; ++k) {
    rss_h += (applyHomography(H, a[k]) - b[k]).squaredNorm();
    rss_a += (applyHomography(A, a[k]) - b[k]).squaredNorm();
  }
  if (!std::isfinite(rss_a)) return H;
  const double d = 2.0 * n - 8;
  const double f_crit = d / 2 * (std::pow(kPerspectiveFalseAlarm, -2 / d) - 1);
  const double f = (rss_a - rss_h) / 2 / std::max(rss_h / d, 1e-12);
  return f < f_crit ? A : H;
}

/// Robust homography from matches; fills a candidate when it passes min_inliers, the a-contrario
/// test (n_tested reference features were tested) and plausibility.
bool makeCandidate(const Context& cx, const std::vector<Correspondence>& matches, Candidate* c, int n_tested) {
  auto reject = [](int* counter) {
    ++*counter;
    return false;
  };
  int* too_few = &cx.rejects->too_few_inliers;
  if (static_cast<int>(matches.size()) < std::max(4, cx.opt.min_inliers)) return reject(too_few);
  std::vector<Vec2> a, b;
  a.reserve(matches.size());
  b.reserve(matches.size());
  for (const auto& m : matches) {
    a.push_back(pt(cx.ref.features.keypoints[m.ref]));
    b.push_back(pt(cx.scene.keypoints[m.scene]));
  }
  HomographyResult hr = estimateHomographyUnchecked(a, b, homographyOptions(cx.opt));
  if (!hr.ok || static_cast<int>(hr.inliers.size()) < cx.opt.min_inliers) return reject(too_few);
  {
    // Tighten to 3 sigma of the fit (the RANSAC threshold admits coarse mismatches), refit.
    const double tight = std::max(1.0, 3 * hr.rms_px);
    std::vector<int> keep;
    std::vector<Vec2> ka, kb;
    for (int k : hr.inliers)
      if ((applyHomography(hr.H, a[k]) - b[k]).norm() <= tight) {
        keep.push_back(k);
        ka.push_back(a[k]);
        kb.push_back(b[k]);
      }
    if (static_cast<int>(keep.size()) < cx.opt.min_inliers) return reject(too_few);
    const Eigen::Matrix3d Ht = fitHomographyLeastSquares(ka, kb);
    if (!Ht.allFinite()) return reject(too_few);
    hr.H = planeAffineUnlessPerspective(cx, Ht, ka, kb);
    hr.inliers = keep;
  }
  double log10_nfa = -std::numeric_limits<double>::infinity();
  if (std::isfinite(cx.opt.max_log10_nfa)) {
    std::vector<double> res;
    res.reserve(a.size());
    for (size_t k = 0; k < a.size(); ++k) res.push_back((applyHomography(hr.H, a[k]) - b[k]).norm());
    log10_nfa = log10Nfa(cx, std::move(res), n_tested);
    if (!(log10_nfa <= cx.opt.max_log10_nfa)) return reject(&cx.rejects->not_significant);
  }
  if (!homographyPlausible(hr.H, cx.ref.hull_px, kMinAreaPx2))
    return reject(&cx.rejects->implausible_homography);
  std::vector<cv::Point2f> in, hull;
  for (int k : hr.inliers) in.push_back(cx.ref.features.keypoints[matches[k].ref].pt);
  cv::convexHull(in, hull);
  if (cv::contourArea(hull) < cx.opt.min_inlier_spread * cx.ref.feature_hull_area_px2)
    return reject(&cx.rejects->narrow_inlier_spread);
  c->H = hr.H;
  c->tested = n_tested;
  c->log10_nfa = log10_nfa;
  c->inliers.clear();
  double sum = 0;
  for (int k : hr.inliers) {
    c->inliers.push_back(matches[k]);
    sum += (applyHomography(hr.H, a[k]) - b[k]).norm() * matches[k].descriptor_distance;
  }
  c->score = sum / hr.inliers.size();  // eq. 3
  c->quad.clear();
  for (const Vec2& p : cx.ref.hull_px) {
    const Vec2 q = applyHomography(hr.H, p);
    c->quad.emplace_back(static_cast<float>(q.x()), static_cast<float>(q.y()));
  }
  c->area = std::abs(cv::contourArea(c->quad));
  return true;
}

bool overlaps(const Candidate& a, const Candidate& b) {
  std::vector<cv::Point2f> inter;
  const float area = cv::intersectConvexConvex(a.quad, b.quad, inter, true);
  return area > kOverlapFraction * std::min(a.area, b.area);
}

/// Greedy selection: best score first, no overlap, scene features used once.
std::vector<MatchCandidate> selectInstances(const Context& cx, std::vector<Candidate> cands) {
  // A candidate overlapping one with more than twice its inliers is dominated (e.g. a hypothesis
  // shifted by one period of a repeated motif); eq. 3 only ranks the survivors.
  std::vector<bool> dominated(cands.size(), false);
  for (size_t i = 0; i < cands.size(); ++i)
    for (size_t j = 0; j < cands.size(); ++j)
      if (i != j && cands[j].inliers.size() > 2 * cands[i].inliers.size() && overlaps(cands[i], cands[j]))
        dominated[i] = true;
  std::vector<int> order;
  for (size_t i = 0; i < cands.size(); ++i)
    if (!dominated[i]) order.push_back(static_cast<int>(i));
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return cands[a].score < cands[b].score; });

  std::vector<MatchCandidate> out;
  std::vector<Candidate> accepted;
  std::vector<char> used(cx.scene.keypoints.size(), 0);
  for (int idx : order) {
    if (static_cast<int>(out.size()) >= cx.opt.max_instances) break;
    Candidate c = cands[idx];
    bool clash = false;
    for (const auto& a : accepted) clash |= overlaps(c, a);
    if (clash) continue;
    std::vector<Correspondence> free;
    for (const auto& m : c.inliers)
      if (!used[m.scene]) free.push_back(m);
    if (free.size() != c.inliers.size() && !makeCandidate(cx, free, &c, c.tested)) continue;
    for (const auto& m : c.inliers) used[m.scene] = 1;
    accepted.push_back(c);
    out.push_back({c.inliers, c.H, c.score, c.log10_nfa});
  }
  return out;
}

std::vector<Correspondence> toCorrespondences(const std::vector<LocalMatch>& m) {
  std::vector<Correspondence> c;
  c.reserve(m.size());
  for (const auto& x : m) c.push_back({x.ref, x.scene, x.desc_dist});
  return c;
}

/// Evaluates the hypothesis seeded by (ref r, scene s). The paper's local search under T^k, made
/// cheap and perspective-tolerant by growing it: a quick test on r's nearest neighbours, pass 1
/// under T^k on r's neighbourhood, then two passes over all reference features under the
/// homography fitted to the previous pass.
bool evaluateHypothesis(const Context& cx, int r, int s, Candidate* out, int* reached) {
  const auto& rk = cx.ref.features.keypoints;
  const auto& sk = cx.scene.keypoints;
  const Predictor sim = Predictor::similarity(rk[r], sk[s]);
  const Vec2 seed = pt(sk[s]);
  const double factor = cx.opt.search_radius_factor;
  // Expected error of T^k grows with the distance from the seed (scale/orientation error of one
  // keypoint, perspective); the search radius is factor times that.
  auto simRadius = [&](const Vec2& xs) {
    return factor * (kSimilarityErrorPx + kSimilarityErrorPerPx * (xs - seed).norm());
  };
  std::vector<LocalMatch> m;
  auto tooFewLocal = [&] {
    ++cx.rejects->too_few_local_matches;
    *reached = std::max(*reached, static_cast<int>(m.size()));
    return false;
  };
  // r's nearest reference features that are detectable at this scale: a far (small) instance
  // shows only the coarse features, which can lie beyond the nearest few hundred.
  auto detectable = [&](int i) { return rk[i].size * sim.dscale >= cx.min_scene_size; };
  std::vector<int> near;
  // The walks cover a number of places of the pattern, whatever its features per place.
  const double per_place = std::max(1.0, cx.ref.features_per_place);
  cx.ref.neighbours.nearest(r, static_cast<int>(std::lround(kQuickNeighbours * per_place)), detectable, &near);
  localSearch(cx, sim, &near, simRadius, &m);
  if (static_cast<int>(m.size()) < kQuickMinMatches) return tooFewLocal();
  cx.ref.neighbours.nearest(r, static_cast<int>(std::lround(kPass1Neighbours * per_place)), detectable, &near);
  localSearch(cx, sim, &near, simRadius, &m);
  if (static_cast<int>(m.size()) < kPass1MinMatches) return tooFewLocal();

  // A homography fitted to a neighbourhood extrapolates with an error that grows with the
  // distance from it; the second fit covers the whole pattern and is trusted uniformly.
  int tested = 0;
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<Vec2> a, b;
    for (const auto& x : m) {
      a.push_back(pt(rk[x.ref]));
      b.push_back(pt(sk[x.scene]));
    }
    const HomographyResult h = estimateHomographyUnchecked(a, b, homographyOptions(cx.opt));
    if (!h.ok || static_cast<int>(h.inliers.size()) < kPass1MinMatches) return tooFewLocal();
    const Predictor hom = Predictor::homography(h.H);
    const double e0 = std::max(kHomographyErrorPx, h.rms_px);
    if (pass == 0) {
      localSearch(cx, hom, nullptr, [&](const Vec2& xs) {
        return factor * (e0 + kHomographyErrorPerPx * (xs - seed).norm());
      }, &m);
    } else {
      localSearch(cx, hom, nullptr, [&](const Vec2&) { return factor * e0; }, &m, &tested);
    }
  }
  *reached = std::max(*reached, static_cast<int>(m.size()));
  return makeCandidate(cx, toCorrespondences(m), out, tested);
}

MatchResult matchPaper(const Context& cx, const std::vector<NearestTwo>& nn) {
  MatchResult res;
  const auto& rk = cx.ref.features.keypoints;
  const auto& sk = cx.scene.keypoints;
  const double gr2 = cx.opt.global_ratio * cx.opt.global_ratio;
  struct Seed {
    int ref, scene;
    double ratio2;
    long key;
    bool ambiguous;
  };
  std::vector<Seed> seeds;
  std::unordered_map<long, int> votes;
  auto addSeed = [&](int r, int j, double ratio2, bool ambiguous) {
    // Hough key of T^k (Lowe's bins): predicted pattern centre in cells of a quarter of the
    // projected pattern size, scale octave, 30 degree orientation bins. Used only for ordering.
    const Predictor p = Predictor::similarity(rk[r], sk[j]);
    const Vec2 c = p.A * (cx.ref.centre_px - p.xr0) + p.xs0;
    const long so = std::lround(std::log2(p.dscale));
    const double cell = std::max(8.0, 0.25 * std::exp2(static_cast<double>(so)) * cx.ref.diagonal_px);
    const long ox = static_cast<long>(std::floor(wrapPi(p.dtheta) / (kPi / 6)));
    const long key = ((((static_cast<long>(std::floor(c.x() / cell)) & 0xfff) * 4096 +
                        (static_cast<long>(std::floor(c.y() / cell)) & 0xfff)) * 64 + (so & 63)) * 16) + (ox & 15);
    seeds.push_back({r, j, ratio2, key, ambiguous});
    ++votes[key];
  };
  // Repeated and symmetric patterns make twins in the reference, so the global ratio rejects
  // their matches; a close match to the first or second twin still seeds a hypothesis (tried
  // after the unambiguous ones), and the local search decides.
  const double amb1 = kAmbiguousSeedFraction * cx.opt.max_descriptor_distance;
  const double amb1_2 = amb1 * amb1;
  // The ratio test compares places: a view-synthesised copy (plane_views.h) of the first's place
  // in the reference, or the place of which the first is such a copy, is no rival.
  auto samePlace = [&](int a, int b) {
    if (rk[a].class_id != kSynthesisedFeature && rk[b].class_id != kSynthesisedFeature) return false;
    const double dx = rk[a].pt.x - rk[b].pt.x, dy = rk[a].pt.y - rk[b].pt.y;
    const double r = kSamePlaceFraction * std::max(rk[a].size, rk[b].size);
    return dx * dx + dy * dy <= r * r;
  };
  for (int j = 0; j < static_cast<int>(nn.size()); ++j) {
    if (nn[j].best < 0 || nn[j].d2 == INT_MAX) continue;
    const double ratio2 = static_cast<double>(nn[j].d1) / nn[j].d2;
    if (ratio2 < gr2 || (nn[j].d1 <= cx.max_dd2 && samePlace(nn[j].best, nn[j].second))) {
      addSeed(nn[j].best, j, ratio2, false);
      ++res.global_matches;
    } else if (nn[j].d1 < amb1_2 && nn[j].d2 < amb1_2) {
      addSeed(nn[j].best, j, ratio2, true);
      addSeed(nn[j].second, j, ratio2, true);
    }
  }
  std::stable_sort(seeds.begin(), seeds.end(), [&](const Seed& a, const Seed& b) {
    if (a.ambiguous != b.ambiguous) return b.ambiguous;
    const int va = votes[a.key], vb = votes[b.key];
    return va != vb ? va > vb : a.ratio2 < b.ratio2;
  });

  std::vector<Candidate> cands;
  std::vector<WeakRegion> weak;
  std::vector<char> covered(sk.size(), 0);
  bool clean_candidate = false;
  for (const Seed& sd : seeds) {
    if (res.hypotheses_evaluated >= cx.opt.max_hypotheses) break;
    // Early exit once there are enough candidates: seeds are ordered by cluster size, ambiguous
    // ones last. Lone seeds are then skipped; ambiguous ones too unless the pattern itself is
    // ambiguous (all candidates so far came from twin seeds), where alignments must compete.
    if (static_cast<int>(cands.size()) >= cx.opt.max_instances &&
        (sd.ambiguous ? clean_candidate : votes[sd.key] < 2))
      break;
    if (covered[sd.scene]) continue;
    // Collapse: a seed that an existing candidate already explains is a near-identical hypothesis.
    bool explained = false;
    for (const auto& c : cands) {
      const Vec2 xs = pt(sk[sd.scene]);
      if ((applyHomography(c.H, pt(rk[sd.ref])) - xs).norm() <= 2 * cx.opt.ransac_reproj_px) {
        explained = true;
        break;
      }
    }
    if (explained) continue;
    ++res.hypotheses_evaluated;
    Candidate c;
    int reached = 0;
    if (!evaluateHypothesis(cx, sd.ref, sd.scene, &c, &reached)) {
      // Weak evidence: the pattern's bounding square under the seed's similarity, grown by half
      // (one keypoint's scale and orientation error, perspective).
      const Predictor p = Predictor::similarity(rk[sd.ref], sk[sd.scene]);
      const double diagonal = p.dscale * cx.ref.diagonal_px;
      if (reached >= kWeakMinMatches && diagonal <= kMaxWeakDiagonalPx) {
        const Vec2 c0 = p.A * (cx.ref.centre_px - p.xr0) + p.xs0;
        const double side = 1.5 * diagonal;
        weak.push_back({cv::Rect2d(c0.x() - side / 2, c0.y() - side / 2, side, side), reached});
      }
      continue;
    }
    clean_candidate |= !sd.ambiguous;
    for (const auto& m : c.inliers) covered[m.scene] = 1;
    cands.push_back(std::move(c));
  }
  res.instances = selectInstances(cx, std::move(cands));
  std::stable_sort(weak.begin(), weak.end(),
                   [](const WeakRegion& a, const WeakRegion& b) { return a.local_matches > b.local_matches; });
  for (const WeakRegion& w : weak) {
    if (static_cast<int>(res.weak.size()) >= kMaxWeakRegions) break;
    const cv::Point2d c(w.box.x + w.box.width / 2, w.box.y + w.box.height / 2);
    if (std::none_of(res.weak.begin(), res.weak.end(), [&](const WeakRegion& o) { return o.box.contains(c); }))
      res.weak.push_back(w);
  }
  return res;
}

MatchResult matchRatio(const Context& cx, const std::vector<NearestTwo>& nn) {
  MatchResult res;
  res.hypotheses_evaluated = 1;
  const double gr2 = cx.opt.global_ratio * cx.opt.global_ratio;
  std::vector<Correspondence> matches;
  for (int j = 0; j < static_cast<int>(nn.size()); ++j)
    if (nn[j].best >= 0 && nn[j].d2 != INT_MAX && nn[j].d1 < gr2 * nn[j].d2)
      matches.push_back({nn[j].best, j, static_cast<float>(std::sqrt(static_cast<double>(nn[j].d1)))});
  res.global_matches = static_cast<int>(matches.size());
  // Sequential RANSAC: take an instance, remove its inliers, try again.
  std::vector<Candidate> accepted;
  while (static_cast<int>(res.instances.size()) < cx.opt.max_instances) {
    Candidate c;
    if (!makeCandidate(cx, matches, &c, cx.ref.features.size())) break;
    bool clash = false;
    for (const auto& a : accepted) clash |= overlaps(c, a);
    std::vector<char> used(cx.scene.keypoints.size(), 0);
    for (const auto& m : c.inliers) used[m.scene] = 1;
    std::vector<Correspondence> rest;
    for (const auto& m : matches)
      if (!used[m.scene]) rest.push_back(m);
    matches.swap(rest);
    if (clash) continue;
    accepted.push_back(c);
    res.instances.push_back({c.inliers, c.H, c.score, c.log10_nfa});
  }
  return res;
}

}  // namespace

void MatchOptions::check() const {
  refgrasp::check(global_ratio > 0 && global_ratio <= 1, "MatchOptions.global_ratio", "must be in (0, 1]");
  refgrasp::check(local_ratio > 0 && local_ratio <= 1, "MatchOptions.local_ratio", "must be in (0, 1]");
  refgrasp::check(std::isfinite(search_radius_factor) && search_radius_factor > 0,
                  "MatchOptions.search_radius_factor", "must be > 0");
  refgrasp::check(orientation_tolerance_rad > 0 && orientation_tolerance_rad <= kPi,
                  "MatchOptions.orientation_tolerance_rad", "must be in (0, pi]");
  refgrasp::check(scale_tolerance > 0 && scale_tolerance < 1, "MatchOptions.scale_tolerance",
                  "must be in (0, 1)");
  refgrasp::check(max_hypotheses >= 1, "MatchOptions.max_hypotheses", "must be >= 1");
  refgrasp::check(max_reference_features >= 4, "MatchOptions.max_reference_features", "must be >= 4");
  refgrasp::check(min_inliers >= 4, "MatchOptions.min_inliers", "must be >= 4");
  refgrasp::check(std::isfinite(ransac_reproj_px) && ransac_reproj_px > 0,
                  "MatchOptions.ransac_reproj_px", "must be > 0");
  refgrasp::check(max_instances >= 1, "MatchOptions.max_instances", "must be >= 1");
  refgrasp::check(std::isfinite(max_descriptor_distance) && max_descriptor_distance > 0,
                  "MatchOptions.max_descriptor_distance", "must be > 0");
  refgrasp::check(min_inlier_spread >= 0 && min_inlier_spread < 1, "MatchOptions.min_inlier_spread",
                  "must be in [0, 1)");
  refgrasp::check(std::isfinite(affine_below_px) && affine_below_px >= 0, "MatchOptions.affine_below_px",
                  "must be >= 0");
  refgrasp::check(weak_regions >= 0 && weak_regions <= kMaxWeakRegions, "MatchOptions.weak_regions",
                  "must be in [0, " + std::to_string(kMaxWeakRegions) + "]");
  refgrasp::check(weak_contrast_threshold > 0 && weak_contrast_threshold < 1, "MatchOptions.weak_contrast_threshold",
                  "must be in (0, 1)");
  refgrasp::check(!std::isnan(max_log10_nfa) && max_log10_nfa > -std::numeric_limits<double>::infinity(),
                  "MatchOptions.max_log10_nfa", "must be a number or +inf");
}

MatchResult matchObject(const ReferenceIndex& ref, const Features& scene, const GridIndex& grid,
                        const MatchOptions& opt) {
  opt.check();
  return matchObjectUnchecked(ref, scene, grid, opt);
}

namespace {

/// The per-call context: scene descriptors for the kernels, size floor, bounds, and the
/// a-contrario background model measured on this frame. nn: the global 2-NN of the scene.
// The context of the local searches alone (no global matches, no background model).
Context localContext(const ReferenceIndex& ref, const Features& scene, const GridIndex& grid, const MatchOptions& opt,
                     MatchRejects* rejects) {
  Context cx{ref, scene, grid, opt, integerDescriptors(scene.descriptors, false), rejects, 0, 0, {}};
  double min_size = 1e9;
  for (const auto& k : scene.keypoints) min_size = std::min<double>(min_size, k.size);
  cx.min_scene_size = 0.8 * min_size;
  cx.max_dd2 = opt.max_descriptor_distance * opt.max_descriptor_distance;
  cx.bounds = cv::Rect2d(-0.5, -0.5, scene.image_size.width, scene.image_size.height);
  return cx;
}

Context makeContext(const ReferenceIndex& ref, const Features& scene, const GridIndex& grid, const MatchOptions& opt,
                    MatchRejects* rejects, std::vector<NearestTwo>* nn) {
  Context cx = localContext(ref, scene, grid, opt, rejects);
  *nn = nearestTwo(ref.descriptors, cx.scene_desc);
  if (std::isfinite(opt.max_log10_nfa)) {
    // Background model of the a-contrario test, measured on this frame: scene features per px^2
    // over the area they fall in, times the chance that one passes a local match's orientation
    // window, scale window (of ~5 octaves of sizes) and descriptor bound for a given reference
    // feature (scene features within the bound of some reference feature, per reference feature).
    float x0 = 1e9f, y0 = 1e9f, x1 = -1e9f, y1 = -1e9f;
    for (const auto& k : scene.keypoints) {
      x0 = std::min(x0, k.pt.x), x1 = std::max(x1, k.pt.x);
      y0 = std::min(y0, k.pt.y), y1 = std::max(y1, k.pt.y);
    }
    const double area = std::max(1.0, static_cast<double>(x1 - x0) * (y1 - y0));
    int close = 0;
    for (const auto& x : *nn) close += x.best >= 0 && x.d1 <= cx.max_dd2;
    const double q_desc = std::clamp(static_cast<double>(close) / (static_cast<double>(scene.size()) * ref.features.size()), 1e-6, 1.0);
    const double q_orient = opt.orientation_tolerance_rad / kPi;
    const double q_scale = std::min(1.0, std::log2((1 + opt.scale_tolerance) / (1 - opt.scale_tolerance)) / 5);
    cx.chance_per_px2 = scene.size() / area * q_orient * q_scale * q_desc;
    cx.log10_tests = std::log10(static_cast<double>(opt.matcher == MatcherType::kPaper ? opt.max_hypotheses : 1));
  }
  return cx;
}

}  // namespace

MatchResult matchObjectUnchecked(const ReferenceIndex& ref, const Features& scene,
                                 const GridIndex& grid, const MatchOptions& opt) {
  if (ref.features.size() < 4 || scene.size() < 4) return {};
  MatchRejects rejects;
  std::vector<NearestTwo> nn;
  const Context cx = makeContext(ref, scene, grid, opt, &rejects, &nn);
  MatchResult res = opt.matcher == MatcherType::kPaper ? matchPaper(cx, nn) : matchRatio(cx, nn);
  res.rejected = rejects;
  return res;
}

namespace {

/// matchUnderHomography in a context made once for several alignments.
std::optional<MatchCandidate> matchUnderHomographyIn(const Context& cx, const Eigen::Matrix3d& H) {
  // Two searches over all reference features, the more significant consensus wins:
  //  - one pass under H with the radius of a precise alignment (a wider one takes the neighbours
  //    one period away on a repeated motif, and their consensus comes back);
  //  - evaluateHypothesis's last two passes (a radius of 2 px, a homography fitted to the matches,
  //    then max(2 px, its rms)), for an alignment that is right but not everywhere precise.
  const double factor = cx.opt.search_radius_factor;
  std::optional<MatchCandidate> best;
  auto consider = [&](const std::vector<LocalMatch>& m, int tested) {
    Candidate c;
    if (!makeCandidate(cx, toCorrespondences(m), &c, tested)) return;
    if (!best || c.log10_nfa < best->log10_nfa ||
        (c.log10_nfa == best->log10_nfa && c.inliers.size() > best->inliers.size()))  // both -inf: the count rule
      best = MatchCandidate{c.inliers, c.H, c.score, c.log10_nfa};
  };
  std::vector<LocalMatch> m;
  int tested = 0;
  localSearch(cx, Predictor::homography(H), nullptr, [&](const Vec2&) { return factor * kAlignedErrorPx; }, &m, &tested);
  consider(m, tested);
  localSearch(cx, Predictor::homography(H), nullptr, [&](const Vec2&) { return factor * kHomographyErrorPx; }, &m);
  if (static_cast<int>(m.size()) >= kPass1MinMatches) {
    std::vector<Vec2> a, b;
    for (const auto& x : m) {
      a.push_back(pt(cx.ref.features.keypoints[x.ref]));
      b.push_back(pt(cx.scene.keypoints[x.scene]));
    }
    const HomographyResult h = estimateHomographyUnchecked(a, b, homographyOptions(cx.opt));
    if (h.ok && static_cast<int>(h.inliers.size()) >= kPass1MinMatches) {
      const double e0 = std::max(kHomographyErrorPx, h.rms_px);
      localSearch(cx, Predictor::homography(h.H), nullptr, [&](const Vec2&) { return factor * e0; }, &m, &tested);
      consider(m, tested);
    }
  }
  return best;
}

}  // namespace

std::optional<MatchCandidate> matchUnderHomography(const ReferenceIndex& ref, const Features& scene,
                                                   const GridIndex& grid, const MatchOptions& opt,
                                                   const Eigen::Matrix3d& H) {
  return matchUnderHomographies(ref, scene, grid, opt, {H})[0];
}

double inlierRmsPx(const ReferenceIndex& ref, const Features& scene, const MatchCandidate& cand) {
  if (cand.inliers.empty()) return 0;
  double sq = 0;
  for (const Correspondence& c : cand.inliers)
    sq += (applyHomography(cand.H, pt(ref.features.keypoints[c.ref])) - pt(scene.keypoints[c.scene])).squaredNorm();
  return std::sqrt(sq / cand.inliers.size());
}

std::optional<FeatureRefit> refitUnderHomography(const ReferenceIndex& ref, const Features& scene,
                                                 const GridIndex& grid, const MatchOptions& opt,
                                                 const Eigen::Matrix3d& H, double radius_px) {
  if (ref.features.size() < 4 || scene.size() < 4 || !H.allFinite()) return std::nullopt;
  MatchRejects rejects;
  const Context cx = localContext(ref, scene, grid, opt, &rejects);
  std::vector<LocalMatch> m;
  localSearch(cx, Predictor::homography(H), nullptr, [&](const Vec2&) { return radius_px; }, &m);
  std::vector<Vec2> a, b;
  for (const auto& x : m) {
    a.push_back(pt(ref.features.keypoints[x.ref]));
    b.push_back(pt(scene.keypoints[x.scene]));
  }
  const int floor = std::max(4, opt.min_inliers);
  if (static_cast<int>(a.size()) < floor) return std::nullopt;
  FeatureRefit out;
  out.H = planeAffineUnlessPerspective(cx, fitHomographyLeastSquares(a, b), a, b);
  if (!out.H.allFinite()) return std::nullopt;
  double sq = 0;
  for (size_t k = 0; k < a.size(); ++k) sq += (applyHomography(out.H, a[k]) - b[k]).squaredNorm();
  const double tight = 3 * std::sqrt(sq / a.size());
  std::vector<Vec2> ka, kb;
  for (size_t k = 0; k < a.size(); ++k)
    if ((applyHomography(out.H, a[k]) - b[k]).norm() <= tight) {
      ka.push_back(a[k]);
      kb.push_back(b[k]);
    }
  if (static_cast<int>(ka.size()) < floor) return std::nullopt;
  out.H = planeAffineUnlessPerspective(cx, fitHomographyLeastSquares(ka, kb), ka, kb);
  out.matches = static_cast<int>(ka.size());
  if (!out.H.allFinite()) return std::nullopt;
  return out;
}

std::vector<std::optional<MatchCandidate>> matchUnderHomographies(const ReferenceIndex& ref, const Features& scene,
                                                                  const GridIndex& grid, const MatchOptions& opt,
                                                                  const std::vector<Eigen::Matrix3d>& Hs) {
  std::vector<std::optional<MatchCandidate>> out(Hs.size());
  if (ref.features.size() < 4 || scene.size() < 4) return out;
  MatchRejects rejects;
  std::vector<NearestTwo> nn;
  const Context cx = makeContext(ref, scene, grid, opt, &rejects, &nn);
  for (size_t k = 0; k < Hs.size(); ++k)
    if (Hs[k].allFinite()) out[k] = matchUnderHomographyIn(cx, Hs[k]);
  return out;
}


}  // namespace refgrasp::detector
