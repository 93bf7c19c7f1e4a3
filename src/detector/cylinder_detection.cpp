#include "detector/cylinder_detection.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/geometry.h"
#include "detector/cylinder_dense.h"
#include "detector/cylinder_views.h"
#include "detector/homography.h"
#include "detector/sanity.h"

namespace refgrasp::detector {

namespace {

// Label features are expanded to where the surface faces the camera by more than this cosine
// (84 deg from the viewing ray): SIFT still finds a feature there, foreshortened up to 10 x.
constexpr double kExpansionFacingCos = 0.1;
// The label is compared with the scene where it faces the camera by more than this (75 deg):
// nearer the limb it is a sliver where the silhouette's blend with the background dominates.
constexpr double kVerifyFacingCos = 0.25;
// The photometric refinement samples the label where it faces the camera by more than this
// (60 deg): nearer the limb one scene px spans several label columns, and the label smoothed
// isotropically no longer matches the scene smoothed there (a bias of about a degree about the
// axis when 75 deg is used).
constexpr double kDenseFacingCos = 0.5;
// Guided expansion passes (predict, match, refit); the second starts from the first's pose.
constexpr int kExpansionPasses = 2;
// An expanded match stays an inlier within this many sigmas (sigma: keypoint size x
// keypoint_sigma_per_size) of the pose's prediction, and never closer than kMinInlierPx.
constexpr double kInlierSigmas = 3;
constexpr double kMinInlierPx = 1.5;
// Robust PnP: RANSAC iterations and confidence (the band's matches are mostly inliers already).
constexpr int kPnpIterations = 100;
constexpr double kPnpConfidence = 0.999;

constexpr double kPi = 3.14159265358979323846;

double wrapPi(double a) {
  a = std::fmod(a + kPi, 2 * kPi);
  if (a < 0) a += 2 * kPi;
  return a - kPi;
}

// Label px of a candidate's reference feature (matchRegistered's numbering: a seam index's
// features count on from the label index's).
Eigen::Vector2d labelPx(const RegisteredObject& obj, int ref) {
  const int n = obj.index.features.size();
  if (ref < n) {
    const cv::Point2f& p = obj.index.features.keypoints[static_cast<size_t>(ref)].pt;
    return Eigen::Vector2d(p.x, p.y);
  }
  const cv::Point2f& p = obj.seam_index->features.keypoints[static_cast<size_t>(ref - n)].pt;
  const int W = obj.model.cylinder->image_width;
  double u = p.x + W / 2;
  if (u > W - 0.5) u -= W;
  return Eigen::Vector2d(u, p.y);
}

// Label px -> undistorted scene px at cMo, and its Jacobian d(scene px) / d(label px). False
// behind the camera.
bool projectLabel(const CylinderLabel& L, const Pose& cMo, const Eigen::Matrix3d& K, const Eigen::Vector2d& uv,
                  Eigen::Vector2d* xs, Eigen::Matrix2d* J) {
  const double th = L.theta(uv.x());
  const Eigen::Vector3d X = L.point(uv);
  const Eigen::Vector3d Xc = cMo.R * X + cMo.t;
  if (!(Xc.z() > 1e-6)) return false;
  *xs = projectPinhole(K, Xc);
  if (J) {
    const double dth = L.metresPerPixelU() / L.radius_m;
    Eigen::Matrix<double, 3, 2> dX;
    dX << L.radius_m * std::cos(th) * dth, 0, 0, L.metresPerPixelV(), L.radius_m * std::sin(th) * dth, 0;
    Eigen::Matrix<double, 2, 3> dp;
    const double z = Xc.z();
    dp << K(0, 0) / z, 0, -K(0, 0) * Xc.x() / (z * z), 0, K(1, 1) / z, -K(1, 1) * Xc.y() / (z * z);
    *J = dp * cMo.R * dX;
  }
  return xs->allFinite();
}

// 3D-2D pairs of a pose fit: label points (object frame), undistorted scene px, sigma px, and
// which correspondence each came from.
struct Pairs {
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> y;
  std::vector<double> sigma;
  std::vector<Correspondence> from;
  void add(const CylinderLabel& L, const Eigen::Vector2d& uv, const cv::KeyPoint& ks, const Correspondence& c,
           double sigma_per_size) {
    X.push_back(L.point(uv));
    y.emplace_back(ks.pt.x, ks.pt.y);
    sigma.push_back(sigma_per_size > 0 ? std::max(0.05, sigma_per_size * ks.size) : 1.0);
    from.push_back(c);
  }
  int size() const { return static_cast<int>(X.size()); }
};

double residualPx(const Pose& cMo, const Eigen::Matrix3d& K, const Eigen::Vector3d& X, const Eigen::Vector2d& y) {
  const Eigen::Vector3d Xc = cMo.R * X + cMo.t;
  if (!(Xc.z() > 1e-9)) return std::numeric_limits<double>::infinity();
  return (projectPinhole(K, Xc) - y).norm();
}

// Median and RMS reprojection error (px) of the pairs at cMo; infinite without pairs.
double medianResidual(const Pairs& p, const Pose& cMo, const Eigen::Matrix3d& K) {
  std::vector<double> r;
  for (int i = 0; i < p.size(); ++i)
    r.push_back(residualPx(cMo, K, p.X[static_cast<size_t>(i)], p.y[static_cast<size_t>(i)]));
  if (r.empty()) return std::numeric_limits<double>::infinity();
  std::nth_element(r.begin(), r.begin() + static_cast<long>(r.size() / 2), r.end());
  return r[r.size() / 2];
}
double rmsResidual(const Pairs& p, const Pose& cMo, const Eigen::Matrix3d& K) {
  double s = 0;
  for (int i = 0; i < p.size(); ++i)
    s += std::pow(residualPx(cMo, K, p.X[static_cast<size_t>(i)], p.y[static_cast<size_t>(i)]), 2);
  return p.size() > 0 ? std::sqrt(s / p.size()) : std::numeric_limits<double>::infinity();
}

// Huber LM over the pairs from `start`, then again over those within the inlier bound of the
// result. Keeps the kept pairs in *p. ok = false when fewer than 6 remain or LM fails.
PoseResult refitRobustly(Pairs* p, const Pose& start, const Eigen::Matrix3d& K, const PoseOptions& po,
                         double floor_px = kMinInlierPx) {
  PoseResult r;
  if (p->size() < 6) return r;
  r = refinePoseLM(p->X, p->y, K, start, po.refined_lm_iterations, po.huber_px, p->sigma);
  if (!r.ok || !r.cMo.isFinite()) return PoseResult{};
  Pairs kept;
  for (int i = 0; i < p->size(); ++i)
    if (residualPx(r.cMo, K, p->X[i], p->y[i]) <= std::max(floor_px, kInlierSigmas * p->sigma[i])) {
      kept.X.push_back(p->X[i]);
      kept.y.push_back(p->y[i]);
      kept.sigma.push_back(p->sigma[i]);
      kept.from.push_back(p->from[i]);
    }
  if (kept.size() < 6) return PoseResult{};
  *p = std::move(kept);
  r = refinePoseLM(p->X, p->y, K, r.cMo, po.refined_lm_iterations, po.huber_px, p->sigma);
  if (!r.ok || !r.cMo.isFinite()) return PoseResult{};
  return r;
}

// Step 2: robust PnP on the band's matches, then refitRobustly on its inliers, keeping those
// within ransac_reproj_px (the band's own bound: a pose from a narrow band is not yet precise;
// the expansion tightens it).
PoseResult initialPose(Pairs* p, const Eigen::Matrix3d& K, const DetectorOptions& opt) {
  if (p->size() < 6) return {};
  std::vector<cv::Point3d> obj;
  std::vector<cv::Point2d> img;
  for (int i = 0; i < p->size(); ++i) {
    obj.emplace_back(p->X[i].x(), p->X[i].y(), p->X[i].z());
    img.emplace_back(p->y[i].x(), p->y[i].y());
  }
  cv::Mat Kcv(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) Kcv.at<double>(r, c) = K(r, c);
  cv::Mat rvec, tvec;
  std::vector<int> inl;
  bool ok = false;
  try {  // degenerate points (all on one line): no pose for this candidate, the frame goes on
    ok = cv::solvePnPRansac(obj, img, Kcv, cv::noArray(), rvec, tvec, false, kPnpIterations,
                            static_cast<float>(opt.match.ransac_reproj_px), kPnpConfidence, inl, cv::SOLVEPNP_SQPNP);
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok || rvec.empty() || tvec.empty()) return {};
  const Pose start =
      Pose::fromRotationVector(Eigen::Vector3d(rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2)),
                               Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)));
  if (!start.isFinite()) return {};
  Pairs in;  // RANSAC's inliers
  for (const int i : inl) {
    if (i < 0 || i >= p->size()) continue;
    in.X.push_back(p->X[static_cast<size_t>(i)]);
    in.y.push_back(p->y[static_cast<size_t>(i)]);
    in.sigma.push_back(p->sigma[static_cast<size_t>(i)]);
    in.from.push_back(p->from[static_cast<size_t>(i)]);
  }
  *p = std::move(in);
  return refitRobustly(p, start, K, opt.pose_options, std::max(kMinInlierPx, opt.match.ransac_reproj_px));
}

