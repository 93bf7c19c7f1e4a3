#include "detector/homography.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "core/error.h"
#include "core/geometry.h"

namespace refgrasp::detector {
namespace {

using Vec2 = Eigen::Vector2d;
const double kNaN = std::numeric_limits<double>::quiet_NaN();

Vec2 apply(const Eigen::Matrix3d& T, const Vec2& x) {
  const Eigen::Vector3d y = T * x.homogeneous();
  return y.hnormalized();
}

/// Both point sets in Hartley-normalised coordinates: a = Ta from, b = Tb to.
struct Normalized {
  Eigen::Matrix3d Ta, Tb;
  std::vector<Vec2> a, b;
};
Normalized normalize(const std::vector<Vec2>& from, const std::vector<Vec2>& to) {
  Normalized n{hartleyNormalization(from), hartleyNormalization(to), {}, {}};
  n.a.reserve(from.size());
  n.b.reserve(to.size());
  for (const Vec2& x : from) n.a.push_back(apply(n.Ta, x));
  for (const Vec2& x : to) n.b.push_back(apply(n.Tb, x));
  return n;
}

/// Twice the signed area of triangle abc.
double cross(const Vec2& a, const Vec2& b, const Vec2& c) {
  return (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
}

/// DLT on the points idx (already normalised coordinates), returns |H|_F = 1 or NaN.
Eigen::Matrix3d dlt(const std::vector<Vec2>& a, const std::vector<Vec2>& b) {
  Eigen::Matrix<double, 9, 9> AtA = Eigen::Matrix<double, 9, 9>::Zero();
  for (size_t i = 0; i < a.size(); ++i) {
    const double x = a[i].x(), y = a[i].y(), u = b[i].x(), v = b[i].y();
    Eigen::Matrix<double, 9, 1> r1, r2;
    r1 << -x, -y, -1, 0, 0, 0, u * x, u * y, u;
    r2 << 0, 0, 0, -x, -y, -1, v * x, v * y, v;
    AtA.noalias() += r1 * r1.transpose() + r2 * r2.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> es(AtA);
  if (es.info() != Eigen::Success) return Eigen::Matrix3d::Constant(kNaN);
  const Eigen::Matrix<double, 9, 1> h = es.eigenvectors().col(0);
  Eigen::Matrix3d H;
  H << h(0), h(1), h(2), h(3), h(4), h(5), h(6), h(7), h(8);
  return H;
}

/// Exact homography through 4 correspondences (8x8 solve, H(2,2) = 1) or NaN.
Eigen::Matrix3d fourPoint(const Vec2* a, const Vec2* b) {
  Eigen::Matrix<double, 8, 8> M;
  Eigen::Matrix<double, 8, 1> r;
  for (int i = 0; i < 4; ++i) {
    const double x = a[i].x(), y = a[i].y(), u = b[i].x(), v = b[i].y();
    M.row(2 * i) << x, y, 1, 0, 0, 0, -u * x, -u * y;
    M.row(2 * i + 1) << 0, 0, 0, x, y, 1, -v * x, -v * y;
    r(2 * i) = u;
    r(2 * i + 1) = v;
  }
  Eigen::PartialPivLU<Eigen::Matrix<double, 8, 8>> lu(M);
  if (!(std::abs(lu.determinant()) > 1e-12)) return Eigen::Matrix3d::Constant(kNaN);
  const Eigen::Matrix<double, 8, 1> h = lu.solve(r);
  Eigen::Matrix3d H;
  H << h(0), h(1), h(2), h(3), h(4), h(5), h(6), h(7), 1;
  return H;
}

/// No three of the four points (nearly) collinear, relative to their spread.
bool wellSpread(const Vec2* p) {
  double span = 0;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) span = std::max(span, (p[i] - p[j]).squaredNorm());
  const double eps = 1e-6 * span;
  return std::abs(cross(p[0], p[1], p[2])) > eps && std::abs(cross(p[0], p[1], p[3])) > eps &&
         std::abs(cross(p[0], p[2], p[3])) > eps && std::abs(cross(p[1], p[2], p[3])) > eps;
}

double transferError2(const Eigen::Matrix3d& H, const Vec2& a, const Vec2& b) {
  const Eigen::Vector3d y = H * a.homogeneous();
  if (!(y.z() > 1e-12 || y.z() < -1e-12)) return std::numeric_limits<double>::infinity();
  return (y.hnormalized() - b).squaredNorm();
}

}  // namespace

void HomographyOptions::check() const {
  refgrasp::check(std::isfinite(ransac_reproj_px) && ransac_reproj_px > 0,
                  "HomographyOptions.ransac_reproj_px", "must be > 0");
  refgrasp::check(max_iterations >= 1, "HomographyOptions.max_iterations", "must be >= 1");
  refgrasp::check(confidence > 0 && confidence < 1, "HomographyOptions.confidence",
                  "must be in (0, 1)");
}

Vec2 applyHomography(const Eigen::Matrix3d& H, const Vec2& x) { return apply(H, x); }

Eigen::Matrix3d fitHomographyLeastSquares(const std::vector<Vec2>& from, const std::vector<Vec2>& to) {
  const int n = static_cast<int>(from.size());
  if (n < 4 || static_cast<int>(to.size()) != n) return Eigen::Matrix3d::Constant(kNaN);
  for (int i = 0; i < n; ++i)
    if (!from[i].allFinite() || !to[i].allFinite()) return Eigen::Matrix3d::Constant(kNaN);
  const Normalized nz = normalize(from, to);
  const Eigen::Matrix3d &Ta = nz.Ta, &Tb = nz.Tb;
  const std::vector<Vec2>& a = nz.a;
  const std::vector<Vec2>& b = nz.b;
  Eigen::Matrix3d Hn = dlt(a, b);
  if (!Hn.allFinite()) return Hn;

  // Gauss-Newton (with a little damping) on the normalised transfer error; the largest entry of
  // Hn stays fixed, the other eight move. Normalisation is a similarity, so this minimises the
  // pixel transfer error up to a constant factor.
  Eigen::Index fr = 0, fc = 0;
  Hn.array().abs().maxCoeff(&fr, &fc);
  const int fixed = static_cast<int>(fc * 3 + fr);  // column-major index
  Hn /= Hn(fixed);
  auto cost = [&](const Eigen::Matrix3d& H) {
    double c = 0;
    for (int i = 0; i < n; ++i) c += transferError2(H, a[i], b[i]);
    return c;
  };
  double c0 = cost(Hn);
  double lambda = 1e-6;
  for (int it = 0; it < 20 && std::isfinite(c0); ++it) {
    Eigen::Matrix<double, 9, 9> JtJ = Eigen::Matrix<double, 9, 9>::Zero();
    Eigen::Matrix<double, 9, 1> Jtr = Eigen::Matrix<double, 9, 1>::Zero();
    for (int i = 0; i < n; ++i) {
      const double x = a[i].x(), y = a[i].y();
      const Eigen::Vector3d p = Hn * Eigen::Vector3d(x, y, 1);
      const double w = p.z(), u = p.x() / w, v = p.y() / w;
      // d(u,v)/d(H entries), entries in column-major order (matches Eigen storage of Hn).
      Eigen::Matrix<double, 2, 9> J;
      J << x / w, 0, -u * x / w, y / w, 0, -u * y / w, 1 / w, 0, -u / w,  //
          0, x / w, -v * x / w, 0, y / w, -v * y / w, 0, 1 / w, -v / w;
      J.col(fixed).setZero();
      const Eigen::Vector2d r(u - b[i].x(), v - b[i].y());
      JtJ.noalias() += J.transpose() * J;
      Jtr.noalias() += J.transpose() * r;
    }
    JtJ(fixed, fixed) = 1;
    Eigen::Matrix<double, 9, 9> A = JtJ;
    A.diagonal() *= 1 + lambda;
    const Eigen::Matrix<double, 9, 1> dh = A.ldlt().solve(-Jtr);
    if (!dh.allFinite()) break;
    Eigen::Matrix3d Hc = Hn + Eigen::Map<const Eigen::Matrix3d>(dh.data());
    const double c1 = cost(Hc);
    if (c1 < c0) {
      const bool tiny = c0 - c1 < 1e-14 * (1 + c0);
      Hn = Hc;
      c0 = c1;
      lambda = std::max(1e-9, lambda * 0.1);
      if (tiny) break;
    } else {
      lambda *= 10;
      if (lambda > 1e6) break;
    }
  }
  Eigen::Matrix3d H = Tb.inverse() * Hn * Ta;
  if (!H.allFinite() || std::abs(H(2, 2)) < 1e-15) return Eigen::Matrix3d::Constant(kNaN);
  return H / H(2, 2);
}

Eigen::Matrix3d fitAffineLeastSquares(const std::vector<Vec2>& from, const std::vector<Vec2>& to) {
  const int n = static_cast<int>(from.size());
  if (n < 3 || static_cast<int>(to.size()) != n) return Eigen::Matrix3d::Constant(kNaN);
  // Centred coordinates: the 2x2 part from the centred normal equations, then the translation.
  Vec2 ma = Vec2::Zero(), mb = Vec2::Zero();
  for (int i = 0; i < n; ++i) {
    if (!from[i].allFinite() || !to[i].allFinite()) return Eigen::Matrix3d::Constant(kNaN);
    ma += from[i];
    mb += to[i];
  }
  ma /= n;
  mb /= n;
  Eigen::Matrix2d S = Eigen::Matrix2d::Zero(), C = Eigen::Matrix2d::Zero();
  for (int i = 0; i < n; ++i) {
    const Vec2 x = from[i] - ma, y = to[i] - mb;
    S.noalias() += x * x.transpose();
    C.noalias() += y * x.transpose();
  }
  // Collinear (or coincident) points: the smallest spread direction is (near) empty.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(S);
  if (es.info() != Eigen::Success || !(es.eigenvalues()(0) > 1e-9 * std::max(1.0, es.eigenvalues()(1))))
    return Eigen::Matrix3d::Constant(kNaN);
  const Eigen::Matrix2d M = C * S.inverse();
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();
  A.topLeftCorner<2, 2>() = M;
  A.topRightCorner<2, 1>() = mb - M * ma;
  if (!A.allFinite()) return Eigen::Matrix3d::Constant(kNaN);
  return A;
}

HomographyResult estimateHomography(const std::vector<Vec2>& from, const std::vector<Vec2>& to,
                                    const HomographyOptions& opt) {
  opt.check();
  return estimateHomographyUnchecked(from, to, opt);
}

HomographyResult estimateHomographyUnchecked(const std::vector<Vec2>& from,
                                             const std::vector<Vec2>& to,
                                             const HomographyOptions& opt) {
  HomographyResult res;
  const int n = static_cast<int>(from.size());
  if (n < 4 || static_cast<int>(to.size()) != n) return res;
  for (int i = 0; i < n; ++i)
    if (!from[i].allFinite() || !to[i].allFinite()) return res;

  const Normalized nz = normalize(from, to);
  const Eigen::Matrix3d &Ta = nz.Ta, &Tb = nz.Tb;
  const std::vector<Vec2>& a = nz.a;
  const std::vector<Vec2>& b = nz.b;
  const double thr2 = opt.ransac_reproj_px * opt.ransac_reproj_px;
  auto inliersOf = [&](const Eigen::Matrix3d& H, std::vector<int>* out) {
    out->clear();
    for (int i = 0; i < n; ++i)
      if (transferError2(H, from[i], to[i]) <= thr2) out->push_back(i);
  };

  std::mt19937_64 rng(opt.seed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::vector<int> best, cur;
  Eigen::Matrix3d bestH = Eigen::Matrix3d::Constant(kNaN);
  long needed = opt.max_iterations;
  const double log1mconf = std::log(1 - opt.confidence);
  for (long it = 0; it < needed; ++it) {
    int s[4];
    for (int k = 0; k < 4; ++k) {
      bool dup;
      do {
        s[k] = pick(rng);
        dup = false;
        for (int j = 0; j < k; ++j) dup |= s[j] == s[k];
      } while (dup);
    }
    const Vec2 pa[4] = {a[s[0]], a[s[1]], a[s[2]], a[s[3]]};
    const Vec2 pb[4] = {b[s[0]], b[s[1]], b[s[2]], b[s[3]]};
    if (!wellSpread(pa) || !wellSpread(pb)) continue;
    // A homography keeps the orientation of every triangle of the sample, or flips them all.
    const double o0 = cross(pa[0], pa[1], pa[2]) * cross(pb[0], pb[1], pb[2]);
    const double o1 = cross(pa[0], pa[1], pa[3]) * cross(pb[0], pb[1], pb[3]);
    const double o2 = cross(pa[0], pa[2], pa[3]) * cross(pb[0], pb[2], pb[3]);
    if ((o0 > 0) != (o1 > 0) || (o0 > 0) != (o2 > 0)) continue;
    const Eigen::Matrix3d Hn = fourPoint(pa, pb);
    if (!Hn.allFinite()) continue;
    const Eigen::Matrix3d H = Tb.inverse() * Hn * Ta;
    inliersOf(H, &cur);
    if (cur.size() > best.size()) {
      best.swap(cur);
      bestH = H;
      const double w = static_cast<double>(best.size()) / n;
      const double denom = std::log(std::max(1e-12, 1 - std::pow(w, 4)));
      if (denom < 0) needed = std::min<long>(opt.max_iterations, static_cast<long>(std::ceil(log1mconf / denom)));
      if (w >= 1) break;
    }
  }
  if (best.size() < 4) return res;

  // Least squares on the inliers, re-select, repeat until the set is stable.
  Eigen::Matrix3d H = bestH;
  std::vector<int> inl = best;
  for (int round = 0; round < 4; ++round) {
    std::vector<Vec2> fa, tb;
    for (int i : inl) {
      fa.push_back(from[i]);
      tb.push_back(to[i]);
    }
    const Eigen::Matrix3d Hr = fitHomographyLeastSquares(fa, tb);
    if (!Hr.allFinite()) break;
    inliersOf(Hr, &cur);
    if (cur.size() < inl.size() && round > 0) break;
    H = Hr;
    const bool same = cur == inl;
    inl = cur;
    if (same) break;
  }
  if (inl.size() < 4 || !H.allFinite()) return res;
  // Near-singular: the smallest singular value of the normalised H vanishes.
  const Eigen::Matrix3d Hn = Tb * H * Ta.inverse();
  const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::Matrix3d>(Hn).singularValues();
  if (!(sv(2) > 1e-8 * sv(0))) return res;
  double sum2 = 0;
  for (int i : inl) sum2 += transferError2(H, from[i], to[i]);
  res.ok = true;
  res.H = H;
  res.inliers = inl;
  res.rms_px = std::sqrt(sum2 / inl.size());
  return res;
}

bool homographyPlausible(const Eigen::Matrix3d& H, const std::vector<Vec2>& polygon,
                         double min_area_px2) {
  if (!H.allFinite() || polygon.size() < 3) return false;
  const int n = static_cast<int>(polygon.size());
  std::vector<Vec2> q(n);
  double w0 = 0;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d y = H * polygon[i].homogeneous();
    if (i == 0) w0 = y.z();
    if (!(y.z() * w0 > 0)) return false;  // polygon crosses the vanishing line
    q[i] = y.hnormalized();
    if (!q[i].allFinite()) return false;
  }
  const double src_area = shoelace2(polygon.data(), n), dst_area = shoelace2(q.data(), n);
  if (src_area * dst_area <= 0) return false;  // flipped
  if (std::abs(dst_area) / 2 < min_area_px2) return false;
  // Convex image with the source's turning direction (the source polygon is convex).
  const double sign = src_area > 0 ? 1 : -1;
  for (int i = 0; i < n; ++i) {
    const double c = cross(q[i], q[(i + 1) % n], q[(i + 2) % n]);
    const double cs = cross(polygon[i], polygon[(i + 1) % n], polygon[(i + 2) % n]);
    if (std::abs(cs) < 1e-12) continue;  // collinear source vertex
    if (c * sign <= 0) return false;
  }
  return true;
}

}  // namespace refgrasp::detector
