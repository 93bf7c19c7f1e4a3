#include "detector/peak_search.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "core/geometry.h"

namespace refgrasp::detector {

std::vector<Eigen::Matrix3d> photometricPeaks(const RegisteredObject& obj, const Eigen::Matrix3d& H,
                                              const std::vector<Eigen::Vector2d>& polygon, const cv::Mat& scene,
                                              const Intrinsics& camera, const VerifyOptions& opt) {
  std::vector<Eigen::Matrix3d> out;
  if (obj.pyramid.empty() || scene.empty() || polygon.size() < 3) return out;
  std::vector<Eigen::Vector2d> proj;
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  double w0 = 0;
  for (const auto& p : polygon) {
    const Eigen::Vector3d q = H * p.homogeneous();
    if (proj.empty()) w0 = q.z();
    if (!(q.z() * w0 > 0)) return out;  // the whole polygon in front of the vanishing line
    proj.push_back(q.hnormalized());
    lo = lo.cwiseMin(proj.back());
    hi = hi.cwiseMax(proj.back());
  }
  const double diag = patternDiagonal(obj, H);
  if (!(diag > 8) || !(diag < 1e5) || !lo.allFinite() || !hi.allFinite()) return out;
  const Eigen::Vector2d mid = 0.5 * (lo + hi), shift = distortPixel(camera, mid) - mid;
  lo += shift;
  hi += shift;
  // Bounded before the casts to int below (NaN fails too).
  if (!(lo.cwiseAbs().maxCoeff() < 1e5) || !(hi.cwiseAbs().maxCoeff() < 1e5)) return out;
  for (auto& p : proj) p += shift;
  const double k = std::min(1.0, 48.0 / diag);  // grid px per scene px
  const double r = opt.peak_search_reach * diag;
  const cv::Rect img(0, 0, scene.cols, scene.rows);
  const cv::Rect crop = cv::Rect(cv::Point(static_cast<int>(std::floor(lo.x() - r)), static_cast<int>(std::floor(lo.y() - r))),
                                 cv::Point(static_cast<int>(std::ceil(hi.x() + r)) + 1, static_cast<int>(std::ceil(hi.y() + r)) + 1)) & img;
  const int tw = static_cast<int>(std::ceil((hi.x() - lo.x()) * k)) + 1, th = static_cast<int>(std::ceil((hi.y() - lo.y()) * k)) + 1;
  if (crop.area() <= 0 || tw < 6 || th < 6) return out;
  cv::Mat sc;
  if (k < 1) cv::resize(scene(crop), sc, cv::Size(), k, k, cv::INTER_AREA);
  else sc = scene(crop);
  if (sc.cols < tw || sc.rows < th) return out;
  // Reference level: about one reference px per grid px.
  const double a_ref = std::abs(signedArea(polygon)), a_scene = std::abs(signedArea(proj)) * k * k;
  if (!(a_ref > 0) || !(a_scene > 16)) return out;
  const int L = std::clamp(static_cast<int>(std::floor(0.5 * std::log2(a_ref / a_scene))), 0, static_cast<int>(obj.pyramid.size()) - 1);
  const double ls = std::ldexp(1.0, L);
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();  // level px -> ref px
  A(0, 0) = A(1, 1) = ls;
  Eigen::Matrix3d G = Eigen::Matrix3d::Identity();  // scene px -> template px
  G(0, 0) = G(1, 1) = k;
  G(0, 2) = -k * lo.x();
  G(1, 2) = -k * lo.y();
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();  // undistorted px -> raw px, near the pattern
  D(0, 2) = shift.x();
  D(1, 2) = shift.y();
  const Eigen::Matrix3d W = G * D * H * A;
  cv::Mat warp(3, 3, CV_64F);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) warp.at<double>(i, j) = W(i, j);
  cv::Mat templ, mask = cv::Mat::zeros(th, tw, CV_8UC1);
  cv::warpPerspective(obj.pyramid[L], templ, warp, cv::Size(tw, th), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  std::vector<cv::Point> poly;
  for (const auto& p : proj)
    poly.emplace_back(static_cast<int>(std::lround(k * (p.x() - lo.x()))), static_cast<int>(std::lround(k * (p.y() - lo.y()))));
  cv::fillPoly(mask, std::vector<std::vector<cv::Point>>{poly}, cv::Scalar(255));
  cv::erode(mask, mask, cv::Mat());
  if (cv::countNonZero(mask) < 24) return out;
  cv::Mat tf, sf, res;
  templ.convertTo(tf, CV_32F);
  sc.convertTo(sf, CV_32F);
  cv::GaussianBlur(tf, tf, cv::Size(3, 3), 0.7);
  cv::GaussianBlur(sf, sf, cv::Size(3, 3), 0.7);
  try {
    cv::matchTemplate(sf, tf, res, cv::TM_CCOEFF_NORMED, mask);
  } catch (const cv::Exception&) {
    return out;
  }
  cv::patchNaNs(res, -1);
  for (int v = 0; v < res.rows; ++v)
    for (int u = 0; u < res.cols; ++u)
      if (!std::isfinite(res.at<float>(v, u)) || std::abs(res.at<float>(v, u)) > 1.0001f) res.at<float>(v, u) = -1;
  const cv::Point2d p0(k * (lo.x() - crop.x), k * (lo.y() - crop.y));
  const int i0 = std::clamp(static_cast<int>(std::lround(p0.x)), 0, res.cols - 1), j0 = std::clamp(static_cast<int>(std::lround(p0.y)), 0, res.rows - 1);
  float at0 = -1;  // best within a grid pixel of H
  for (int dv = -1; dv <= 1; ++dv)
    for (int du = -1; du <= 1; ++du) {
      const int u = i0 + du, v = j0 + dv;
      if (u >= 0 && v >= 0 && u < res.cols && v < res.rows) at0 = std::max(at0, res.at<float>(v, u));
    }
  const double away = 3.0 * k;  // grid px
  const int nms = std::max(2, static_cast<int>(std::lround(away)));
  for (int n = 0; n < opt.peak_search_count; ++n) {
    double mx;
    cv::Point pm;
    cv::minMaxLoc(res, nullptr, &mx, nullptr, &pm);
    if (!(mx > at0 + opt.peak_search_margin)) break;
    const double dx = (pm.x - p0.x) / k, dy = (pm.y - p0.y) / k;
    cv::rectangle(res, cv::Rect(pm.x - nms, pm.y - nms, 2 * nms + 1, 2 * nms + 1), cv::Scalar(-1), cv::FILLED);
    if (std::hypot(pm.x - p0.x, pm.y - p0.y) <= away) continue;
    Eigen::Matrix3d T = Eigen::Matrix3d::Identity();
    T(0, 2) = dx;
    T(1, 2) = dy;
    out.push_back(T * H);
  }
  return out;
}

}  // namespace refgrasp::detector