float squaredL2(const float* a, const float* b) {
  float s = 0;
  for (int k = 0; k < 128; ++k) {
    const float d = a[k] - b[k];
    s += d * d;
  }
  return s;
}

// Step 3, one pass: every label feature facing the camera, matched near its prediction at cMo
// within radius_px; one scene feature keeps its descriptor-nearest label feature.
Pairs expand(const CandidateContext& ctx, const Pose& cMo, double radius_px) {
  const RegisteredObject& obj = ctx.object;
  const CylinderLabel& L = *obj.model.cylinder;
  const MatchOptions& mo = ctx.opt.match;
  const Eigen::Matrix3d K = ctx.camera.K();
  const auto& lk = obj.label_features.keypoints;
  const auto& sk = ctx.scene.keypoints;
  const double lr2 = mo.local_ratio * mo.local_ratio;
  const double max_dd2 = mo.max_descriptor_distance * mo.max_descriptor_distance;
  struct Found {
    int label, scene;
    float dd2;
  };
  std::vector<Found> found;
  std::vector<int> cand;
  for (size_t i = 0; i < lk.size(); ++i) {
    const Eigen::Vector2d uv(lk[i].pt.x, lk[i].pt.y);
    if (!L.facesCamera(uv.x(), uv.y(), cMo, kExpansionFacingCos)) continue;
    Eigen::Vector2d xs;
    Eigen::Matrix2d J;
    if (!projectLabel(L, cMo, K, uv, &xs, &J)) continue;
    const double a = lk[i].angle * kPi / 180;
    const Eigen::Vector2d dir = J * Eigen::Vector2d(std::cos(a), std::sin(a));
    const double angle = std::atan2(dir.y(), dir.x());
    const double size = lk[i].size * std::sqrt(std::abs(J.determinant()));
    if (!std::isfinite(size) || !std::isfinite(angle)) continue;
    ctx.grid->radiusSearch(xs, radius_px, &cand);
    int best = -1;
    float d1 = std::numeric_limits<float>::max(), d2 = d1;
    const float* ld = obj.label_features.descriptors.ptr<float>(static_cast<int>(i));
    for (const int j : cand) {
      const cv::KeyPoint& k = sk[static_cast<size_t>(j)];
      if (std::abs(wrapPi(k.angle * kPi / 180 - angle)) > mo.orientation_tolerance_rad) continue;
      if (std::abs(k.size - size) > mo.scale_tolerance * size) continue;
      const float d = squaredL2(ld, ctx.scene.descriptors.ptr<float>(j));
      if (d < d1) {
        d2 = d1;
        d1 = d;
        best = j;
      } else if (d < d2) {
        d2 = d;
      }
    }
    if (best < 0 || d1 > max_dd2) continue;
    if (d2 != std::numeric_limits<float>::max() && !(d1 < lr2 * d2)) continue;
    found.push_back({static_cast<int>(i), best, d1});
  }
  std::sort(found.begin(), found.end(),
            [](const Found& a, const Found& b) { return a.scene != b.scene ? a.scene < b.scene : a.dd2 < b.dd2; });
  Pairs p;
  const double k = ctx.opt.pose_options.keypoint_sigma_per_size;
  for (size_t n = 0; n < found.size(); ++n) {
    if (n > 0 && found[n].scene == found[n - 1].scene) continue;
    const cv::KeyPoint& l = lk[static_cast<size_t>(found[n].label)];
    p.add(L, Eigen::Vector2d(l.pt.x, l.pt.y), sk[static_cast<size_t>(found[n].scene)],
          {found[n].label, found[n].scene, std::sqrt(found[n].dd2)}, k);
  }
  return p;
}

