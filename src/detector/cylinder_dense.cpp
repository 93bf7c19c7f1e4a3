#include "detector/cylinder_dense.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "detector/cylinder_detection.h"
#include "detector/pose.h"

namespace refgrasp::detector {

namespace {

// Scene smoothing (Gaussian sigma, scene px) of the coarse-to-fine levels: 2 px draws in a start
// a couple of pixels off, 1 px keeps the detail that fixes the rotation.
constexpr double kSmoothingPx[] = {2.0, 1.0};
constexpr int kIterations = 12;  // Gauss-Newton steps per level (it converges in 3-6)
// Huber threshold in robust standard deviations of the residuals (1.4826 x median |r|).
constexpr double kHuberSigmas = 1.345;

// A label sample: its surface point (object frame) and the smoothed label value there.
struct Sample {
  Eigen::Vector3d X;
  float T;
};

// Bilinear value and gradient of a CV_32F image at (x, y); false outside [0, w-2] x [0, h-2].
bool sampleImage(const cv::Mat& I, const cv::Mat& gx, const cv::Mat& gy, double x, double y, double* v, double* dx,
                 double* dy) {
  if (!(x >= 0 && y >= 0 && x < I.cols - 1 && y < I.rows - 1)) return false;
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const double fx = x - x0, fy = y - y0;
  auto lerp = [&](const cv::Mat& m) {
    const float* r0 = m.ptr<float>(y0);
    const float* r1 = m.ptr<float>(y0 + 1);
    return (1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x0 + 1]) + fy * ((1 - fx) * r1[x0] + fx * r1[x0 + 1]);
  };
  *v = lerp(I);
  *dx = lerp(gx);
  *dy = lerp(gy);
  return true;
}

double ncc(const std::vector<double>& a, const std::vector<double>& b) {
  const size_t n = a.size();
  if (n < 12) return 0;
  double ma = 0, mb = 0;
  for (size_t i = 0; i < n; ++i) ma += a[i], mb += b[i];
  ma /= n;
  mb /= n;
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < n; ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return saa > 0 && sbb > 0 ? sab / std::sqrt(saa * sbb) : 0;
}

// The scene around the samples, smoothed, with its gradients (CV_32F) and its offset.
struct SceneLevel {
  cv::Mat I, gx, gy;
  cv::Point2d origin;
};

SceneLevel sceneLevel(const cv::Mat& scene, const cv::Rect& box, double sigma) {
  SceneLevel s;
  scene(box).convertTo(s.I, CV_32F);
  cv::GaussianBlur(s.I, s.I, cv::Size(0, 0), sigma);
  cv::Sobel(s.I, s.gx, CV_32F, 1, 0, 3, 1.0 / 8);
  cv::Sobel(s.I, s.gy, CV_32F, 0, 1, 3, 1.0 / 8);
  s.origin = cv::Point2d(box.x, box.y);
  return s;
}

// The smoothed scene's value and gradient where sample q projects at cMo; false when it is behind
// the camera or off the level.
bool sceneAt(const Sample& q, const SceneLevel& s, const Intrinsics& cam, const Pose& cMo, double* v, double* dx,
             double* dy) {
  const Eigen::Vector3d Xc = cMo * q.X;
  if (!(Xc.z() > 1e-6)) return false;
  const Eigen::Vector2d p = cam.project(Xc);
  return sampleImage(s.I, s.gx, s.gy, p.x() - s.origin.x, p.y() - s.origin.y, v, dx, dy);
}

// Label (*t) and scene (*i) values of the samples in view at cMo.
void valuesAt(const std::vector<Sample>& samples, const SceneLevel& s, const Intrinsics& cam, const Pose& cMo,
              std::vector<double>* t, std::vector<double>* i) {
  for (const Sample& q : samples) {
    double v, dx, dy;
    if (!sceneAt(q, s, cam, cMo, &v, &dx, &dy)) continue;
    t->push_back(q.T);
    i->push_back(v);
  }
}

double correlationAt(const std::vector<Sample>& samples, const SceneLevel& s, const Intrinsics& cam, const Pose& cMo,
                     int* n) {
  std::vector<double> a, b;
  valuesAt(samples, s, cam, cMo, &a, &b);
  if (n) *n = static_cast<int>(a.size());
  return ncc(a, b);
}

// The label over its visible part on a grid of about one sample per scene px (coarser when
// that exceeds max_samples), smoothed by sigma_px scene px.
std::vector<Sample> labelSamples(const CylinderLabel& L, const std::vector<cv::Mat>& pyr, const Intrinsics& cam,
                                 const Pose& cMo, const VisibleLabel& part, double facing_cos, int max_samples,
                                 double sigma_px) {
  // Scene px per label px at the part's centre (finite differences through the projection).
  const Eigen::Vector2d c(0.5 * (part.u0 + part.u1), 0.5 * (part.v0 + part.v1));
  const Eigen::Vector2d p0 = cam.project(cMo * L.point(c));
  const Eigen::Vector2d pu = cam.project(cMo * L.point(c + Eigen::Vector2d(1, 0)));
  const Eigen::Vector2d pv = cam.project(cMo * L.point(c + Eigen::Vector2d(0, 1)));
  Eigen::Matrix2d J;
  J << pu - p0, pv - p0;
  const double s = std::sqrt(std::abs(J.determinant()));
  if (!(s > 1e-6) || !std::isfinite(s)) return {};
  const double w = part.u1 - part.u0, h = part.v1 - part.v0;
  const double step = std::max(1 / s, std::sqrt(w * h / max_samples));  // label px per sample
  const int tw = static_cast<int>(w / step), th = static_cast<int>(h / step);
  if (tw < 6 || th < 6) return {};
  const int level = std::clamp(static_cast<int>(std::floor(std::log2(step))), 0, static_cast<int>(pyr.size()) - 1);
  const double ls = std::ldexp(1.0, level);
  cv::Mat mapx(th, tw, CV_32F), mapy(th, tw, CV_32F);
  for (int i = 0; i < th; ++i)
    for (int j = 0; j < tw; ++j) {
      mapx.at<float>(i, j) = static_cast<float>((part.u0 + (j + 0.5) * step + 0.5) / ls - 0.5);
      mapy.at<float>(i, j) = static_cast<float>((part.v0 + (i + 0.5) * step + 0.5) / ls - 0.5);
    }
  cv::Mat grid, smooth;
  cv::remap(pyr[static_cast<size_t>(level)], grid, mapx, mapy, cv::INTER_LINEAR,
            L.fullWrap() ? cv::BORDER_WRAP : cv::BORDER_REPLICATE);
  grid.convertTo(smooth, CV_32F);
  cv::GaussianBlur(smooth, smooth, cv::Size(0, 0), std::max(0.3, sigma_px / (step * s)));
  std::vector<Sample> out;
  // One sample in from the grid's edge: the smoothing there mixes in the replicated border.
  for (int i = 1; i < th - 1; ++i)
    for (int j = 1; j < tw - 1; ++j) {
      const Eigen::Vector2d uv(part.u0 + (j + 0.5) * step, part.v0 + (i + 0.5) * step);
      if (!L.facesCamera(uv.x(), uv.y(), cMo, facing_cos)) continue;
      out.push_back({L.point(uv), smooth.at<float>(i, j)});
    }
  return out;
}

}  // namespace

