#include "detector/pose.h"

#include <Eigen/SVD>
#include <cmath>
#include <opencv2/calib3d.hpp>

#include "core/error.h"
#include "detector/homography.h"

namespace refgrasp::detector {

const char* poseMethodName(PoseMethod m) { return m == PoseMethod::kPaper ? "paper" : "refined"; }

void PoseOptions::check() const {
  refgrasp::check(paper_lm_iterations >= 0, "PoseOptions.paper_lm_iterations", "must be >= 0");
  refgrasp::check(refined_lm_iterations >= 0, "PoseOptions.refined_lm_iterations", "must be >= 0");
  refgrasp::check(std::isfinite(huber_px) && huber_px >= 0, "PoseOptions.huber_px",
                  "must be finite and >= 0");
  refgrasp::check(std::isfinite(keypoint_sigma_per_size) && keypoint_sigma_per_size >= 0,
                  "PoseOptions.keypoint_sigma_per_size", "must be finite and >= 0");
  refgrasp::check(std::isfinite(min_corner_depth_m) && min_corner_depth_m > 0,
                  "PoseOptions.min_corner_depth_m", "must be positive");
}

Eigen::Vector2d projectPinhole(const Eigen::Matrix3d& K, const Eigen::Vector3d& Xc) {
  const Eigen::Vector3d p = K * Xc;
  return p.head<2>() / p.z();
}

std::optional<Eigen::Vector3d> PlanarTarget::backProject(const Eigen::Vector2d& ref_px) const {
  // Ray X_c = lambda d in the reference camera; plane z_p = 0, i.e. e3 . (pMc X_c) = 0.
  const Pose pMc = (ref_cMo * oMp).inverse();
  const Eigen::Vector3d d = K_ref.inverse() * ref_px.homogeneous();
  const double denom = pMc.R.row(2).dot(d);
  if (std::abs(denom) < 1e-12) return std::nullopt;
  const double lambda = -pMc.t.z() / denom;
  if (!(lambda > 0) || !std::isfinite(lambda)) return std::nullopt;
  return ref_cMo.inverse() * (lambda * d);
}

std::optional<PlanarTarget> makePlanarTarget(const Eigen::Matrix3d& K_ref, const Pose& ref_cMo,
                                             const Eigen::Vector3d& plane_normal_o,
                                             double plane_offset_m,
                                             const std::array<Eigen::Vector2d, 4>& corners_ref_px) {
  const double nn = plane_normal_o.norm();
  if (!(nn > 1e-12) || !std::isfinite(plane_offset_m)) return std::nullopt;
  PlanarTarget t;
  t.K_ref = K_ref;
  t.ref_cMo = ref_cMo;
  // Plane frame: origin at the plane point closest to the object origin, z along the normal,
  // x as close as possible to the object x axis (identity for the default plane z = 0).
  const Eigen::Vector3d z = plane_normal_o / nn;
  Eigen::Vector3d x = Eigen::Vector3d::UnitX() - z * z.x();
  if (x.norm() < 1e-6) x = Eigen::Vector3d::UnitY() - z * z.y();
  x.normalize();
  Eigen::Matrix3d R;
  R << x, z.cross(x), z;
  t.oMp = Pose(R, z * (plane_offset_m / nn));
  t.corners_ref_px = corners_ref_px;
  for (int i = 0; i < 4; ++i) {
    const auto X = t.backProject(corners_ref_px[i]);
    if (!X) return std::nullopt;
    t.corners_o[i] = *X;
  }
  return t;
}

namespace {

Eigen::Matrix3d nearestRotation(const Eigen::Matrix3d& M) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();
  if (R.determinant() < 0) {
    Eigen::Matrix3d U = svd.matrixU();
    U.col(2) *= -1;
    R = U * svd.matrixV().transpose();
  }
  return R;
}

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

bool cornersInFront(const Pose& cMo, const PlanarTarget& target, double min_depth) {
  for (const auto& X : target.corners_o)
    if (!((cMo * X).z() > min_depth)) return false;
  return true;
}

}  // namespace

std::optional<Pose> poseFromHomography(const Eigen::Matrix3d& H, const PlanarTarget& target,
                                       const Eigen::Matrix3d& K_scene) {
  if (!H.allFinite()) return std::nullopt;
  // Plane points (x, y, 0, 1)_p: x_ref ~ K_ref A_ref (x, y, 1), x_s ~ K_s A_s (x, y, 1) with
  // A = [r1 r2 t] of cMp, so A_s ~ K_s^-1 H K_ref A_ref (eq. 7 restricted to the plane).
  const Pose ref_cMp = target.ref_cMo * target.oMp;
  Eigen::Matrix3d A_ref;
  A_ref << ref_cMp.R.col(0), ref_cMp.R.col(1), ref_cMp.t;
  Eigen::Matrix3d A = K_scene.inverse() * H * target.K_ref * A_ref;
  const double n = 0.5 * (A.col(0).norm() + A.col(1).norm());
  if (!(n > 1e-12) || !std::isfinite(n)) return std::nullopt;
  double k = 1.0 / n;
  if (A(2, 2) * k < 0) k = -k;  // pattern origin in front of the camera
  A *= k;
  Eigen::Matrix3d M;
  M << A.col(0), A.col(1), A.col(0).cross(A.col(1));
  const Pose cMp(nearestRotation(M), A.col(2));
  const Pose cMo = cMp * target.oMp.inverse();
  if (!cMo.isFinite()) return std::nullopt;
  return cMo;
}