// The label rendered at cMo against the scene over the label's visible part, at a coarse
// common resolution (as verifyInstance does for a plane).
struct Comparison {
  cv::Mat a, b, mask;  // label and scene on the comparison grid (CV_32F), compared grid px
  int in_part = 0;     // grid px of the visible part (before the image test)
};

// Zero-mean NCC of a and b over the mask inside box; NaN when flat (std below 1 gray level) or
// fewer than 12 px.
double correlation(const Comparison& c, const cv::Rect& box) {
  const cv::Mat m = c.mask(box);
  const int n = cv::countNonZero(m);
  if (n < 12) return std::nan("");
  cv::Scalar ma, sa, mb, sb;
  cv::meanStdDev(c.a(box), ma, sa, m);
  cv::meanStdDev(c.b(box), mb, sb, m);
  if (!(sa[0] > 1) || !(sb[0] > 1)) return std::nan("");
  cv::Mat prod = (c.a(box) - ma[0]).mul(c.b(box) - mb[0]);
  const double cov = cv::sum(prod.setTo(0, m == 0))[0] / n;
  return cov / (sa[0] * sb[0]);
}

bool sampleComparison(const RegisteredObject& obj, const VisibleLabel& part, const Pose& cMo, const cv::Mat& scene,
                      const Intrinsics& cam, const VerifyOptions& vo, Comparison* c) {
  const CylinderLabel& L = *obj.model.cylinder;
  // The visible part's area in the scene, from a coarse grid of its projection (undistorted px).
  const Eigen::Matrix3d K = cam.K();
  const double w_ref = part.u1 - part.u0, h_ref = part.v1 - part.v0;
  double a_scene = 0;
  constexpr int kCoarse = 8;
  for (int i = 0; i < kCoarse; ++i)
    for (int j = 0; j < kCoarse; ++j) {
      const Eigen::Vector2d uv(part.u0 + (i + 0.5) * w_ref / kCoarse, part.v0 + (j + 0.5) * h_ref / kCoarse);
      Eigen::Vector2d xs;
      Eigen::Matrix2d J;
      if (projectLabel(L, cMo, K, uv, &xs, &J))
        a_scene += std::abs(J.determinant()) * w_ref * h_ref / (kCoarse * kCoarse);
    }
  const double a_ref = w_ref * h_ref;
  if (!(a_scene > 16) || !(a_ref > 0) || !std::isfinite(a_scene)) return false;
  const double s =
      std::min(vo.compare_px / std::max(w_ref, h_ref), std::sqrt(a_scene / a_ref));  // grid px per label px
  const int tw = std::max(4, static_cast<int>(std::ceil(w_ref * s)));
  const int th = std::max(4, static_cast<int>(std::ceil(h_ref * s)));
  const int L_level =
      std::clamp(static_cast<int>(std::floor(std::log2(1 / s))), 0, static_cast<int>(obj.pyramid.size()) - 1);
  const double ls = std::ldexp(1.0, L_level);
  cv::Mat mapx(th, tw, CV_32F), mapy(th, tw, CV_32F), smx(th, tw, CV_32F), smy(th, tw, CV_32F);
  cv::Mat front(th, tw, CV_8UC1, cv::Scalar(0));
  Eigen::Vector2d lo(1e30, 1e30), hi(-1e30, -1e30);
  for (int v = 0; v < th; ++v)
    for (int u = 0; u < tw; ++u) {
      const Eigen::Vector2d uv(part.u0 + (u + 0.5) / s, part.v0 + (v + 0.5) / s);
      mapx.at<float>(v, u) = static_cast<float>((uv.x() + 0.5) / ls - 0.5);
      mapy.at<float>(v, u) = static_cast<float>((uv.y() + 0.5) / ls - 0.5);
      const Eigen::Vector3d Xc = cMo * L.point(uv);
      Eigen::Vector2d q(-1e6, -1e6);
      if (Xc.z() > 1e-6) {
        q = cam.project(Xc);
        if (q.allFinite()) {
          front.at<uchar>(v, u) = 255;
          lo = lo.cwiseMin(q);
          hi = hi.cwiseMax(q);
        } else {
          q = Eigen::Vector2d(-1e6, -1e6);
        }
      }
      smx.at<float>(v, u) = static_cast<float>(q.x());
      smy.at<float>(v, u) = static_cast<float>(q.y());
    }
  const double scene_step = std::sqrt(a_scene / a_ref) / s, ref_step = 1 / (s * ls);
  const int pad = static_cast<int>(std::ceil(2 * scene_step)) + 3;
  if (!(lo.x() < hi.x()) || !(lo.y() < hi.y())) return false;
  const cv::Rect crop = cv::Rect(cv::Point(static_cast<int>(std::max(-1e6, std::floor(lo.x()))) - pad,
                                           static_cast<int>(std::max(-1e6, std::floor(lo.y()))) - pad),
                                 cv::Point(static_cast<int>(std::min(1e6, std::ceil(hi.x()))) + pad + 1,
                                           static_cast<int>(std::min(1e6, std::ceil(hi.y()))) + pad + 1)) &
                        cv::Rect(0, 0, scene.cols, scene.rows);
  if (crop.area() <= 0) return false;
  // A new image when smoothed: img is the caller's scene or the registered label pyramid.
  auto lowpass = [](const cv::Mat& img, double step) {
    if (!(step > 1.2)) return img;
    cv::Mat out;
    cv::GaussianBlur(img, out, cv::Size(0, 0), 0.45 * step);
    return out;
  };
  const cv::Mat sc = lowpass(scene(crop), scene_step),
                ref = lowpass(obj.pyramid[static_cast<size_t>(L_level)], ref_step);
  smx -= static_cast<float>(crop.x);
  smy -= static_cast<float>(crop.y);
  cv::Mat a, b, inside;
  cv::remap(ref, a, mapx, mapy, cv::INTER_LINEAR, L.fullWrap() ? cv::BORDER_WRAP : cv::BORDER_REPLICATE);
  cv::remap(sc, b, smx, smy, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::remap(cv::Mat(sc.size(), CV_8UC1, cv::Scalar(255)), inside, smx, smy, cv::INTER_NEAREST, cv::BORDER_CONSTANT,
            cv::Scalar(0));
  c->in_part = tw * th;
  // One grid px in from the part's outline, in front of the camera and in the image.
  c->mask = cv::Mat::zeros(th, tw, CV_8UC1);
  c->mask(cv::Rect(1, 1, tw - 2, th - 2)).setTo(255);
  c->mask &= front;
  c->mask &= inside;
  a.convertTo(c->a, CV_32F);
  b.convertTo(c->b, CV_32F);
  cv::GaussianBlur(c->a, c->a, cv::Size(3, 3), 0.7);
  cv::GaussianBlur(c->b, c->b, cv::Size(3, 3), 0.7);
  return true;
}

// Step 5's photometric check: VerifyOptions' rules over the visible part (overall correlation,
// half the textured 3 x 3 cells agreeing, min_strong_cells strongly).
bool labelAgrees(const RegisteredObject& obj, const VisibleLabel& part, const Pose& cMo, const cv::Mat& scene,
                 const Intrinsics& cam, const VerifyOptions& vo, double* corr) {
  *corr = 0;
  if (scene.empty() || scene.type() != CV_8UC1 || obj.pyramid.empty()) return false;
  Comparison c;
  if (!sampleComparison(obj, part, cMo, scene, cam, vo, &c)) return false;
  const int n = cv::countNonZero(c.mask);
  if (n < 12 || n < 0.25 * c.in_part) return false;
  const int tw = c.a.cols, th = c.a.rows;
  const double all = correlation(c, cv::Rect(0, 0, tw, th));
  if (std::isnan(all)) return false;
  *corr = all;
  int cells = 0, agreeing = 0, strong = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const double x = correlation(
          c, cv::Rect(j * tw / 3, i * th / 3, (j + 1) * tw / 3 - j * tw / 3, (i + 1) * th / 3 - i * th / 3));
      if (std::isnan(x)) continue;
      ++cells;
      agreeing += x >= vo.min_correlation;
      strong += x >= vo.strong_correlation;
    }
  return all >= vo.min_correlation && 2 * agreeing >= cells && strong >= std::min(vo.min_strong_cells, cells);
}

