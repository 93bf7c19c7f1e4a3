#include "detector/features.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <numeric>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "detector/sift_fast.h"

namespace refgrasp::detector {

SiftImplementation defaultSiftImplementation() {
  static const SiftImplementation def = [] {
    const char* env = std::getenv("REFGRASP_SIFT");
    return env && std::string(env) == "opencv" ? SiftImplementation::kOpenCV : SiftImplementation::kFast;
  }();
  return def;
}

void SiftOptions::check() const {
  refgrasp::check(implementation == SiftImplementation::kOpenCV ||
                      implementation == SiftImplementation::kFast,
                  "SiftOptions.implementation", "unknown value");
  refgrasp::check(threads >= 0, "SiftOptions.threads", "must be >= 0");
  refgrasp::check(max_features >= 0, "SiftOptions.max_features", "must be >= 0");
  refgrasp::check(octave_layers >= 1 && octave_layers <= 10, "SiftOptions.octave_layers",
                  "must be in [1, 10]");
  refgrasp::check(std::isfinite(contrast_threshold) && contrast_threshold > 0,
                  "SiftOptions.contrast_threshold", "must be > 0");
  refgrasp::check(std::isfinite(edge_threshold) && edge_threshold > 1,
                  "SiftOptions.edge_threshold", "must be > 1");
  refgrasp::check(std::isfinite(sigma) && sigma > 0.1 && sigma < 10, "SiftOptions.sigma",
                  "must be in (0.1, 10)");
}

namespace {
/// Sizes are input px; keypoints outside [min_size_px, max_size_px] or away from `roi` (image
/// px, empty = all) need not be searched for (the caller filters).
Features extractWhole(const cv::Mat& image, const SiftOptions& opt, double min_size_px = 0,
                      double max_size_px = 1e30, const cv::Rect& roi = {});
}

Features extractSift(const cv::Mat& image, const SiftOptions& opt, const ExtractRegion& region) {
  opt.check();
  return extractSiftUnchecked(image, opt, region);
}

Features extractSiftUnchecked(const cv::Mat& image, const SiftOptions& opt, const ExtractRegion& region) {
  refgrasp::check(!image.empty(), "extractSift", "empty image");
  refgrasp::check(std::isfinite(region.min_size_px) && !std::isnan(region.max_size_px) &&
                      region.min_size_px <= region.max_size_px,
                  "ExtractRegion.min_size_px", "must be finite and <= max_size_px");
  refgrasp::check(std::isfinite(region.downsample) && region.downsample >= 1, "ExtractRegion.downsample",
                  "must be finite and >= 1");
  if (region.whole()) return extractWhole(image, opt);
  const cv::Rect full(0, 0, image.cols, image.rows);
  const cv::Rect roi = region.roi.area() > 0 ? (region.roi & full) : full;
  Features f;
  f.image_size = image.size();
  if (roi.area() == 0) {
    f.descriptors.create(0, 128, CV_32F);
    return f;
  }
  // cv::SIFT has no ROI: extract on a crop with a margin that keeps the scale space of the
  // keypoints wanted (their descriptor window spans about 1.5 sizes), then shift back. Part of
  // that context is inside roi already when the keypoints that matter lie inner_margin_px in.
  const double keep = std::min(region.max_size_px, 0.5 * std::max(image.cols, image.rows));
  const double inner = std::isfinite(region.inner_margin_px) ? std::max(0.0, region.inner_margin_px) : 0.0;
  const int margin = 8 + static_cast<int>(std::ceil(std::max(0.0, 1.5 * keep - inner)));
  // The crop origin is a multiple of 32 px so that every octave samples the same grid as the
  // whole image does (octave o takes every 2^o-th pixel of the doubled image).
  const int x0 = std::max(0, (roi.x - margin) / 32 * 32), y0 = std::max(0, (roi.y - margin) / 32 * 32);
  const cv::Rect crop = cv::Rect(x0, y0, roi.x + roi.width + margin - x0,
                                 roi.y + roi.height + margin - y0) & full;
  cv::Mat work = image(crop);
  cv::Rect work_roi = roi - crop.tl();
  double sx = 1, sy = 1;  // input px per work px
  if (region.downsample > 1) {
    const cv::Size size(std::max(1, cvRound(crop.width / region.downsample)),
                        std::max(1, cvRound(crop.height / region.downsample)));
    cv::resize(image(crop), work, size, 0, 0, cv::INTER_AREA);
    sx = static_cast<double>(crop.width) / size.width;
    sy = static_cast<double>(crop.height) / size.height;
    const int x0 = cvFloor(work_roi.x / sx), y0 = cvFloor(work_roi.y / sy);
    work_roi = cv::Rect(x0, y0, cvCeil((work_roi.x + work_roi.width) / sx) - x0,
                        cvCeil((work_roi.y + work_roi.height) / sy) - y0);
  }
  const double to_work = 1 / std::sqrt(sx * sy);  // keypoint sizes
  Features c = extractWhole(work, opt, region.min_size_px * to_work, region.max_size_px * to_work, work_roi);
  f.descriptors.create(0, 128, CV_32F);
  for (int i = 0; i < c.size(); ++i) {
    cv::KeyPoint kp = c.keypoints[i];
    // Work pixel w covers input pixels [w sx, (w + 1) sx): its centre is input (w + 0.5) sx - 0.5.
    kp.pt.x = static_cast<float>((kp.pt.x + 0.5) * sx - 0.5 + crop.x);
    kp.pt.y = static_cast<float>((kp.pt.y + 0.5) * sy - 0.5 + crop.y);
    kp.size = static_cast<float>(kp.size / to_work);
    const bool inside = kp.pt.x >= roi.x - 0.5f && kp.pt.x < roi.x + roi.width - 0.5f &&
                        kp.pt.y >= roi.y - 0.5f && kp.pt.y < roi.y + roi.height - 0.5f;
    if (!inside || kp.size < region.min_size_px || kp.size > region.max_size_px) continue;
    f.keypoints.push_back(kp);
    f.descriptors.push_back(c.descriptors.row(i));
  }
  return f;
}

namespace {
Features extractWhole(const cv::Mat& image, const SiftOptions& opt, double min_size_px,
                      double max_size_px, const cv::Rect& roi) {
  cv::Mat gray;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  } else {
    gray = image;
  }
  if (gray.depth() != CV_8U) {
    cv::Mat g8;
    gray.convertTo(g8, CV_8U);
    gray = g8;
  }

