#include "detector/matching.h"

#include <Eigen/Dense>
#include <algorithm>
#include <climits>
#include <map>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <unordered_map>

#include "core/error.h"
#include "core/geometry.h"
#include "detector/homography.h"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define REFGRASP_HAVE_X86 1
#endif

namespace refgrasp::detector {
namespace {

using Vec2 = Eigen::Vector2d;
constexpr int kDim = 128;
constexpr double kPi = M_PI;

// Local-search constants (the paper's "expected value" of the localisation error).
constexpr double kSimilarityErrorPx = 2.0;     // at the seed itself: SIFT localisation
constexpr double kSimilarityErrorPerPx = 0.1;  // growth with distance: ~10% scale/orientation error
constexpr double kHomographyErrorPx = 2.0;     // after a homography fit
constexpr double kHomographyErrorPerPx = 0.03; // extrapolating a fit from the seed's neighbourhood
constexpr int kQuickNeighbours = 40;           // detectable reference neighbours tried in the quick test
constexpr int kStoredNeighbours = 200;         // neighbour list length (small ones get skipped)
constexpr int kQuickMinMatches = 4;            // quick test passes with this many local matches
constexpr int kPass1MinMatches = 6;            // pass-1 matches needed to fit a homography
constexpr double kOverlapFraction = 0.25;      // instances overlapping more than this conflict
constexpr double kMinAreaPx2 = 64.0;           // smallest projected pattern accepted
constexpr double kAmbiguousSeedFraction = 0.7; // twin seeds need d1, d2 < this x max_descriptor_distance

Vec2 pt(const cv::KeyPoint& k) { return Vec2(k.pt.x, k.pt.y); }
double deg2rad(double d) { return d * kPi / 180.0; }
double wrapPi(double a) {
  a = std::fmod(a + kPi, 2 * kPi);
  if (a < 0) a += 2 * kPi;
  return a - kPi;
}

int dist2(const int16_t* a, const int16_t* b) {
  int s = 0;
  for (int k = 0; k < kDim; ++k) {
    const int d = a[k] - b[k];
    s += d * d;
  }
  return s;
}

cv::Mat toS16(const cv::Mat& desc, std::vector<int>* norm2) {
  cv::Mat out;
  desc.convertTo(out, CV_16S);
  norm2->resize(out.rows);
  for (int i = 0; i < out.rows; ++i) {
    const int16_t* r = out.ptr<int16_t>(i);
    int s = 0;
    for (int k = 0; k < kDim; ++k) s += r[k] * r[k];
    (*norm2)[i] = s;
  }
  return out;
}

void knnRowsScalar(const cv::Mat& S, const std::vector<int>& sn2, const cv::Mat& R,
                   const std::vector<int>& rn2, int s0, int s1, NearestTwo* out) {
  for (int i = s0; i < s1; ++i) {
    const int16_t* s = S.ptr<int16_t>(i);
    NearestTwo nn;
    for (int j = 0; j < R.rows; ++j) {
      const int16_t* r = R.ptr<int16_t>(j);
      int dot = 0;
      for (int k = 0; k < kDim; ++k) dot += s[k] * r[k];
      const int d = sn2[i] + rn2[j] - 2 * dot;
      if (d < nn.d2) {
        if (d < nn.d1) {
          nn.d2 = nn.d1;
          nn.second = nn.best;
          nn.d1 = d;
          nn.best = j;
        } else {
          nn.d2 = d;
          nn.second = j;
        }
      }
    }
    out[i] = nn;
  }
}

#ifdef REFGRASP_HAVE_X86
// Exact integer dot products, four scene rows per pass over a reference row.
__attribute__((target("avx2"))) void knnRowsAvx2(const cv::Mat& S, const std::vector<int>& sn2,
                                                 const cv::Mat& R, const std::vector<int>& rn2,
                                                 int s0, int s1, NearestTwo* out) {
  int i = s0;
  for (; i + 4 <= s1; i += 4) {
    const __m256i* s[4];
    for (int q = 0; q < 4; ++q) s[q] = reinterpret_cast<const __m256i*>(S.ptr<int16_t>(i + q));
    NearestTwo nn[4];
    for (int j = 0; j < R.rows; ++j) {
      const __m256i* r = reinterpret_cast<const __m256i*>(R.ptr<int16_t>(j));
      __m256i acc[4] = {_mm256_setzero_si256(), _mm256_setzero_si256(), _mm256_setzero_si256(),
                        _mm256_setzero_si256()};
      for (int k = 0; k < 8; ++k) {
        const __m256i rv = _mm256_loadu_si256(r + k);
        for (int q = 0; q < 4; ++q)
          acc[q] = _mm256_add_epi32(acc[q], _mm256_madd_epi16(rv, _mm256_loadu_si256(s[q] + k)));
      }
      // Horizontal sums of the four accumulators.
      const __m256i h01 = _mm256_hadd_epi32(acc[0], acc[1]);
      const __m256i h23 = _mm256_hadd_epi32(acc[2], acc[3]);
      const __m256i h = _mm256_hadd_epi32(h01, h23);
      const __m128i sum = _mm_add_epi32(_mm256_castsi256_si128(h), _mm256_extracti128_si256(h, 1));
      alignas(16) int dots[4];
      _mm_store_si128(reinterpret_cast<__m128i*>(dots), sum);
      for (int q = 0; q < 4; ++q) {
        const int d = sn2[i + q] + rn2[j] - 2 * dots[q];
        if (d < nn[q].d2) {
          if (d < nn[q].d1) {
            nn[q].d2 = nn[q].d1;
            nn[q].second = nn[q].best;
            nn[q].d1 = d;
            nn[q].best = j;
          } else {
            nn[q].d2 = d;
            nn[q].second = j;
          }
        }
      }
    }
    for (int q = 0; q < 4; ++q) out[i + q] = nn[q];
  }
  if (i < s1) knnRowsScalar(S, sn2, R, rn2, i, s1, out);
}
#endif

#ifdef REFGRASP_HAVE_X86
// Eight scene rows per lane group; each reference row is one pass. Dot products with the 8-bit
// VNNI instruction (u8 scene x s8 reference, exact int32 sums); the nearest/second-nearest
// bookkeeping is vectorised across the eight scene rows.
__attribute__((target("avx2,avx512f,avx512vl,avx512bw,avx512vnni"))) void knnBlocksVnni(
    const cv::Mat& S8, const std::vector<int>& sn2, const ReferenceIndex& ref, int b0, int b1, NearestTwo* out) {
  const int ns = S8.rows, nr = ref.descriptors_lo_s8.rows;
  alignas(32) uint8_t pad[8][kDim];
  for (int blk = b0; blk < b1; ++blk) {
    const int i0 = blk * 8;
    const uint8_t* rows[8];
    for (int q = 0; q < 8; ++q) {
      if (i0 + q < ns) {
        rows[q] = S8.ptr<uint8_t>(i0 + q);
      } else {
        std::fill(pad[q], pad[q] + kDim, 0);
        rows[q] = pad[q];
      }
    }
    alignas(32) int n2[8];
    for (int q = 0; q < 8; ++q) n2[q] = i0 + q < ns ? sn2[i0 + q] : 0;
    const __m256i sn = _mm256_load_si256(reinterpret_cast<const __m256i*>(n2));
    __m256i d1 = _mm256_set1_epi32(INT_MAX), d2 = _mm256_set1_epi32(INT_MAX);
    __m256i best = _mm256_set1_epi32(-1), second = _mm256_set1_epi32(-1);
    for (int j = 0; j < nr; ++j) {
      const __m256i* lo = reinterpret_cast<const __m256i*>(ref.descriptors_lo_s8.ptr<int8_t>(j));
      const __m256i l0 = _mm256_loadu_si256(lo), l1 = _mm256_loadu_si256(lo + 1),
                    l2 = _mm256_loadu_si256(lo + 2), l3 = _mm256_loadu_si256(lo + 3);
      __m256i acc[8];
      for (int q = 0; q < 8; ++q) {
        const __m256i* s = reinterpret_cast<const __m256i*>(rows[q]);
        __m256i a = _mm256_dpbusd_epi32(_mm256_setzero_si256(), _mm256_loadu_si256(s), l0);
        a = _mm256_dpbusd_epi32(a, _mm256_loadu_si256(s + 1), l1);
        a = _mm256_dpbusd_epi32(a, _mm256_loadu_si256(s + 2), l2);
        acc[q] = _mm256_dpbusd_epi32(a, _mm256_loadu_si256(s + 3), l3);
      }
      if (ref.has_hi[j]) {
        const __m256i* hi = reinterpret_cast<const __m256i*>(ref.descriptors_hi_s8.ptr<int8_t>(j));
        for (int q = 0; q < 8; ++q) {
          const __m256i* s = reinterpret_cast<const __m256i*>(rows[q]);
          __m256i a = _mm256_setzero_si256();
          for (int k = 0; k < 4; ++k) a = _mm256_dpbusd_epi32(a, _mm256_loadu_si256(s + k), _mm256_loadu_si256(hi + k));
          acc[q] = _mm256_add_epi32(acc[q], _mm256_slli_epi32(a, 7));
        }
      }
      const __m256i h01 = _mm256_hadd_epi32(acc[0], acc[1]), h23 = _mm256_hadd_epi32(acc[2], acc[3]);
      const __m256i h45 = _mm256_hadd_epi32(acc[4], acc[5]), h67 = _mm256_hadd_epi32(acc[6], acc[7]);
      const __m256i h03 = _mm256_hadd_epi32(h01, h23), h47 = _mm256_hadd_epi32(h45, h67);
      const __m256i dot = _mm256_add_epi32(_mm256_permute2x128_si256(h03, h47, 0x20),
                                           _mm256_permute2x128_si256(h03, h47, 0x31));
      const __m256i d = _mm256_sub_epi32(_mm256_add_epi32(sn, _mm256_set1_epi32(ref.descriptor_norm2[j])),
                                         _mm256_slli_epi32(dot, 1));
      const __m256i closer = _mm256_cmpgt_epi32(d1, d), closer2 = _mm256_cmpgt_epi32(d2, d);
      const __m256i jv = _mm256_set1_epi32(j);
      second = _mm256_blendv_epi8(_mm256_blendv_epi8(second, jv, closer2), best, closer);
      d2 = _mm256_blendv_epi8(_mm256_min_epi32(d2, d), d1, closer);
      best = _mm256_blendv_epi8(best, jv, closer);
      d1 = _mm256_min_epi32(d1, d);
    }
    alignas(32) int vb[8], vs[8], v1[8], v2[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(vb), best);
    _mm256_store_si256(reinterpret_cast<__m256i*>(vs), second);
    _mm256_store_si256(reinterpret_cast<__m256i*>(v1), d1);
    _mm256_store_si256(reinterpret_cast<__m256i*>(v2), d2);
    for (int q = 0; q < 8 && i0 + q < ns; ++q) out[i0 + q] = {vb[q], v1[q], v2[q], vs[q]};
  }
}
#endif

bool cpuHas(KnnKernel k) {
#ifdef REFGRASP_HAVE_X86
  static const bool avx2 = __builtin_cpu_supports("avx2");
  static const bool vnni = __builtin_cpu_supports("avx512vnni") && __builtin_cpu_supports("avx512vl") &&
                           __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx2");
  if (k == KnnKernel::kAvx2) return avx2;
  if (k == KnnKernel::kVnni) return vnni;
#endif
  return k == KnnKernel::kScalar || k == KnnKernel::kAuto;
}

std::vector<NearestTwo> globalKnn(const cv::Mat& S, const std::vector<int>& sn2, const ReferenceIndex& ref,
                                  KnnKernel kernel = KnnKernel::kAuto) {
  const cv::Mat& R = ref.descriptors_s16;
  const std::vector<int>& rn2 = ref.descriptor_norm2;
  std::vector<NearestTwo> out(S.rows);
  if (R.rows == 0 || S.rows == 0) return out;
  if (kernel == KnnKernel::kAuto) {
    kernel = cpuHas(KnnKernel::kVnni) ? KnnKernel::kVnni
             : cpuHas(KnnKernel::kAvx2) ? KnnKernel::kAvx2 : KnnKernel::kScalar;
  }
  if (!cpuHas(kernel)) kernel = KnnKernel::kScalar;
#ifdef REFGRASP_HAVE_X86
  if (kernel == KnnKernel::kVnni) {
    cv::Mat S8;
    S.convertTo(S8, CV_8U);
    const int nblocks = (S.rows + 7) / 8;
    cv::parallel_for_(cv::Range(0, nblocks), [&](const cv::Range& rg) {
      knnBlocksVnni(S8, sn2, ref, rg.start, rg.end, out.data());
    }, 8);
    return out;
  }
#endif
  const int chunk = 64;
  const int nchunks = (S.rows + chunk - 1) / chunk;
  cv::parallel_for_(cv::Range(0, nchunks), [&](const cv::Range& rg) {
    for (int c = rg.start; c < rg.end; ++c) {
      const int s0 = c * chunk, s1 = std::min(S.rows, s0 + chunk);
#ifdef REFGRASP_HAVE_X86
      if (kernel == KnnKernel::kAvx2) {
        knnRowsAvx2(S, sn2, R, rn2, s0, s1, out.data());
        continue;
      }
#endif
      knnRowsScalar(S, sn2, R, rn2, s0, s1, out.data());
    }
  });
  return out;
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
  cv::Mat scene16;
  std::vector<int> scene_norm2;
  double min_scene_size = 0;
  double max_dd2 = 0;
  cv::Rect2d bounds;
};

/// The paper's local search: for each listed reference feature, among scene features within the
/// radius of its predicted position, with orientation within +-tol and size within +-tol*s of the
/// prediction, take the nearest in descriptor space if it passes the local ratio.
/// radius_px(i, predicted xs) gives the search radius. One scene feature keeps its best match.
/// With a list, at most max_tried of its features predicted to be detectable are tried.
template <class Radius>
void localSearch(const Context& cx, const Predictor& pred, const std::vector<int>* list,
                 const Radius& radius_px, std::vector<LocalMatch>* out, int max_tried = INT_MAX) {
  out->clear();
  const auto& rk = cx.ref.features.keypoints;
  const auto& sk = cx.scene.keypoints;
  const double lr2 = cx.opt.local_ratio * cx.opt.local_ratio;
  std::vector<int> cand;
  const int n = list ? static_cast<int>(list->size()) : static_cast<int>(rk.size());
  int tried = 0;
  for (int li = 0; li < n && tried < max_tried; ++li) {
    const int i = list ? (*list)[li] : li;
    Vec2 xs;
    double ang, size;
    if (!pred.predict(rk[i], &xs, &ang, &size)) continue;
    if (size < cx.min_scene_size) continue;  // too small to have been detected in the scene
    ++tried;
    const double r = radius_px(xs);
    if (xs.x() < cx.bounds.x - r || xs.y() < cx.bounds.y - r ||
        xs.x() > cx.bounds.x + cx.bounds.width + r || xs.y() > cx.bounds.y + cx.bounds.height + r)
      continue;
    cx.grid.radiusSearch(xs, r, &cand);
    int best = -1, d1 = INT_MAX, d2 = INT_MAX;
    const int16_t* rd = cx.ref.descriptors_s16.ptr<int16_t>(i);
    for (int j : cand) {
      const cv::KeyPoint& k = sk[j];
      if (std::abs(wrapPi(deg2rad(k.angle) - ang)) > cx.opt.orientation_tolerance_rad) continue;
      if (std::abs(k.size - size) > cx.opt.scale_tolerance * size) continue;
      const int d = dist2(rd, cx.scene16.ptr<int16_t>(j));
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
};

HomographyOptions homographyOptions(const MatchOptions& opt) {
  HomographyOptions h;
  h.ransac_reproj_px = opt.ransac_reproj_px;
  h.seed = opt.seed;
  return h;
}

/// Robust homography from matches; fills a candidate when it passes min_inliers and plausibility.
bool makeCandidate(const Context& cx, const std::vector<Correspondence>& matches, Candidate* c) {
  if (static_cast<int>(matches.size()) < std::max(4, cx.opt.min_inliers)) return false;
  std::vector<Vec2> a, b;
  a.reserve(matches.size());
  b.reserve(matches.size());
  for (const auto& m : matches) {
    a.push_back(pt(cx.ref.features.keypoints[m.ref]));
    b.push_back(pt(cx.scene.keypoints[m.scene]));
  }
  HomographyResult hr = estimateHomography(a, b, homographyOptions(cx.opt));
  if (!hr.ok || static_cast<int>(hr.inliers.size()) < cx.opt.min_inliers) return false;
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
    if (static_cast<int>(keep.size()) < cx.opt.min_inliers) return false;
    const Eigen::Matrix3d Ht = fitHomographyLeastSquares(ka, kb);
    if (!Ht.allFinite()) return false;
    hr.H = Ht;
    hr.inliers = keep;
  }
  if (!homographyPlausible(hr.H, cx.ref.hull_px, kMinAreaPx2)) return false;
  std::vector<cv::Point2f> in, hull;
  for (int k : hr.inliers) in.push_back(cx.ref.features.keypoints[matches[k].ref].pt);
  cv::convexHull(in, hull);
  if (cv::contourArea(hull) < cx.opt.min_inlier_spread * cx.ref.feature_hull_area_px2) return false;
  c->H = hr.H;
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
    if (free.size() != c.inliers.size() && !makeCandidate(cx, free, &c)) continue;
    for (const auto& m : c.inliers) used[m.scene] = 1;
    accepted.push_back(c);
    out.push_back({c.inliers, c.H, c.score});
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
bool evaluateHypothesis(const Context& cx, int r, int s, Candidate* out) {
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
  localSearch(cx, sim, &cx.ref.neighbours[r], simRadius, &m, kQuickNeighbours);
  if (static_cast<int>(m.size()) < kQuickMinMatches) return false;
  localSearch(cx, sim, &cx.ref.neighbours[r], simRadius, &m);
  if (static_cast<int>(m.size()) < kPass1MinMatches) return false;

  // A homography fitted to a neighbourhood extrapolates with an error that grows with the
  // distance from it; the second fit covers the whole pattern and is trusted uniformly.
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<Vec2> a, b;
    for (const auto& x : m) {
      a.push_back(pt(rk[x.ref]));
      b.push_back(pt(sk[x.scene]));
    }
    const HomographyResult h = estimateHomography(a, b, homographyOptions(cx.opt));
    if (!h.ok || static_cast<int>(h.inliers.size()) < kPass1MinMatches) return false;
    const Predictor hom = Predictor::homography(h.H);
    const double e0 = std::max(kHomographyErrorPx, h.rms_px);
    if (pass == 0) {
      localSearch(cx, hom, nullptr, [&](const Vec2& xs) {
        return factor * (e0 + kHomographyErrorPerPx * (xs - seed).norm());
      }, &m);
    } else {
      localSearch(cx, hom, nullptr, [&](const Vec2&) { return factor * e0; }, &m);
    }
  }
  return makeCandidate(cx, toCorrespondences(m), out);
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
  for (int j = 0; j < static_cast<int>(nn.size()); ++j) {
    if (nn[j].best < 0 || nn[j].d2 == INT_MAX) continue;
    const double ratio2 = static_cast<double>(nn[j].d1) / nn[j].d2;
    if (ratio2 < gr2) {
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
    if (!evaluateHypothesis(cx, sd.ref, sd.scene, &c)) continue;
    clean_candidate |= !sd.ambiguous;
    for (const auto& m : c.inliers) covered[m.scene] = 1;
    cands.push_back(std::move(c));
  }
  res.instances = selectInstances(cx, std::move(cands));
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
    if (!makeCandidate(cx, matches, &c)) break;
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
    res.instances.push_back({c.inliers, c.H, c.score});
  }
  return res;
}

}  // namespace

bool knnKernelAvailable(KnnKernel kernel) { return cpuHas(kernel); }

std::vector<NearestTwo> nearestTwo(const ReferenceIndex& ref, const Features& scene, KnnKernel kernel) {
  std::vector<int> n2;
  const cv::Mat s16 = toS16(scene.descriptors, &n2);
  return globalKnn(s16, n2, ref, kernel);
}

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
}

ReferenceIndex buildReferenceIndex(Features f, const std::vector<Vec2>& polygon,
                                   const MatchOptions& opt) {
  opt.check();
  refgrasp::check(polygon.empty() || polygon.size() >= 3, "buildReferenceIndex",
                  "pattern polygon needs >= 3 vertices");
  refgrasp::check(f.descriptors.rows == f.size() && (f.size() == 0 || f.descriptors.cols == kDim),
                  "buildReferenceIndex", "descriptors must be N x 128");
  ReferenceIndex ri;
  ri.polygon_px = polygon;
  if (ri.polygon_px.empty()) {
    const double w = f.image_size.width, h = f.image_size.height;
    ri.polygon_px = {Vec2(-0.5, -0.5), Vec2(w - 0.5, -0.5), Vec2(w - 0.5, h - 0.5), Vec2(-0.5, h - 0.5)};
  }
  for (const auto& p : ri.polygon_px) refgrasp::check(p.allFinite(), "buildReferenceIndex", "non-finite polygon vertex");
  std::vector<cv::Point2f> poly, hull;
  for (const auto& p : ri.polygon_px) poly.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  cv::convexHull(poly, hull, /*clockwise=*/false);
  for (const auto& p : hull) ri.hull_px.emplace_back(p.x, p.y);
  // Centroid of the polygon (area-weighted), bounding-box diagonal.
  refgrasp::check(std::abs(shoelace2(ri.polygon_px.data(), ri.polygon_px.size())) > 1e-9,
                  "buildReferenceIndex", "pattern polygon has zero area");
  ri.centre_px = polygonCentroid(ri.polygon_px);
  Eigen::Vector2d lo = ri.polygon_px[0], hi = ri.polygon_px[0];
  for (const auto& p : ri.polygon_px) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  ri.diagonal_px = (hi - lo).norm();

  // Inside the polygon, strongest first.
  std::vector<int> keep;
  for (int i = 0; i < f.size(); ++i)
    if (cv::pointPolygonTest(poly, f.keypoints[i].pt, false) >= 0) keep.push_back(i);
  auto stronger = [&](int a, int b) { return f.keypoints[a].response > f.keypoints[b].response; };
  std::stable_sort(keep.begin(), keep.end(), stronger);
  if (static_cast<int>(keep.size()) > opt.max_reference_features) {
    // Round robin over octaves (strongest first within each): coarse features are few and weak
    // but the only ones left when the object is far away, so the cap must not drop them.
    std::map<int, std::vector<int>> octaves;
    for (int i : keep) octaves[static_cast<int>(std::floor(std::log2(std::max(1e-3f, f.keypoints[i].size))))].push_back(i);
    std::vector<int> picked;
    for (size_t rank = 0; static_cast<int>(picked.size()) < opt.max_reference_features; ++rank)
      for (const auto& [oct, list] : octaves)
        if (rank < list.size() && static_cast<int>(picked.size()) < opt.max_reference_features)
          picked.push_back(list[rank]);
    std::stable_sort(picked.begin(), picked.end(), stronger);
    keep = picked;
  }
  ri.features.image_size = f.image_size;
  ri.features.descriptors.create(static_cast<int>(keep.size()), kDim, CV_32F);
  for (size_t k = 0; k < keep.size(); ++k) {
    ri.features.keypoints.push_back(f.keypoints[keep[k]]);
    f.descriptors.row(keep[k]).copyTo(ri.features.descriptors.row(static_cast<int>(k)));
  }
  ri.descriptors_s16 = toS16(ri.features.descriptors, &ri.descriptor_norm2);
  if (!ri.features.keypoints.empty()) {
    std::vector<cv::Point2f> pts, fh;
    for (const auto& k : ri.features.keypoints) pts.push_back(k.pt);
    cv::convexHull(pts, fh);
    ri.feature_hull_area_px2 = cv::contourArea(fh);
  }
  ri.descriptors_lo_s8.create(ri.descriptors_s16.size(), CV_8S);
  ri.descriptors_hi_s8.create(ri.descriptors_s16.size(), CV_8S);
  ri.has_hi.assign(ri.descriptors_s16.rows, 0);
  for (int i = 0; i < ri.descriptors_s16.rows; ++i)
    for (int k = 0; k < kDim; ++k) {
      const int v = ri.descriptors_s16.at<int16_t>(i, k);
      ri.descriptors_lo_s8.at<int8_t>(i, k) = static_cast<int8_t>(v & 127);
      ri.descriptors_hi_s8.at<int8_t>(i, k) = static_cast<int8_t>(v >> 7);
      ri.has_hi[i] |= v >= 128;
    }

  const int n = ri.features.size();
  ri.neighbours.resize(n);
  std::vector<std::pair<double, int>> d(n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j)
      d[j] = {(pt(ri.features.keypoints[i]) - pt(ri.features.keypoints[j])).squaredNorm() + (i == j ? -1 : 0), j};
    const int k = std::min(n, kStoredNeighbours);
    std::partial_sort(d.begin(), d.begin() + k, d.end());
    for (int q = 0; q < k; ++q) ri.neighbours[i].push_back(d[q].second);
  }
  return ri;
}

MatchResult matchObject(const ReferenceIndex& ref, const Features& scene, const GridIndex& grid,
                        const MatchOptions& opt) {
  opt.check();
  MatchResult res;
  if (ref.features.size() < 4 || scene.size() < 4) return res;
  Context cx{ref, scene, grid, opt, {}, {}, 0, 0, {}};
  cx.scene16 = toS16(scene.descriptors, &cx.scene_norm2);
  double min_size = 1e9;
  for (const auto& k : scene.keypoints) min_size = std::min<double>(min_size, k.size);
  cx.min_scene_size = 0.8 * min_size;
  cx.max_dd2 = opt.max_descriptor_distance * opt.max_descriptor_distance;
  cx.bounds = cv::Rect2d(-0.5, -0.5, scene.image_size.width, scene.image_size.height);
  const std::vector<NearestTwo> nn = globalKnn(cx.scene16, cx.scene_norm2, ref);
  return opt.matcher == MatcherType::kPaper ? matchPaper(cx, nn) : matchRatio(cx, nn);
}

}  // namespace refgrasp::detector