// The candidate's H in label px (a seam candidate's is in rolled label px).
Eigen::Matrix3d labelHomography(const RegisteredObject& obj, const MatchCandidate& cand) {
  const int n = obj.index.features.size();
  if (cand.inliers.empty() || cand.inliers.front().ref < n) return cand.H;
  Eigen::Matrix3d T = Eigen::Matrix3d::Identity();  // label px (u in [W/2, W + W/2)) -> rolled px
  T(0, 2) = -(obj.model.cylinder->image_width / 2);
  return cand.H * T;
}

}  // namespace

std::optional<VisibleLabel> visibleLabel(const CylinderLabel& L, const Pose& cMo, double cos_margin) {
  if (!cMo.isFinite() || !(L.radius_m > 0) || L.image_width <= 0 || L.image_height <= 0) return std::nullopt;
  // The column facing the camera most directly: the camera's direction from the axis.
  const Eigen::Vector3d c = cMo.inverse().t;
  const double phi = std::atan2(c.x(), L.radius_m - c.z());
  const double centre = phi * L.radius_m / L.metresPerPixelU() + (L.image_width - 1) / 2.0;
  const double v_mid = (L.image_height - 1) / 2.0;
  if (!L.facesCamera(centre, v_mid, cMo, cos_margin)) return std::nullopt;
  // Out from it (a quarter-pixel search after a coarse one) while the surface faces the camera.
  const double period = 2 * kPi * L.radius_m / L.metresPerPixelU();
  auto edge = [&](double dir) {
    double step = period / 64, u = centre;
    for (int k = 0; k < 64 && L.facesCamera(u + dir * step, v_mid, cMo, cos_margin); ++k) u += dir * step;
    while (step > 0.25) {
      step /= 2;
      if (L.facesCamera(u + dir * step, v_mid, cMo, cos_margin)) u += dir * step;
    }
    return u;
  };
  VisibleLabel part;
  part.u0 = edge(-1);
  part.u1 = edge(+1);
  if (L.fullWrap()) {
    // Unwrapped around the label: the centre column taken into [-0.5, W - 0.5).
    const double shift = std::floor((centre + 0.5) / period) * period;
    part.u0 -= shift;
    part.u1 -= shift;
  } else {
    part.u0 = std::max(part.u0, -0.5);
    part.u1 = std::min(part.u1, L.image_width - 0.5);
  }
  if (!(part.u1 - part.u0 >= 1)) return std::nullopt;
  part.v0 = -0.5;
  part.v1 = L.image_height - 0.5;
  return part;
}

