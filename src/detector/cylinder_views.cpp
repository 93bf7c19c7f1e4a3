#include "detector/cylinder_views.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "detector/plane_views.h"

namespace refgrasp::detector {

namespace {

constexpr double kPi = M_PI;
// Turns of the synthesised views about the axis (radians): every 30 deg, so that every label
// column is seen within 15 deg of a view's facing column and, with kMaxAngle, from 4 turns.
constexpr double kTurnStep = kPi / 6;
// Features are kept where the surface faces the view within this angle (60 deg: squeezed at most
// 2x across the axis; nearer the limb the view's resampling aliases).
constexpr double kMaxAngle = kPi / 3;
// The view spans this angle either side of its facing column, so that the kept features have
// their context (75 deg; the silhouette lies at 90).
constexpr double kSpanAngle = 75 * kPi / 180;
// Scales of the views (image px per label px along the axis): the label itself and two octaves
// coarser, the structure a camera 2-4x further away resolves.
constexpr double kScales[] = {1.0, 0.5, 0.25};
// Grey margin round a view (px), so that SIFT's border exclusion does not eat the label's rows.
constexpr int kMarginPx = 12;

// One view: the label wrapped on the cylinder turned by `turn`, seen orthographically at `scale`,
// and its features mapped back to label px.
void addView(const CylinderLabel& L, const cv::Mat& gray, double turn, double scale, const SiftOptions& sift,
             Features* out) {
  const double px_m = L.metresPerPixelU() / scale;  // view px along the circumference, metres
  const int half = static_cast<int>(std::ceil(L.radius_m * std::sin(kSpanAngle) / px_m));
  const int rows = std::max(1, static_cast<int>(std::lround(L.image_height * scale)));
  if (half < 2 || rows < 8) return;
  cv::Mat scaled;  // the label at the view's scale, both axes (area averaging: no aliasing)
  cv::resize(gray, scaled, cv::Size(std::max(1, static_cast<int>(std::lround(L.image_width * scale))), rows), 0, 0,
             cv::INTER_AREA);
  // The scaled label's own scales (its size is rounded to whole px).
  const double sx = static_cast<double>(scaled.cols) / L.image_width;
  const double sy = static_cast<double>(rows) / L.image_height;
  const int cols = 2 * half + 1;
  // View column x -> label column u (the view's facing column, x = half, is the label's at turn).
  auto labelColumn = [&](double x) {
    const double theta = turn + std::asin(std::clamp((x - half) * px_m / L.radius_m, -1.0, 1.0));
    const double u = theta * L.radius_m / L.metresPerPixelU() + (L.image_width - 1) / 2.0;
    return L.fullWrap() ? u - L.image_width * std::floor((u + 0.5) / L.image_width) : u;
  };
  cv::Mat map_x(rows, cols, CV_32F), map_y(rows, cols, CV_32F);
  for (int x = 0; x < cols; ++x) {
    const float mx = static_cast<float>((labelColumn(x) + 0.5) * sx - 0.5);
    for (int y = 0; y < rows; ++y) {
      map_x.at<float>(y, x) = mx;
      map_y.at<float>(y, x) = static_cast<float>(y);
    }
  }
  cv::Mat view;
  cv::remap(scaled, view, map_x, map_y, cv::INTER_LINEAR, L.fullWrap() ? cv::BORDER_WRAP : cv::BORDER_CONSTANT,
            cv::Scalar(128));
  cv::copyMakeBorder(view, view, kMarginPx, kMarginPx, kMarginPx, kMarginPx, cv::BORDER_CONSTANT, cv::Scalar(128));
  const Features f = extractSiftUnchecked(view, sift);
  const double max_x = L.radius_m * std::sin(kMaxAngle) / px_m;
  for (int i = 0; i < f.size(); ++i) {
    cv::KeyPoint k = f.keypoints[static_cast<size_t>(i)];
    const double x = k.pt.x - kMarginPx, y = k.pt.y - kMarginPx;
    if (std::abs(x - half) > max_x || y < 0 || y > rows - 1) continue;
    const double u = labelColumn(x);
    if (!L.fullWrap() && (u < 0 || u > L.image_width - 1)) continue;
    k.pt = cv::Point2f(static_cast<float>(u), static_cast<float>((y + 0.5) / sy - 0.5));
    k.size = static_cast<float>(k.size / sy);
    out->keypoints.push_back(k);
    out->descriptors.push_back(f.descriptors.row(i));
  }
}

bool repeats(const Features& kept, const cv::KeyPoint& k, const cv::Mat& d) {
  for (int j = 0; j < kept.size(); ++j)
    if (repeatsFeature(kept.keypoints[static_cast<size_t>(j)], kept.descriptors.row(j), k, d)) return true;
  return false;
}

}  // namespace

Features synthesisedLabelFeatures(const CylinderLabel& L, const cv::Mat& label, const Features& flat,
                                  const std::vector<Eigen::Vector2d>& region, const SiftOptions& sift) {
  cv::Mat gray = label;
  if (label.channels() == 3) cv::cvtColor(label, gray, cv::COLOR_BGR2GRAY);
  if (label.channels() == 4) cv::cvtColor(label, gray, cv::COLOR_BGRA2GRAY);
  Features views;
  // Turns whose facing column lies on the label (a partial label: its columns' angles).
  const double lo = L.fullWrap() ? -kPi : L.theta(0), hi = L.fullWrap() ? kPi - 1e-9 : L.theta(L.image_width - 1);
  for (const double scale : kScales)
    for (double turn = kTurnStep * std::ceil(lo / kTurnStep); turn <= hi; turn += kTurnStep)
      addView(L, gray, turn, scale, sift, &views);
  std::vector<cv::Point2f> poly;
  for (const Eigen::Vector2d& p : region) poly.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  Features kept = flat;
  const int n_flat = kept.size();
  for (int i = 0; i < views.size(); ++i) {
    const cv::KeyPoint& k = views.keypoints[static_cast<size_t>(i)];
    if (poly.size() >= 3 && cv::pointPolygonTest(poly, k.pt, false) < 0) continue;
    if (repeats(kept, k, views.descriptors.row(i))) continue;
    kept.keypoints.push_back(k);
    kept.descriptors.push_back(views.descriptors.row(i));
  }
  Features out;
  out.image_size = flat.image_size;
  out.keypoints.assign(kept.keypoints.begin() + n_flat, kept.keypoints.end());
  if (kept.size() > n_flat) out.descriptors = kept.descriptors.rowRange(n_flat, kept.size()).clone();
  return out;
}

}  // namespace refgrasp::detector
