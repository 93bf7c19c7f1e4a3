#include "detector/dense.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "core/error.h"
#include "core/geometry.h"

namespace refgrasp::detector {

void DenseRefineOptions::check() const {
  const std::string w = "DenseRefineOptions";
  refgrasp::check(max_iterations >= 1, w + ".max_iterations", "must be >= 1");
  refgrasp::check(std::isfinite(epsilon) && epsilon > 0, w + ".epsilon", "must be finite and > 0");
  refgrasp::check(max_template_px >= 64, w + ".max_template_px", "must be >= 64");
  refgrasp::check(std::isfinite(max_corner_shift_px) && max_corner_shift_px > 0,
                  w + ".max_corner_shift_px", "must be finite and > 0");
  refgrasp::check(std::isfinite(min_correlation) && min_correlation >= -1 && min_correlation < 1,
                  w + ".min_correlation", "must be in [-1, 1)");
  refgrasp::check(gauss_filter_size >= 1 && gauss_filter_size % 2 == 1, w + ".gauss_filter_size",
                  "must be odd and >= 1");
  refgrasp::check(std::isfinite(normalize_sigma_px) && normalize_sigma_px >= 0 && normalize_sigma_px <= 64,
                  w + ".normalize_sigma_px", "must be in [0, 64] (0: off)");
  refgrasp::check(std::isfinite(raw_trusted_correlation) && raw_trusted_correlation >= -1 &&
                      raw_trusted_correlation <= 1,
                  w + ".raw_trusted_correlation", "must be in [-1, 1]");
  refgrasp::check(std::isfinite(normalized_min_correlation) && normalized_min_correlation >= -1 &&
                      normalized_min_correlation < 1,
                  w + ".normalized_min_correlation", "must be in [-1, 1)");
  refgrasp::check(std::isfinite(max_2d_coarsening) && max_2d_coarsening >= 1, w + ".max_2d_coarsening",
                  "must be finite and >= 1");
  refgrasp::check(pose_grid >= 2, w + ".pose_grid", "must be >= 2");
  refgrasp::check(robust_block_px >= 2, w + ".robust_block_px", "must be >= 2");
  refgrasp::check(std::isfinite(robust_min_residual) && robust_min_residual > 0, w + ".robust_min_residual",
                  "must be finite and > 0");
  refgrasp::check(std::isfinite(robust_min_kept) && robust_min_kept > 0 && robust_min_kept <= 1,
                  w + ".robust_min_kept", "must be in (0, 1]");
}

std::vector<cv::Mat> buildReferencePyramid(const cv::Mat& gray, int min_side_px) {
  std::vector<cv::Mat> pyr;
  if (gray.empty()) return pyr;
  pyr.push_back(gray);
  while (true) {
    const cv::Mat& last = pyr.back();
    if ((last.cols + 1) / 2 < min_side_px || (last.rows + 1) / 2 < min_side_px) break;
    cv::Mat next;
    cv::pyrDown(last, next);
    pyr.push_back(next);
  }
  return pyr;
}

namespace {

/// Template pixels to keep (255) after a converged ECC warp: blocks whose residual between the
/// normalised template and the normalised warped scene is small; blocks off the scene crop,
/// blocks an occluder covers (large residual) and their neighbours are 0. `seen`: the fraction
/// of the template's blocks in the scene and not occluded (before leaving the neighbours out).
/// `region` (template px, optional): only its pixels are the pattern; blocks not wholly inside
/// it are neither kept nor counted.
cv::Mat occlusionMask(const cv::Mat& templ, const cv::Mat& scene, const cv::Mat& warp,
                      const DenseRefineOptions& opt, const cv::Mat& region, double* seen) {
  *seen = 0;
  cv::Mat warped, inside;
  cv::warpPerspective(scene, warped, warp, templ.size(), cv::INTER_LINEAR + cv::WARP_INVERSE_MAP);
  cv::warpPerspective(cv::Mat(scene.size(), CV_8UC1, cv::Scalar(255)), inside, warp, templ.size(),
                      cv::INTER_NEAREST + cv::WARP_INVERSE_MAP);
  if (!region.empty()) cv::bitwise_and(inside, region, inside);
  cv::Mat t, w;
  templ.convertTo(t, CV_32F);
  warped.convertTo(w, CV_32F);
  cv::Scalar tm, ts, wm, ws;
  cv::meanStdDev(t, tm, ts, inside);
  cv::meanStdDev(w, wm, ws, inside);
  if (!(ts[0] > 1e-6 && ws[0] > 1e-6)) {
    *seen = cv::countNonZero(inside) / static_cast<double>(inside.total());
    return inside;
  }
  cv::Mat r = cv::abs((t - tm[0]) / ts[0] - (w - wm[0]) / ws[0]);
  const int b = opt.robust_block_px;
  const int bx = (templ.cols + b - 1) / b, by = (templ.rows + b - 1) / b;
  std::vector<double> block(static_cast<size_t>(bx * by), -1);
  std::vector<double> valid;
  for (int j = 0; j < by; ++j)
    for (int i = 0; i < bx; ++i) {
      const cv::Rect rc = cv::Rect(i * b, j * b, b, b) & cv::Rect(0, 0, templ.cols, templ.rows);
      if (cv::countNonZero(inside(rc)) < rc.area()) continue;  // partly off the scene
      block[static_cast<size_t>(j * bx + i)] = cv::mean(r(rc))[0];
      valid.push_back(block[static_cast<size_t>(j * bx + i)]);
    }
  if (valid.empty()) return cv::Mat::zeros(templ.size(), CV_8UC1);
  std::nth_element(valid.begin(), valid.begin() + static_cast<long>(valid.size() / 2), valid.end());
  const double limit = std::max(opt.robust_min_residual, 3 * valid[valid.size() / 2]);
  size_t pattern_blocks = block.size();
  if (!region.empty()) {
    pattern_blocks = 0;
    for (int j = 0; j < by; ++j)
      for (int i = 0; i < bx; ++i) {
        const cv::Rect rc = cv::Rect(i * b, j * b, b, b) & cv::Rect(0, 0, templ.cols, templ.rows);
        pattern_blocks += cv::countNonZero(region(rc)) == rc.area();
      }
    if (pattern_blocks == 0) return cv::Mat::zeros(templ.size(), CV_8UC1);
  }
  *seen = std::count_if(valid.begin(), valid.end(), [&](double v) { return v <= limit; }) /
          static_cast<double>(pattern_blocks);
  cv::Mat mask = cv::Mat::zeros(templ.size(), CV_8UC1);
  // A block next to an occluded one is left out too: partly covered, its mean residual can pass.
  const auto occluded = [&](int i, int j) {
    return i >= 0 && j >= 0 && i < bx && j < by && block[static_cast<size_t>(j * bx + i)] > limit;
  };
  for (int j = 0; j < by; ++j)
    for (int i = 0; i < bx; ++i) {
      const double v = block[static_cast<size_t>(j * bx + i)];
      if (v < 0 || v > limit) continue;
      bool near = false;
      for (int dj = -1; dj <= 1; ++dj)
        for (int di = -1; di <= 1; ++di) near = near || occluded(i + di, j + dj);
      if (near) continue;
      mask(cv::Rect(i * b, j * b, b, b) & cv::Rect(0, 0, templ.cols, templ.rows)).setTo(255);
    }
  return mask;
}

// DenseRefineOptions::normalize_sigma_px: (I - local mean) / sqrt(local variance + 5^2), CV_32F.
cv::Mat normaliseLocally(const cv::Mat& in, double sigma) {
  cv::Mat f, mean, var;
  in.convertTo(f, CV_32F);
  cv::GaussianBlur(f, mean, cv::Size(), sigma, sigma, cv::BORDER_REFLECT);
  f -= mean;
  cv::GaussianBlur(f.mul(f), var, cv::Size(), sigma, sigma, cv::BORDER_REFLECT);
  cv::sqrt(var + 25.0f, var);
  return f / var;
}

// One ECC refinement; normalise: on locally normalised intensities.
DenseRefineResult refineOnce(const std::vector<cv::Mat>& ref_pyramid, const cv::Mat& scene,
                             const Eigen::Matrix3d& H, const std::array<Eigen::Vector2d, 4>& pattern_rect,
                             const DenseRefineOptions& opt, const std::vector<Eigen::Vector2d>* mask_polygon,
                             bool normalise) {
  DenseRefineResult res;
  res.H = H;
  if (ref_pyramid.empty() || scene.empty() || scene.type() != CV_8UC1 || !H.allFinite()) return res;
  std::array<Eigen::Vector2d, 4> proj;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d q = H * pattern_rect[i].homogeneous();
    if (!(q.z() > 0)) return res;
    proj[i] = q.head<2>() / q.z();
    if (!proj[i].allFinite()) return res;
  }
  const double a_ref = std::abs(signedArea(pattern_rect)), a_scene = std::abs(signedArea(proj));
  if (!(a_ref > 0) || !(a_scene > 16)) return res;