std::vector<Eigen::Vector2d> projectVisibleLabel(const CylinderLabel& L, const Pose& cMo, const Intrinsics& camera,
                                                 int n) {
  std::vector<Eigen::Vector2d> out;
  const auto part = visibleLabel(L, cMo, 0);
  if (!part || n < 2) return out;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const Eigen::Vector2d uv(part->u0 + i * (part->u1 - part->u0) / (n - 1),
                               part->v0 + j * (part->v1 - part->v0) / (n - 1));
      const Eigen::Vector3d Xc = cMo * L.point(uv);
      if (!(Xc.z() > 1e-6)) continue;
      const Eigen::Vector2d q = camera.project(Xc);
      if (q.allFinite()) out.push_back(q);
    }
  return out;
}

std::optional<std::pair<double, double>> predictedKeypointSizes(const RegisteredObject& obj, const Pose& cMo,
                                                                const Intrinsics& camera) {
  if (!obj.model.cylinder || !cMo.isFinite()) return std::nullopt;
  const CylinderLabel& L = *obj.model.cylinder;
  double lo = std::numeric_limits<double>::infinity(), hi = 0;
  for (const cv::KeyPoint& k : obj.label_features.keypoints) {
    if (!L.facesCamera(k.pt.x, k.pt.y, cMo, kExpansionFacingCos)) continue;
    Eigen::Vector2d xs;
    Eigen::Matrix2d J;
    if (!projectLabel(L, cMo, camera.K(), Eigen::Vector2d(k.pt.x, k.pt.y), &xs, &J)) continue;
    const double s = k.size * std::sqrt(std::abs(J.determinant()));
    if (!std::isfinite(s)) continue;
    lo = std::min(lo, s);
    hi = std::max(hi, s);
  }
  if (!(hi > 0)) return std::nullopt;
  return std::make_pair(lo, hi);
}