  // OpenCV 4.6 always doubles the image first (firstOctave = -1). Without up-sampling we feed it
  // the half-size image, so its first octave sees the input's resolution.
  cv::Mat work = gray;
  if (!opt.upsample) cv::resize(gray, work, cv::Size(gray.cols / 2, gray.rows / 2), 0, 0, cv::INTER_AREA);

  Features f;
  f.image_size = gray.size();
  if (work.cols < 8 || work.rows < 8) {
    f.descriptors.create(0, 128, CV_32F);
    return f;
  }
  std::vector<cv::KeyPoint> kps;
  cv::Mat desc;
  if (opt.implementation == SiftImplementation::kFast) {
    FastSiftCall call;
    call.isa = bestSiftIsa();
    call.threads = opt.threads;
    const double to_work = opt.upsample ? 1.0 : 0.5;  // work-image px per input px
    call.min_size = min_size_px * to_work;
    call.max_size = max_size_px * to_work;
    if (roi.area() > 0)
      call.roi = cv::Rect(cvFloor(roi.x * to_work), cvFloor(roi.y * to_work), cvCeil(roi.width * to_work) + 1,
                          cvCeil(roi.height * to_work) + 1);
    fastSiftDetectAndCompute(work, opt, call, &kps, &desc);
  } else {
    auto sift = cv::SIFT::create(opt.max_features, opt.octave_layers, opt.contrast_threshold,
                                 opt.edge_threshold, opt.sigma);
    sift->detectAndCompute(work, cv::noArray(), kps, desc);
  }

  // Strongest first; ties broken by position so the order never depends on threading.
  std::vector<int> order(kps.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    const cv::KeyPoint &ka = kps[a], &kb = kps[b];
    if (ka.response != kb.response) return ka.response > kb.response;
    if (ka.pt.y != kb.pt.y) return ka.pt.y < kb.pt.y;
    if (ka.pt.x != kb.pt.x) return ka.pt.x < kb.pt.x;
    if (ka.size != kb.size) return ka.size < kb.size;
    return ka.angle < kb.angle;
  });
  if (opt.max_features > 0 && static_cast<int>(order.size()) > opt.max_features)
    order.resize(opt.max_features);