  // Pattern bounding box in reference px.
  double minx = 1e300, miny = 1e300, maxx = -1e300, maxy = -1e300;
  for (const auto& c : pattern_rect) {
    minx = std::min(minx, c.x()), maxx = std::max(maxx, c.x());
    miny = std::min(miny, c.y()), maxy = std::max(maxy, c.y());
  }
  // Level: the coarsest one at least as fine as the pattern in the scene (area ratio: up to twice
  // finer, linearly), coarser until the template fits.
  const int levels = static_cast<int>(ref_pyramid.size());
  int L = std::max(0, static_cast<int>(std::floor(0.5 * std::log2(a_ref / a_scene))));
  L = std::min(L, levels - 1);
  cv::Rect trect;
  for (;; ++L) {
    if (L >= levels) return res;
    const double s = std::ldexp(1.0, L);
    const cv::Mat& img = ref_pyramid[L];
    // Inset: pyrDown reflects at the image border and the scene mixes the background in at the
    // pattern's edge; both bias the fit, so the outermost template pixels are left out.
    const int inset = 2 + opt.gauss_filter_size / 2;
    const int x0 = std::max(0, static_cast<int>(std::ceil(minx / s))) + inset;
    const int y0 = std::max(0, static_cast<int>(std::ceil(miny / s))) + inset;
    const int x1 = std::min(img.cols - 1, static_cast<int>(std::floor(maxx / s))) - inset;
    const int y1 = std::min(img.rows - 1, static_cast<int>(std::floor(maxy / s))) - inset;
    trect = cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1);
    if (trect.width < 8 || trect.height < 8) return res;
    if (trect.area() <= opt.max_template_px) break;
  }
  res.level = L;
  const double s = std::ldexp(1.0, L);
  Eigen::Matrix3d A;  // template px -> reference px
  A << s, 0, s * trect.x, 0, s, s * trect.y, 0, 0, 1;