void reprojectionResidual(const Pose& cMo, const Eigen::Vector3d& X_o, const Eigen::Vector2d& y_px,
                          const Eigen::Matrix3d& K, Eigen::Vector2d* r,
                          Eigen::Matrix<double, 2, 6>* J) {
  const Eigen::Vector3d RX = cMo.R * X_o;
  const Eigen::Vector3d Xc = RX + cMo.t;
  const double iz = 1.0 / Xc.z();
  const double fx = K(0, 0), fy = K(1, 1), s = K(0, 1);
  const double xn = Xc.x() * iz, yn = Xc.y() * iz;
  if (r) *r = Eigen::Vector2d(fx * xn + s * yn + K(0, 2), fy * yn + K(1, 2)) - y_px;
  if (J) {
    Eigen::Matrix<double, 2, 3> dpi;
    dpi << fx * iz, s * iz, -(fx * xn + s * yn) * iz, 0, fy * iz, -fy * yn * iz;
    // d(exp([dw]x) R X)/d(dw) at 0 = -[R X]x; dt enters Xc directly.
    J->leftCols<3>() = -dpi * skew(RX);
    J->rightCols<3>() = dpi;
  }
}

PoseResult refinePoseLM(const std::vector<Eigen::Vector3d>& points_o,
                        const std::vector<Eigen::Vector2d>& points_px, const Eigen::Matrix3d& K,
                        const Pose& initial_cMo, int iterations, double huber_px,
                        const std::vector<double>& sigma_px) {
  PoseResult res;
  const size_t n = points_o.size();
  if (n < 3 || points_px.size() != n || !initial_cMo.isFinite()) return res;
  if (!sigma_px.empty() && sigma_px.size() != n) return res;
  std::vector<double> inv_sigma(n, 1.0);
  for (size_t i = 0; i < sigma_px.size(); ++i) {
    if (!(sigma_px[i] > 0) || !std::isfinite(sigma_px[i])) return res;
    inv_sigma[i] = 1.0 / sigma_px[i];
  }
  auto weight = [&](double e) { return (huber_px > 0 && e > huber_px) ? huber_px / e : 1.0; };
  // Robust cost: Huber rho(e) = e^2 (e <= d), 2 d e - d^2 (e > d).
  auto cost = [&](const Pose& P, bool* in_front) {
    double c = 0;
    *in_front = true;
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d Xc = P * points_o[i];
      if (!(Xc.z() > 1e-9)) {
        *in_front = false;
        return 0.0;
      }
      Eigen::Vector2d r;
      reprojectionResidual(P, points_o[i], points_px[i], K, &r, nullptr);
      const double e = r.norm() * inv_sigma[i];
      c += (huber_px > 0 && e > huber_px) ? 2 * huber_px * e - huber_px * huber_px : e * e;
    }
    return c;
  };
  Pose P = initial_cMo;
  bool front = false;
  double c = cost(P, &front);
  if (!front) return res;
  double lambda = 1e-3;
  int it = 0;
  bool converged = false;
  for (; it < iterations && !converged; ++it) {
    Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    for (size_t i = 0; i < n; ++i) {
      Eigen::Vector2d r;
      Eigen::Matrix<double, 2, 6> J;
      reprojectionResidual(P, points_o[i], points_px[i], K, &r, &J);
      const double s2 = inv_sigma[i] * inv_sigma[i];
      const double w = weight(r.norm() * inv_sigma[i]) * s2;
      A.noalias() += w * J.transpose() * J;
      g.noalias() += w * J.transpose() * r;
    }
    bool improved = false;
    for (int tries = 0; tries < 10 && !improved; ++tries) {
      Eigen::Matrix<double, 6, 6> Ad = A;
      Ad.diagonal() += lambda * A.diagonal().cwiseMax(1e-9);
      const Eigen::Matrix<double, 6, 1> d = -Ad.ldlt().solve(g);
      if (!d.allFinite()) break;
      const Pose Pn(Pose::fromRotationVector(d.head<3>(), Eigen::Vector3d::Zero()).R * P.R,
                    P.t + d.tail<3>());
      bool fr = false;
      const double cn = cost(Pn, &fr);
      if (fr && cn <= c) {
        improved = true;
        const double rel = (c - cn) / std::max(c, 1e-300);
        P = Pn;
        c = cn;
        lambda = std::max(lambda * 0.3, 1e-9);
        converged = rel < 1e-15 || d.norm() < 1e-14;
      } else {
        lambda *= 10;
      }
    }
    if (!improved) break;
  }
  double sq = 0;
  for (size_t i = 0; i < n; ++i) {
    Eigen::Vector2d r;
    reprojectionResidual(P, points_o[i], points_px[i], K, &r, nullptr);
    sq += r.squaredNorm();
  }
  res.ok = P.isFinite();
  res.cMo = P;
  res.rms_px = std::sqrt(sq / n);
  res.iterations = it;
  return res;
}