  f.keypoints.reserve(order.size());
  // The fast SIFT returns them in this order already: its descriptors are used as they are.
  bool in_order = !order.empty() && order.size() == static_cast<size_t>(desc.rows) && desc.type() == CV_32F;
  for (size_t i = 0; i < order.size() && in_order; ++i) in_order = order[i] == static_cast<int>(i);
  if (in_order) {
    f.descriptors = desc;
  } else {
    f.descriptors.create(static_cast<int>(order.size()), 128, CV_32F);
  }
  for (size_t i = 0; i < order.size(); ++i) {
    cv::KeyPoint kp = kps[order[i]];
    // The internal 2x up-sampling (pixel-centre aligned) puts input pixel x at 2x + 0.5 in the
    // doubled image; OpenCV halves that, leaving a +0.25 px bias, removed here.
    kp.pt.x -= 0.25f;
    kp.pt.y -= 0.25f;
    if (!opt.upsample) {  // half-size pixel h -> input pixel 2h + 0.5 (pixel-centre aligned)
      kp.pt.x = 2.f * kp.pt.x + 0.5f;
      kp.pt.y = 2.f * kp.pt.y + 0.5f;
      kp.size *= 2.f;
    }
    f.keypoints.push_back(kp);
    if (!in_order) desc.row(order[i]).copyTo(f.descriptors.row(static_cast<int>(i)));
  }
  return f;
}
}  // namespace

GridIndex::GridIndex(const std::vector<cv::KeyPoint>& kps, cv::Size image_size, int cell_px)
    : cell_px_(std::max(1, cell_px)) {
  cols_ = std::max(1, (image_size.width + cell_px_ - 1) / cell_px_);
  rows_ = std::max(1, (image_size.height + cell_px_ - 1) / cell_px_);
  const int n = static_cast<int>(kps.size());
  x_.resize(n);
  y_.resize(n);
  std::vector<int> cell(n);
  cell_start_.assign(cols_ * rows_ + 1, 0);
  for (int i = 0; i < n; ++i) {
    x_[i] = kps[i].pt.x;
    y_[i] = kps[i].pt.y;
    const int cx = std::clamp(static_cast<int>(std::floor(x_[i] / cell_px_)), 0, cols_ - 1);
    const int cy = std::clamp(static_cast<int>(std::floor(y_[i] / cell_px_)), 0, rows_ - 1);
    cell[i] = cy * cols_ + cx;
    ++cell_start_[cell[i] + 1];
  }
  for (int c = 0; c < cols_ * rows_; ++c) cell_start_[c + 1] += cell_start_[c];
  order_.resize(n);
  std::vector<int> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (int i = 0; i < n; ++i) order_[fill[cell[i]]++] = i;
}

void GridIndex::radiusSearch(const Eigen::Vector2d& centre, double radius_px,
                             std::vector<int>* out) const {
  out->clear();
  if (order_.empty() || !(radius_px >= 0) || !centre.allFinite()) return;
  // Border cells also hold clamped out-of-image points, so clamp the cell range, not the query.
  auto cellOf = [&](double v, int n) {
    return std::clamp(static_cast<int>(std::floor(v / cell_px_)), 0, n - 1);
  };
  const int x0 = cellOf(centre.x() - radius_px, cols_), x1 = cellOf(centre.x() + radius_px, cols_);
  const int y0 = cellOf(centre.y() - radius_px, rows_), y1 = cellOf(centre.y() + radius_px, rows_);
  const double r2 = radius_px * radius_px;
  for (int cy = y0; cy <= y1; ++cy) {
    for (int cx = x0; cx <= x1; ++cx) {
      const int c = cy * cols_ + cx;
      for (int k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
        const int i = order_[k];
        const double dx = x_[i] - centre.x(), dy = y_[i] - centre.y();
        if (dx * dx + dy * dy <= r2) out->push_back(i);
      }
    }
  }
}

}  // namespace refgrasp::detector