  // Scene crop around the projected pattern.
  const double margin = opt.max_corner_shift_px + 4;
  double sx0 = 1e300, sy0 = 1e300, sx1 = -1e300, sy1 = -1e300;
  for (const auto& p : proj) {
    sx0 = std::min(sx0, p.x()), sx1 = std::max(sx1, p.x());
    sy0 = std::min(sy0, p.y()), sy1 = std::max(sy1, p.y());
  }
  const int cx0 = std::max(0, static_cast<int>(std::floor(sx0 - margin)));
  const int cy0 = std::max(0, static_cast<int>(std::floor(sy0 - margin)));
  const int cx1 = std::min(scene.cols - 1, static_cast<int>(std::ceil(sx1 + margin)));
  const int cy1 = std::min(scene.rows - 1, static_cast<int>(std::ceil(sy1 + margin)));
  if (cx1 - cx0 < 8 || cy1 - cy0 < 8) return res;
  const cv::Rect crect(cx0, cy0, cx1 - cx0 + 1, cy1 - cy0 + 1);
  Eigen::Matrix3d B = Eigen::Matrix3d::Identity();  // scene px -> crop px
  B(0, 2) = -cx0;
  B(1, 2) = -cy0;

  Eigen::Matrix3d W = B * H * A;
  W /= W(2, 2);
  cv::Mat warp(3, 3, CV_32F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) warp.at<float>(r, c) = static_cast<float>(W(r, c));
  cv::Mat mask;
  if (mask_polygon) {
    // The polygon at level L in template px, shrunk by the inset like the rectangle's edges.
    mask = cv::Mat::zeros(trect.size(), CV_8UC1);
    std::vector<cv::Point> poly;
    for (const auto& p : *mask_polygon)
      poly.emplace_back(static_cast<int>(std::lround(p.x() / s - trect.x)), static_cast<int>(std::lround(p.y() / s - trect.y)));
    cv::fillPoly(mask, std::vector<std::vector<cv::Point>>{poly}, cv::Scalar(255));
    const int inset = 2 + opt.gauss_filter_size / 2;
    cv::erode(mask, mask, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * inset + 1, 2 * inset + 1)));
    if (cv::countNonZero(mask) < 64) return res;
  }
  // findTransformECC's mask marks valid pixels of the input (scene) image and must have its size:
  // the polygon is moved there by the initial warp (a template-sized mask threw, so every polygon
  // region's refinement failed).
  cv::Mat scene_poly_mask;
  if (mask_polygon) cv::warpPerspective(mask, scene_poly_mask, warp, crect.size(), cv::INTER_NEAREST);
  const cv::TermCriteria stop(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, opt.max_iterations,
                              opt.epsilon);
  cv::Mat templ = ref_pyramid[L](trect), scene_crop = scene(crect);
  if (normalise) {
    templ = normaliseLocally(templ, opt.normalize_sigma_px);
    scene_crop = normaliseLocally(scene_crop, opt.normalize_sigma_px);
  }
  try {
    res.correlation = cv::findTransformECC(
        templ, scene_crop, warp, cv::MOTION_HOMOGRAPHY, stop,
        mask_polygon ? cv::_InputArray(scene_poly_mask) : cv::_InputArray(cv::noArray()), opt.gauss_filter_size);
    // Robust: leave the occluded blocks out and align again, twice (the first warp was pulled
    // towards the occluder, so its residuals mark the occlusion only roughly).
    for (int round = 0; opt.robust && round < 2; ++round) {
      double seen = 0;
      cv::Mat kept = occlusionMask(templ, scene_crop, warp, opt, mask, &seen);
      res.masked_fraction = 1 - seen;
      if (seen < opt.robust_min_kept) return res;
      if (seen >= 0.98) break;
      if (mask_polygon) cv::bitwise_and(kept, mask, kept);
      // ECC's mask lives in the scene (input) image: the kept template moved there.
      cv::Mat scene_mask;
      cv::warpPerspective(kept, scene_mask, warp, crect.size(), cv::INTER_NEAREST);
      res.correlation = cv::findTransformECC(templ, scene_crop, warp,
                                             cv::MOTION_HOMOGRAPHY, stop, scene_mask,
                                             opt.gauss_filter_size);
    }
  } catch (const cv::Exception&) {
    return res;
  }
  Eigen::Matrix3d Wn;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) Wn(r, c) = warp.at<float>(r, c);
  const Eigen::Matrix3d Hn = B.inverse() * Wn * A.inverse();
  if (!Hn.allFinite() || !(res.correlation >= opt.min_correlation)) return res;
  double shift = 0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d q = Hn * pattern_rect[i].homogeneous();
    if (!(q.z() * (H * pattern_rect[i].homogeneous()).z() > 0)) return res;
    shift = std::max(shift, (q.head<2>() / q.z() - proj[i]).norm());
  }
  res.corner_shift_px = shift;
  if (!(shift <= opt.max_corner_shift_px)) return res;
  res.ok = true;
  res.H = Hn / Hn(2, 2);
  return res;
}

}  // namespace

DenseRefineResult refineHomographyDense(const std::vector<cv::Mat>& ref_pyramid,
                                        const cv::Mat& scene, const Eigen::Matrix3d& H,
                                        const std::array<Eigen::Vector2d, 4>& pattern_rect,
                                        const DenseRefineOptions& opt,
                                        const std::vector<Eigen::Vector2d>* mask_polygon) {
  const DenseRefineResult raw = refineOnce(ref_pyramid, scene, H, pattern_rect, opt, mask_polygon, false);
  if ((raw.ok && raw.correlation >= opt.raw_trusted_correlation) || !(opt.normalize_sigma_px > 0)) return raw;
  const DenseRefineResult normalised = refineOnce(ref_pyramid, scene, H, pattern_rect, opt, mask_polygon, true);
  return normalised.ok && normalised.correlation >= opt.normalized_min_correlation ? normalised : raw;
}

}  // namespace refgrasp::detector