PoseResult estimatePosePaper(const Eigen::Matrix3d& H, const PlanarTarget& target,
                             const Eigen::Matrix3d& K_scene, const PoseOptions& opt) {
  PoseResult res;
  const auto init = poseFromHomography(H, target, K_scene);
  if (!init) return res;
  std::vector<Eigen::Vector3d> X(target.corners_o.begin(), target.corners_o.end());
  std::vector<Eigen::Vector2d> y;
  for (const auto& c : target.corners_ref_px) y.push_back(applyHomography(H, c));
  res = refinePoseLM(X, y, K_scene, *init, opt.paper_lm_iterations, 0.0);
  if (res.ok && !cornersInFront(res.cMo, target, opt.min_corner_depth_m)) res.ok = false;
  return res;
}

namespace {

/// IPPE's solutions (one or two: a planar pattern's pose ambiguity), each refined by LM.
std::vector<PoseResult> refinedIppeSolutions(const std::vector<Eigen::Vector3d>& points_o,
                                             const std::vector<Eigen::Vector2d>& points_px,
                                             const PlanarTarget& target, const Eigen::Matrix3d& K_scene,
                                             const PoseOptions& opt, const std::vector<double>& sigma_px,
                                             bool both) {
  std::vector<PoseResult> out;
  const size_t n = points_o.size();
  if (n < 4 || points_px.size() != n) return out;
  // IPPE wants points on z = 0: give it plane-frame coordinates.
  const Pose pMo = target.oMp.inverse();
  std::vector<cv::Point3d> obj;
  std::vector<cv::Point2d> img;
  obj.reserve(n);
  img.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d Xp = pMo * points_o[i];
    obj.emplace_back(Xp.x(), Xp.y(), 0.0);
    img.emplace_back(points_px[i].x(), points_px[i].y());
  }
  cv::Mat Kcv(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) Kcv.at<double>(r, c) = K_scene(r, c);
  std::vector<cv::Mat> rvecs, tvecs;
  try {
    if (both) {
      cv::solvePnPGeneric(obj, img, Kcv, cv::noArray(), rvecs, tvecs, false, cv::SOLVEPNP_IPPE);
    } else {
      cv::Mat rvec, tvec;
      if (cv::solvePnP(obj, img, Kcv, cv::noArray(), rvec, tvec, false, cv::SOLVEPNP_IPPE)) {
        rvecs.push_back(rvec);
        tvecs.push_back(tvec);
      }
    }
  } catch (const cv::Exception&) {
    return out;
  }
  for (size_t k = 0; k < rvecs.size() && k < tvecs.size(); ++k) {
    const cv::Mat& rvec = rvecs[k];
    const cv::Mat& tvec = tvecs[k];
    const Eigen::Vector3d rv(rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2));
    const Eigen::Vector3d tv(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
    const Pose cMo = Pose::fromRotationVector(rv, tv) * pMo;
    PoseResult res = refinePoseLM(points_o, points_px, K_scene, cMo, opt.refined_lm_iterations, opt.huber_px,
                                  sigma_px);
    if (res.ok && !cornersInFront(res.cMo, target, opt.min_corner_depth_m)) res.ok = false;
    if (res.ok) out.push_back(res);
  }
  return out;
}

}  // namespace

PoseResult estimatePoseRefined(const std::vector<Eigen::Vector3d>& points_o,
                               const std::vector<Eigen::Vector2d>& points_px,
                               const PlanarTarget& target, const Eigen::Matrix3d& K_scene,
                               const PoseOptions& opt, const std::vector<double>& sigma_px) {
  const std::vector<PoseResult> s = refinedIppeSolutions(points_o, points_px, target, K_scene, opt, sigma_px, false);
  return s.empty() ? PoseResult() : s.front();
}

PoseResult estimatePoseRefinedNear(const std::vector<Eigen::Vector3d>& points_o,
                                   const std::vector<Eigen::Vector2d>& points_px,
                                   const PlanarTarget& target, const Eigen::Matrix3d& K_scene,
                                   const PoseOptions& opt, const Pose& prior, double ambiguity_margin_px) {
  const std::vector<PoseResult> s = refinedIppeSolutions(points_o, points_px, target, K_scene, opt, {}, true);
  if (s.empty()) return {};
  double best_rms = s.front().rms_px;
  for (const PoseResult& r : s) best_rms = std::min(best_rms, r.rms_px);
  const PoseResult* pick = nullptr;
  for (const PoseResult& r : s) {
    if (!(r.rms_px <= best_rms + ambiguity_margin_px)) continue;
    if (!pick || rotationError(r.cMo, prior) < rotationError(pick->cMo, prior)) pick = &r;
  }
  return pick ? *pick : s.front();
}

}  // namespace refgrasp::detector
