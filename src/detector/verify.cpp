#include "detector/verify.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/geometry.h"

namespace refgrasp::detector {

void VerifyOptions::check() const {
  refgrasp::check(std::isfinite(min_correlation) && min_correlation >= -1 && min_correlation < 1,
                  "VerifyOptions.min_correlation", "must be in [-1, 1)");
  refgrasp::check(compare_px >= 8 && compare_px <= 1024, "VerifyOptions.compare_px", "must be in [8, 1024]");
  refgrasp::check(std::isfinite(strong_correlation) && strong_correlation >= -1 && strong_correlation < 1,
                  "VerifyOptions.strong_correlation", "must be in [-1, 1)");
  refgrasp::check(std::isfinite(realign_trusted_correlation) && realign_trusted_correlation >= 0 &&
                      realign_trusted_correlation <= 1,
                  "VerifyOptions.realign_trusted_correlation", "must be in [0, 1] (1: never)");
  refgrasp::check(std::isfinite(realign_verified_correlation) && realign_verified_correlation >= -1 &&
                      realign_verified_correlation <= 1.01,
                  "VerifyOptions.realign_verified_correlation", "must be in [-1, 1.01] (1.01: never)");
  refgrasp::check(std::isfinite(realign_verified_gain) && realign_verified_gain >= 0 && realign_verified_gain <= 2,
                  "VerifyOptions.realign_verified_gain", "must be in [0, 2]");
  refgrasp::check(realign_verified_cells >= 0 && realign_verified_cells <= 9, "VerifyOptions.realign_verified_cells",
                  "must be in [0, 9]");
  refgrasp::check(std::isfinite(realign_min_in_view) && realign_min_in_view >= 0 && realign_min_in_view <= 1,
                  "VerifyOptions.realign_min_in_view", "must be in [0, 1] (0: always)");
  refgrasp::check(std::isfinite(period_ambiguity_margin) && period_ambiguity_margin >= 0 &&
                      period_ambiguity_margin <= 2,
                  "VerifyOptions.period_ambiguity_margin", "must be in [0, 2]");
  refgrasp::check(std::isfinite(period_switch_correlation) && period_switch_correlation >= -1 &&
                      period_switch_correlation <= 1.01,
                  "VerifyOptions.period_switch_correlation", "must be in [-1, 1.01] (1.01: never)");
  refgrasp::check(period_ambiguity_cells >= 1 && period_ambiguity_cells <= 10, "VerifyOptions.period_ambiguity_cells",
                  "must be in [1, 10] (10: never)");
  refgrasp::check(std::isfinite(max_feature_pose_rms_px) && max_feature_pose_rms_px > 0 && max_feature_pose_rms_px <= 1000,
                  "VerifyOptions.max_feature_pose_rms_px", "must be in (0, 1000] (1000: never)");
  refgrasp::check(min_strong_cells >= 0 && min_strong_cells <= 9, "VerifyOptions.min_strong_cells", "must be in [0, 9]");
  refgrasp::check(periodic_min_strong_cells >= 0 && periodic_min_strong_cells <= 9,
                  "VerifyOptions.periodic_min_strong_cells", "must be in [0, 9]");
}

namespace {

// The polygon mapped by H (undistorted scene px); false when a vertex is not on the side of the
// vanishing line the first one is on.
bool projectPolygon(const Eigen::Matrix3d& H, const std::vector<Eigen::Vector2d>& poly,
                    std::vector<Eigen::Vector2d>* proj) {
  proj->clear();
  double w0 = 0;
  for (const auto& p : poly) {
    const Eigen::Vector3d q = H * p.homogeneous();
    if (proj->empty()) w0 = q.z();
    if (!(q.z() * w0 > 0)) return false;
    proj->push_back(q.hnormalized());
  }
  return true;
}

// The part of the pattern in view (the scene's frame mapped back into the reference, when the
// frame lies wholly on the plane's side of the vanishing line): a pattern seen larger than the
// frame is compared where it is seen. It must cover a quarter of the pattern, or of the frame
// when the pattern is larger. a_pattern: the whole pattern's projected area. False: not
// computable.
bool partInView(const std::vector<Eigen::Vector2d>& pattern, const Eigen::Matrix3d& H, const cv::Mat& scene,
                const Intrinsics& cam, double a_pattern, std::vector<Eigen::Vector2d>* polygon) {
  *polygon = pattern;
  std::vector<Eigen::Vector2d> frame = {{-0.5, -0.5}, {scene.cols - 0.5, -0.5}, {scene.cols - 0.5, scene.rows - 0.5},
                                        {-0.5, scene.rows - 0.5}};
  if (cam.hasDistortion())
    for (auto& f : frame) f = cam.undistortPixel(f);
  const Eigen::Matrix3d Hi = H.inverse();
  std::vector<Eigen::Vector2d> frame_ref;
  bool in_front = Hi.allFinite();
  const double w_pattern = (H * pattern[0].homogeneous()).z();
  for (const auto& f : frame) {
    const Eigen::Vector3d r = Hi * f.homogeneous();
    // The frame's corner must see the pattern's plane (H r = f exactly, so H maps r / r_z with w = 1 / r_z).
    in_front = in_front && r.z() * w_pattern > 0 && std::abs(r.z()) > 1e-12;
    frame_ref.push_back(r.hnormalized());
  }
  if (!in_front) return true;
  *polygon = clipToConvex(pattern, frame_ref);
  std::vector<Eigen::Vector2d> seen;
  if (polygon->size() < 3 || !projectPolygon(H, *polygon, &seen)) return false;
  const double a_seen = std::abs(signedArea(seen));
  return a_seen >= 0.25 * std::min(a_pattern, static_cast<double>(scene.total()));
}

// Both sides on the comparison grid: the reference (a) and the scene (b), smoothed (CV_32F), and
// the grid pixels compared (mask: inside the polygon, one grid pixel in from its outline, and
// landing in the scene image).
struct Grids {
  cv::Mat a, b, mask;
  int width = 0, height = 0;
  int in_polygon = 0;  ///< grid pixels inside the polygon (before the erosion and the image test)
};

// False when the scene's neighbourhood of the pattern is empty.
bool sampleGrids(const std::vector<cv::Mat>& pyr, const std::vector<Eigen::Vector2d>& polygon, const cv::Mat& scene,
                 const Intrinsics& cam, const Eigen::Matrix3d& H, double a_ref, double a_scene,
                 const VerifyOptions& opt, Grids* g) {
  Eigen::Vector2d lo = polygon[0], hi = polygon[0];
  for (const auto& p : polygon) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  // Comparison grid: no finer than the scene's pixels, at most compare_px on the longer side.
  const double side = std::max(hi.x() - lo.x(), hi.y() - lo.y());
  const double s = std::min(opt.compare_px / side, std::sqrt(a_scene / a_ref));  // grid px per ref px
  const int tw = std::max(4, static_cast<int>(std::ceil((hi.x() - lo.x()) * s)));
  const int th = std::max(4, static_cast<int>(std::ceil((hi.y() - lo.y()) * s)));
  // Reference side: the pyramid level just finer than the grid, area-resampled onto it.
  int L = std::clamp(static_cast<int>(std::floor(std::log2(1 / s))), 0, static_cast<int>(pyr.size()) - 1);
  const double ls = std::ldexp(1.0, L);
  cv::Mat mapx(th, tw, CV_32F), mapy(th, tw, CV_32F), smx(th, tw, CV_32F), smy(th, tw, CV_32F);
  for (int v = 0; v < th; ++v)
    for (int u = 0; u < tw; ++u) {
      const Eigen::Vector2d r(lo.x() + (u + 0.5) / s - 0.5, lo.y() + (v + 0.5) / s - 0.5);  // ref px
      mapx.at<float>(v, u) = static_cast<float>((r.x() + 0.5) / ls - 0.5);
      mapy.at<float>(v, u) = static_cast<float>((r.y() + 0.5) / ls - 0.5);
      Eigen::Vector2d q = (H * r.homogeneous()).hnormalized();
      if (cam.hasDistortion()) q = cam.distortNormalized(Eigen::Vector2d((q.x() - cam.cx) / cam.fx, (q.y() - cam.cy) / cam.fy));
      smx.at<float>(v, u) = static_cast<float>(q.x());
      smy.at<float>(v, u) = static_cast<float>(q.y());
    }
  // Low-pass both sides to the grid's resolution before sampling (no aliasing), then a little
  // more on the grid so that a pixel of misalignment does not decorrelate fine texture.
  const double ref_step = 1 / (s * ls), scene_step = std::sqrt(a_scene / a_ref) / s;
  cv::Mat ref, sc;
  const cv::Mat& R = pyr[L];
  auto lowpass = [](const cv::Mat& img, double step, cv::Mat* out) {
    if (step > 1.2) cv::GaussianBlur(img, *out, cv::Size(0, 0), 0.45 * step);
    else *out = img;
  };
  // Only the scene's neighbourhood of the pattern is filtered.
  Eigen::Vector2d slo(1e30, 1e30), shi(-1e30, -1e30);
  for (int v = 0; v < th; ++v)
    for (int u = 0; u < tw; ++u) {
      const Eigen::Vector2d q(smx.at<float>(v, u), smy.at<float>(v, u));
      slo = slo.cwiseMin(q);
      shi = shi.cwiseMax(q);
    }
  const int pad = static_cast<int>(std::ceil(2 * scene_step)) + 3;
  const cv::Rect crop = cv::Rect(cv::Point(static_cast<int>(std::floor(slo.x())) - pad, static_cast<int>(std::floor(slo.y())) - pad),
                                 cv::Point(static_cast<int>(std::ceil(shi.x())) + pad + 1, static_cast<int>(std::ceil(shi.y())) + pad + 1)) &
                        cv::Rect(0, 0, scene.cols, scene.rows);
  if (crop.area() <= 0) return false;
  lowpass(scene(crop), scene_step, &sc);
  smx -= static_cast<float>(crop.x);
  smy -= static_cast<float>(crop.y);
  lowpass(R, ref_step, &ref);
  cv::Mat a, b, inside;
  cv::remap(ref, a, mapx, mapy, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  cv::remap(sc, b, smx, smy, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::remap(cv::Mat(sc.size(), CV_8UC1, cv::Scalar(255)), inside, smx, smy, cv::INTER_NEAREST, cv::BORDER_CONSTANT,
            cv::Scalar(0));
  // The polygon on the grid, one grid pixel inside its outline.
  g->mask = cv::Mat::zeros(th, tw, CV_8UC1);
  std::vector<cv::Point> poly;
  for (const auto& p : polygon)
    poly.emplace_back(cv::Point(static_cast<int>(std::lround((p.x() - lo.x()) * s)), static_cast<int>(std::lround((p.y() - lo.y()) * s))));
  cv::fillPoly(g->mask, std::vector<std::vector<cv::Point>>{poly}, cv::Scalar(255));
  g->in_polygon = cv::countNonZero(g->mask);
  cv::erode(g->mask, g->mask, cv::Mat());
  g->mask &= inside;
  a.convertTo(g->a, CV_32F);
  b.convertTo(g->b, CV_32F);
  cv::GaussianBlur(g->a, g->a, cv::Size(3, 3), 0.7);
  cv::GaussianBlur(g->b, g->b, cv::Size(3, 3), 0.7);
  g->width = tw;
  g->height = th;
  return true;
}

// Zero-mean NCC over a box of the grid; NaN when it is flat (std below 1 gray level) or small.
double maskedNcc(const Grids& g, const cv::Rect& box) {
  const double ma = cv::mean(g.a(box), g.mask(box))[0], mb = cv::mean(g.b(box), g.mask(box))[0];
  double sab = 0, saa = 0, sbb = 0;
  int k = 0;
  for (int v = box.y; v < box.y + box.height; ++v)
    for (int u = box.x; u < box.x + box.width; ++u) {
      if (!g.mask.at<uchar>(v, u)) continue;
      const double x = g.a.at<float>(v, u) - ma, y = g.b.at<float>(v, u) - mb;
      sab += x * y;
      saa += x * x;
      sbb += y * y;
      ++k;
    }
  if (k < 12 || !(saa > 1.0 * k) || !(sbb > 1.0 * k)) return std::nan("");
  return sab / std::sqrt(saa * sbb);
}

}  // namespace

VerifyResult verifyInstance(const std::vector<cv::Mat>& pyr, const std::vector<Eigen::Vector2d>& pattern,
                            const cv::Mat& scene, const Intrinsics& cam, const Eigen::Matrix3d& H,
                            const VerifyOptions& opt) {
  VerifyResult res;
  if (pyr.empty() || scene.empty() || scene.type() != CV_8UC1 || pattern.size() < 3 || !H.allFinite()) return res;
  // Pattern in the scene (undistorted px): in front of the vanishing line, its area.
  std::vector<Eigen::Vector2d> proj;
  if (!projectPolygon(H, pattern, &proj)) return res;
  const double a_pattern = std::abs(signedArea(proj));
  if (!(a_pattern > 4) || !std::isfinite(a_pattern)) return res;
  std::vector<Eigen::Vector2d> polygon;
  if (!partInView(pattern, H, scene, cam, a_pattern, &polygon)) return res;
  std::vector<Eigen::Vector2d> seen;
  if (!projectPolygon(H, polygon, &seen)) return res;
  const double a_ref = std::abs(signedArea(polygon)), a_scene = std::abs(signedArea(seen));
  if (!(a_ref > 0) || !(a_scene > 4) || !std::isfinite(a_scene)) return res;
  Grids g;
  if (!sampleGrids(pyr, polygon, scene, cam, H, a_ref, a_scene, opt, &g)) return res;
  const int n = cv::countNonZero(g.mask);
  res.visible_fraction = g.in_polygon > 0 ? static_cast<double>(n) / g.in_polygon : 0;
  if (n < 12 || res.visible_fraction < 0.25) return res;
  res.correlation = maskedNcc(g, cv::Rect(0, 0, g.width, g.height));
  if (std::isnan(res.correlation)) {
    res.correlation = 0;
    return res;
  }
  // The pattern's box cut into 3 x 3 cells: of the cells with texture on both sides, at least
  // half must agree on their own, and min_strong_cells strongly. A shared logo or word (a
  // sibling product), or a repeated pattern aligned one period off, agrees in part of the
  // pattern, not over most of it.
  const int tw = g.width, th = g.height;
  int cells = 0, agreeing = 0, strong = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const cv::Rect cell(j * tw / 3, i * th / 3, (j + 1) * tw / 3 - j * tw / 3, (i + 1) * th / 3 - i * th / 3);
      const double c = maskedNcc(g, cell);
      if (std::isnan(c)) continue;
      ++cells;
      agreeing += c >= opt.min_correlation;
      strong += c >= opt.strong_correlation;
    }
  res.strong_cells = strong;
  res.textured_cells = cells;
  res.ok = res.correlation >= opt.min_correlation && 2 * agreeing >= cells && strong >= std::min(opt.min_strong_cells, cells);
  return res;
}

}  // namespace refgrasp::detector