void registerCylinder(RegisteredObject* obj, const DetectorOptions& opt) {
  obj->cylinder_model = true;
  obj->dense_usable = false;  // the dense refinement aligns a plane
  const CylinderLabel& L = *obj->model.cylinder;
  const int W = L.image_width;
  Features& lf = obj->label_features;
  lf.image_size = obj->model.reference.size();
  const Features flat = obj->index.features;
  for (int i = 0; i < flat.size(); ++i) {
    const double u = flat.keypoints[static_cast<size_t>(i)].pt.x;
    if (!L.fullWrap() || (u >= W / 4.0 && u < 3 * W / 4.0)) {
      lf.keypoints.push_back(flat.keypoints[static_cast<size_t>(i)]);
      lf.descriptors.push_back(flat.descriptors.row(i));
    }
  }
  // The label's features as it looks turned away and from further (cylinder_views.h) join both
  // indices; the cap grows with them, so that they add to the label's own rather than replace them.
  const Features views = opt.match.cylinder_views
                             ? synthesisedLabelFeatures(L, obj->model.reference, flat, obj->index.polygon_px, opt.sift)
                             : Features{};
  MatchOptions mo = opt.match;
  mo.max_reference_features += views.size();
  auto joined = [](Features a, const Features& b) {
    a.keypoints.insert(a.keypoints.end(), b.keypoints.begin(), b.keypoints.end());
    if (!b.descriptors.empty()) a.descriptors.push_back(b.descriptors);
    return a;
  };
  if (views.size() > 0) obj->index = buildReferenceIndex(joined(flat, views), obj->index.polygon_px, mo);
  if (!L.fullWrap() || W < 4) return;
  const int s = W / 2;
  cv::Mat rolled;
  cv::hconcat(obj->model.reference.colRange(s, W), obj->model.reference.colRange(0, s), rolled);
  const Features seam_flat = extractSift(rolled, opt.sift);
  Features rolled_views = views;
  for (cv::KeyPoint& k : rolled_views.keypoints) {
    k.pt.x -= static_cast<float>(s);
    if (k.pt.x < -0.5f) k.pt.x += static_cast<float>(W);
  }
  obj->seam_index = buildReferenceIndex(joined(seam_flat, rolled_views), {}, mo);
  for (int i = 0; i < seam_flat.size(); ++i) {
    cv::KeyPoint k = seam_flat.keypoints[static_cast<size_t>(i)];
    if (!(k.pt.x >= W / 4.0 && k.pt.x < 3 * W / 4.0)) continue;
    k.pt.x += static_cast<float>(s);
    if (k.pt.x > W - 0.5f) k.pt.x -= static_cast<float>(W);
    lf.keypoints.push_back(k);
    lf.descriptors.push_back(seam_flat.descriptors.row(i));
  }
}