CylinderDenseResult refineCylinderPoseDense(const CylinderLabel& L, const std::vector<cv::Mat>& pyr,
                                            const cv::Mat& scene, const Intrinsics& cam, const Pose& start,
                                            double facing_cos, int max_samples) {
  CylinderDenseResult res;
  res.cMo = start;
  if (pyr.empty() || scene.empty() || scene.type() != CV_8UC1 || !start.isFinite()) return res;
  const auto part = visibleLabel(L, start, facing_cos);
  if (!part) return res;
  const Eigen::Matrix3d K = cam.K();
  Pose cMo = start;
  double a = 1, b = 0;
  bool first = true;
  for (const double sigma : kSmoothingPx) {
    const std::vector<Sample> samples = labelSamples(L, pyr, cam, start, *part, facing_cos, max_samples, sigma);
    if (samples.size() < 50) return res;
    // The scene around the samples' projections at the current pose, with room to move.
    Eigen::Vector2d lo(1e30, 1e30), hi(-1e30, -1e30);
    for (const Sample& q : samples) {
      const Eigen::Vector3d Xc = cMo * q.X;
      if (!(Xc.z() > 1e-6)) continue;
      const Eigen::Vector2d p = cam.project(Xc);
      if (!p.allFinite()) continue;
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    const int pad = static_cast<int>(std::ceil(3 * sigma)) + 8;
    if (!(lo.x() < hi.x() && lo.y() < hi.y()) || hi.x() - lo.x() > 4.0 * scene.cols ||
        hi.y() - lo.y() > 4.0 * scene.rows)
      return res;
    const cv::Rect box =
        cv::Rect(cv::Point(static_cast<int>(std::floor(lo.x())) - pad, static_cast<int>(std::floor(lo.y())) - pad),
                 cv::Point(static_cast<int>(std::ceil(hi.x())) + pad, static_cast<int>(std::ceil(hi.y())) + pad)) &
        cv::Rect(0, 0, scene.cols, scene.rows);
    if (box.width < 4 || box.height < 4) return res;
    const SceneLevel s = sceneLevel(scene, box, sigma);
    if (first) {
      // Gain and offset from the start: the label's spread onto the scene's.
      std::vector<double> tv, iv;
      valuesAt(samples, s, cam, cMo, &tv, &iv);
      if (tv.size() < 50) return res;
      double mt = 0, mi = 0, st = 0, si = 0;
      for (size_t i = 0; i < tv.size(); ++i) mt += tv[i], mi += iv[i];
      mt /= tv.size();
      mi /= iv.size();
      for (size_t i = 0; i < tv.size(); ++i) st += (tv[i] - mt) * (tv[i] - mt), si += (iv[i] - mi) * (iv[i] - mi);
      a = st > 0 ? std::sqrt(si / st) : 1;
      b = mi - a * mt;
      first = false;
    }
    std::vector<double> r;
    std::vector<Eigen::Matrix<double, 8, 1>> rows;
    for (int it = 0; it < kIterations; ++it) {
      r.clear();
      rows.clear();
      for (const Sample& q : samples) {
        double v, dx, dy;
        if (!sceneAt(q, s, cam, cMo, &v, &dx, &dy)) continue;
        Eigen::Matrix<double, 2, 6> Jp;
        reprojectionResidual(cMo, q.X, Eigen::Vector2d::Zero(), K, nullptr, &Jp);
        Eigen::Matrix<double, 8, 1> row;
        row.head<6>() = (Eigen::RowVector2d(dx, dy) * Jp).transpose();
        row(6) = -q.T;
        row(7) = -1;
        rows.push_back(row);
        r.push_back(v - (a * q.T + b));
      }
      if (rows.size() < 50) return res;
      std::vector<double> mag(r.size());
      for (size_t i = 0; i < r.size(); ++i) mag[i] = std::abs(r[i]);
      std::nth_element(mag.begin(), mag.begin() + static_cast<long>(mag.size() / 2), mag.end());
      const double k = std::max(1.0, kHuberSigmas * 1.4826 * mag[mag.size() / 2]);
      Eigen::Matrix<double, 8, 8> A = Eigen::Matrix<double, 8, 8>::Zero();
      Eigen::Matrix<double, 8, 1> g = Eigen::Matrix<double, 8, 1>::Zero();
      for (size_t i = 0; i < rows.size(); ++i) {
        const double w = std::abs(r[i]) <= k ? 1.0 : k / std::abs(r[i]);
        A.noalias() += w * rows[i] * rows[i].transpose();
        g.noalias() += w * r[i] * rows[i];
      }
      A.diagonal() *= 1.0 + 1e-6;
      const Eigen::Matrix<double, 8, 1> d = A.ldlt().solve(-g);
      if (!d.allFinite()) return res;
      cMo = Pose(Pose::fromRotationVector(d.head<3>(), Eigen::Vector3d::Zero()).R * cMo.R, cMo.t + d.segment<3>(3));
      a += d(6);
      b += d(7);
      if (d.head<3>().norm() < 1e-6 && d.segment<3>(3).norm() < 1e-6) break;
    }
    if (!cMo.isFinite()) return res;
    res.correlation_after = correlationAt(samples, s, cam, cMo, &res.samples);
    if (sigma == kSmoothingPx[std::size(kSmoothingPx) - 1])
      res.correlation_before = correlationAt(samples, s, cam, start, nullptr);
  }
  res.ok = true;
  res.cMo = cMo;
  return res;
}

}  // namespace refgrasp::detector