MatchResult matchRegistered(const RegisteredObject& obj, const Features& scene, const GridIndex& grid,
                            const MatchOptions& options) {
  if (!obj.cylinder_model) return matchObjectUnchecked(obj.index, scene, grid, options);
  // The inliers' spread is measured against the part of the label that can be seen at once (at
  // most half the circumference), not the whole label.
  const CylinderLabel& L = *obj.model.cylinder;
  MatchOptions opt = options;
  opt.min_inlier_spread *= std::min(1.0, kPi * L.radius_m / L.width_m);
  MatchResult m = matchObjectUnchecked(obj.index, scene, grid, opt);
  if (!obj.seam_index) return m;
  MatchResult s = matchObjectUnchecked(*obj.seam_index, scene, grid, opt);
  const int n = obj.index.features.size();
  for (MatchCandidate& c : s.instances) {
    for (Correspondence& x : c.inliers) x.ref += n;
    m.instances.push_back(std::move(c));
  }
  m.global_matches = std::max(m.global_matches, s.global_matches);
  m.hypotheses_evaluated += s.hypotheses_evaluated;
  m.weak.insert(m.weak.end(), s.weak.begin(), s.weak.end());
  m.rejected.too_few_local_matches += s.rejected.too_few_local_matches;
  m.rejected.too_few_inliers += s.rejected.too_few_inliers;
  m.rejected.not_significant += s.rejected.not_significant;
  m.rejected.implausible_homography += s.rejected.implausible_homography;
  m.rejected.narrow_inlier_spread += s.rejected.narrow_inlier_spread;
  // One instance found by both indices shares its scene features: the more inliers is kept.
  std::stable_sort(m.instances.begin(), m.instances.end(), [](const MatchCandidate& a, const MatchCandidate& b) {
    return a.inliers.size() > b.inliers.size();
  });
  std::vector<char> used(static_cast<size_t>(scene.size()), 0);
  std::vector<MatchCandidate> kept;
  for (MatchCandidate& c : m.instances) {
    if (static_cast<int>(kept.size()) >= opt.max_instances) break;
    const bool shared = std::any_of(c.inliers.begin(), c.inliers.end(),
                                    [&](const Correspondence& x) { return used[static_cast<size_t>(x.scene)] != 0; });
    if (shared) continue;
    for (const Correspondence& x : c.inliers) used[static_cast<size_t>(x.scene)] = 1;
    kept.push_back(std::move(c));
  }
  m.instances = std::move(kept);
  return m;
}

Verdict verifyCylinderCandidate(const CandidateContext& ctx, const MatchCandidate& matched) {
  const RegisteredObject& obj = ctx.object;
  const CylinderLabel& L = *obj.model.cylinder;
  const DetectorOptions& opt = ctx.opt;
  const Eigen::Matrix3d K = ctx.camera.K();
  Verdict verdict;
  Detection& d = verdict.detection;
  d.object = ctx.id;
  d.H = labelHomography(obj, matched);
  d.inliers = static_cast<int>(matched.inliers.size());
  d.score = matched.score;
  d.log10_nfa = matched.log10_nfa;
  // Step 2: the band's matches on the surface.
  Pairs band;
  for (const Correspondence& c : matched.inliers) {
    band.add(L, labelPx(obj, c.ref), ctx.scene.keypoints[static_cast<size_t>(c.scene)], c,
             opt.pose_options.keypoint_sigma_per_size);
  }
  const Pairs matched_pairs = band;
  PoseResult pose = initialPose(&band, K, opt);
  if (!pose.ok) {
    verdict.outcome = CheckOutcome::kPoseFailed;
    return verdict;
  }
  // Step 3: over the visible half, the search radius shrinking with the fit.
  Pairs pairs = band;
  if (ctx.grid) {
    for (int pass = 0; pass < kExpansionPasses; ++pass) {
      const double radius = pass == 0 ? std::max(4.0, 2 * opt.match.ransac_reproj_px)
                                      : std::max(2.0, kInlierSigmas * std::max(pose.rms_px, 0.5));
      Pairs more = expand(ctx, pose.cMo, radius);
      if (more.size() < pairs.size()) break;  // the band fits better than the expansion
      const PoseResult refit = refitRobustly(&more, pose.cMo, K, opt.pose_options);
      if (!refit.ok || more.size() < pairs.size()) break;
      pose = refit;
      pairs = std::move(more);
    }
  }
  // Step 4: the photometric refinement replaces the features' pose when the label agrees better with
  // the scene there and the features still fit it.
  if (ctx.scene.image.type() == CV_8UC1) {
    const CylinderDenseResult dense =
        refineCylinderPoseDense(L, obj.pyramid, ctx.scene.image, ctx.camera, pose.cMo, kDenseFacingCos);
    if (dense.ok && dense.correlation_after > dense.correlation_before &&
        medianResidual(pairs, dense.cMo, K) <= std::max(kMinInlierPx, 2 * medianResidual(pairs, pose.cMo, K))) {
      pose.cMo = dense.cMo;
      pose.rms_px = rmsResidual(pairs, dense.cMo, K);
    }
  }
  d.cMo = pose.cMo;
  d.pose_rms_px = pose.rms_px;
  d.inliers = pairs.size();
  // Step 5: the matcher's band must lie where the pose puts it (a pose caught in a wrong
  // minimum, or pulled by the expansion onto look-alikes, does not explain it).
  if (!(medianResidual(matched_pairs, pose.cMo, K) <= opt.match.ransac_reproj_px)) {
    verdict.outcome = CheckOutcome::kPoseDisagrees;
    d.sanity = SanityStatus::kPoseDisagrees;
    return verdict;
  }
  const auto part = visibleLabel(L, pose.cMo, kVerifyFacingCos);
  if (!part) {
    verdict.outcome = CheckOutcome::kNotVerified;
    return verdict;
  }
  const std::array<Eigen::Vector2d, 4> label_corners = {
      Eigen::Vector2d(part->u0, part->v0), Eigen::Vector2d(part->u1, part->v0), Eigen::Vector2d(part->u1, part->v1),
      Eigen::Vector2d(part->u0, part->v1)};
  for (int i = 0; i < 4; ++i)
    d.corners[static_cast<size_t>(i)] = ctx.camera.project(pose.cMo * L.point(label_corners[static_cast<size_t>(i)]));
  d.sanity = checkDetection(d.corners, d.cMo, ctx.camera.width, ctx.camera.height, opt.sanity);
  if (d.sanity != SanityStatus::kOk) {
    verdict.outcome = CheckOutcome::kSanity;
    return verdict;
  }
  if (opt.verify.enabled &&
      !labelAgrees(obj, *part, pose.cMo, ctx.scene.image, ctx.camera, opt.verify, &d.correlation)) {
    verdict.outcome = CheckOutcome::kNotVerified;
    return verdict;
  }
  verdict.outcome = CheckOutcome::kOk;
  return verdict;
}

}  // namespace refgrasp::detector
