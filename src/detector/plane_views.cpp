#include "detector/plane_views.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "core/geometry.h"

namespace refgrasp::detector {

namespace {

using Vec2 = Eigen::Vector2d;
constexpr double kPi = M_PI;
// Tilts of the synthesised views, t = 1 / cos(tilt): fronto-parallel, 45 and 60 deg (the scenes'
// range, 0-60 deg, within a factor sqrt(2) of one of them: SIFT tolerates about that much).
constexpr double kTilts[] = {1.0, 1.4142135623730951, 2.0};
// Tilt axes every kAxisStepDeg / t deg over [0, 180) (ASIFT's sampling: the same overlap of the
// views' squeezes at every tilt).
constexpr double kAxisStepDeg = 72.0;
// Sizes of the pattern in the views (square root of its area, view px): octaves down to the
// far faces' own 24-45 px, each at most the reference's own (a view never has more detail than
// the reference: the frontal map is normalised to shrink only). A nearer face is the
// reference's own features' business; a larger view would only add cost (its features grow with
// its area).
constexpr double kViewSizesPx[] = {80, 40};
// A view this close to the reference (singular values within this of 1) is the reference itself.
constexpr double kSameViewTolerance = 0.02;
// Border added round a view (replicated px), so that SIFT's border exclusion keeps the pattern's
// edge.
constexpr int kMarginPx = 12;
// Context kept round the pattern's bounding box, fraction of its diagonal: a feature at the
// pattern's edge describes a neighbourhood several times its size.
constexpr double kContextFraction = 0.1;
// repeatsFeature's bounds: place (fraction of the larger size), size ratio, descriptor (L2).
constexpr double kSamePlaceFraction = 0.5;
constexpr double kSameSizeRatio = 1.5;
constexpr double kSameDescriptor = 250;
constexpr double kGridCellPx = 16;  // the repeat test's bucket side, reference px

// One view: `gray` (the reference cropped at `offset`) mapped by the linear map
// L = diag(sx, sy) R (R a rotation, sx >= sy) about its centre: shrunk by sx (area averaging),
// rotated, then squeezed by sy / sx along y (area averaging: no aliasing). Its features mapped back
// to reference px are appended to out.
void addView(const cv::Mat& gray, const Vec2& offset, const Eigen::Matrix2d& R, double sx, double sy,
             const SiftOptions& sift, Features* out) {
  cv::Mat small = gray;
  if (sx < 1)
    cv::resize(gray, small, cv::Size(std::max(1, static_cast<int>(std::lround(gray.cols * sx))),
                                     std::max(1, static_cast<int>(std::lround(gray.rows * sx)))), 0, 0, cv::INTER_AREA);
  const Vec2 e0(static_cast<double>(small.cols) / gray.cols, static_cast<double>(small.rows) / gray.rows);
  const Vec2 c((small.cols - 1) / 2.0, (small.rows - 1) / 2.0);
  Vec2 lo(1e300, 1e300), hi(-1e300, -1e300);
  for (const Vec2& p : {Vec2(0, 0), Vec2(small.cols - 1, 0), Vec2(0, small.rows - 1), Vec2(small.cols - 1, small.rows - 1)}) {
    const Vec2 q = R * (p - c);
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  const cv::Size rot_size(static_cast<int>(std::ceil(hi.x() - lo.x())) + 1, static_cast<int>(std::ceil(hi.y() - lo.y())) + 1);
  const Vec2 c_rot = -lo;  // the centre in the rotated image
  const Vec2 t = c_rot - R * c;
  const cv::Mat A = (cv::Mat_<double>(2, 3) << R(0, 0), R(0, 1), t.x(), R(1, 0), R(1, 1), t.y());
  cv::Mat rotated, view;
  cv::warpAffine(small, rotated, A, rot_size, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  const int rows = static_cast<int>(std::lround(rot_size.height * sy / sx));
  if (rot_size.width < 16 || rows < 16) return;
  cv::resize(rotated, view, cv::Size(rot_size.width, rows), 0, 0, cv::INTER_AREA);
  cv::copyMakeBorder(view, view, kMarginPx, kMarginPx, kMarginPx, kMarginPx, cv::BORDER_REPLICATE);
  const double ey = static_cast<double>(rows) / rot_size.height;  // the squeeze, as rounded
  const Features f = extractSiftUnchecked(view, sift);
  for (int i = 0; i < f.size(); ++i) {
    cv::KeyPoint k = f.keypoints[static_cast<size_t>(i)];
    const Vec2 q(k.pt.x - kMarginPx, (k.pt.y - kMarginPx + 0.5) / ey - 0.5);
    const Vec2 ps = R.transpose() * (q - c_rot) + c;
    const Vec2 p((ps.x() + 0.5) / e0.x() - 0.5 + offset.x(), (ps.y() + 0.5) / e0.y() - 0.5 + offset.y());
    const double a = k.angle * kPi / 180;
    const Vec2 d = R.transpose() * Vec2(std::cos(a), std::sin(a) / ey);
    double angle = std::atan2(d.y() / e0.y(), d.x() / e0.x()) * 180 / kPi;
    if (angle < 0) angle += 360;
    k.pt = cv::Point2f(static_cast<float>(p.x()), static_cast<float>(p.y()));
    k.angle = static_cast<float>(angle);
    k.size = static_cast<float>(k.size / std::sqrt(e0.x() * e0.y() * ey));
    k.class_id = kSynthesisedFeature;
    out->keypoints.push_back(k);
    out->descriptors.push_back(f.descriptors.row(i));
  }
}

// The kept features bucketed by position, for the repeat test.
class KeptGrid {
 public:
  KeptGrid(cv::Size size) : cols_(std::max(1, static_cast<int>(std::ceil(size.width / kGridCellPx)) + 1)),
                            rows_(std::max(1, static_cast<int>(std::ceil(size.height / kGridCellPx)) + 1)),
                            cells_(static_cast<size_t>(cols_ * rows_)) {}
  void add(const Features& kept, int i) { cells_[cell(kept.keypoints[static_cast<size_t>(i)].pt)].push_back(i); }
  bool repeats(const Features& kept, const cv::KeyPoint& k, const cv::Mat& d) const {
    const double r = kSamePlaceFraction * kSameSizeRatio * k.size;  // the largest size a repeat may have
    const int x0 = cellX(k.pt.x - r), x1 = cellX(k.pt.x + r), y0 = cellY(k.pt.y - r), y1 = cellY(k.pt.y + r);
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x)
        for (int j : cells_[static_cast<size_t>(y * cols_ + x)])
          if (repeatsFeature(kept.keypoints[static_cast<size_t>(j)], kept.descriptors.row(j), k, d)) return true;
    return false;
  }

 private:
  int cellX(double x) const { return std::clamp(static_cast<int>(std::floor(x / kGridCellPx)), 0, cols_ - 1); }
  int cellY(double y) const { return std::clamp(static_cast<int>(std::floor(y / kGridCellPx)), 0, rows_ - 1); }
  size_t cell(const cv::Point2f& p) const { return static_cast<size_t>(cellY(p.y) * cols_ + cellX(p.x)); }
  int cols_, rows_;
  std::vector<std::vector<int>> cells_;
};

}  // namespace

bool repeatsFeature(const cv::KeyPoint& o, const cv::Mat& od, const cv::KeyPoint& k, const cv::Mat& d) {
  const double dx = o.pt.x - k.pt.x, dy = o.pt.y - k.pt.y;
  const double r = kSamePlaceFraction * std::max(o.size, k.size);
  if (dx * dx + dy * dy > r * r) return false;
  if (std::max(o.size, k.size) > kSameSizeRatio * std::min(o.size, k.size)) return false;
  return cv::norm(od, d, cv::NORM_L2) < kSameDescriptor;
}

Features synthesisedPlaneFeatures(const cv::Mat& reference, const Features& own, const std::vector<Vec2>& region,
                                  const Eigen::Matrix2d& frontal, const SiftOptions& sift) {
  Features out;
  out.image_size = own.image_size;
  cv::Mat gray = reference;
  if (reference.channels() == 3) cv::cvtColor(reference, gray, cv::COLOR_BGR2GRAY);
  if (reference.channels() == 4) cv::cvtColor(reference, gray, cv::COLOR_BGRA2GRAY);
  Eigen::JacobiSVD<Eigen::Matrix2d> fs(frontal);
  if (gray.empty() || !frontal.allFinite() || !(fs.singularValues()(0) > 0)) return out;
  // Shrink only (largest singular value 1), and keep the reference's handedness: a mirrored view
  // has mirrored descriptors.
  Eigen::Matrix2d F = frontal / fs.singularValues()(0);
  if (F.determinant() < 0) F.row(1) *= -1;
  std::vector<Vec2> outline = region;
  if (outline.size() < 3)
    outline = {Vec2(0, 0), Vec2(gray.cols - 1, 0), Vec2(gray.cols - 1, gray.rows - 1), Vec2(0, gray.rows - 1)};
  const double frontal_size = std::sqrt(std::abs(signedArea(outline) * F.determinant()));
  // Only the pattern and a margin for its features' context are synthesised.
  Vec2 lo = outline[0], hi = outline[0];
  for (const Vec2& p : outline) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double margin = kContextFraction * (hi - lo).norm() + kMarginPx;
  const cv::Rect box = cv::Rect(cv::Point(static_cast<int>(std::floor(lo.x() - margin)), static_cast<int>(std::floor(lo.y() - margin))),
                                cv::Point(static_cast<int>(std::ceil(hi.x() + margin)) + 1, static_cast<int>(std::ceil(hi.y() + margin)) + 1)) &
                       cv::Rect(0, 0, gray.cols, gray.rows);
  if (box.width < 16 || box.height < 16) return out;
  const cv::Mat crop = gray(box);
  const Vec2 offset(box.x, box.y);
  std::vector<double> scales;
  for (const double size : kViewSizesPx) {
    const double s = std::min(1.0, size / std::max(1.0, frontal_size));
    if (scales.empty() || s < scales.back() * (1 - kSameViewTolerance)) scales.push_back(s);
  }
  Features views;
  for (const double t : kTilts) {
    const int axes = t > 1 ? static_cast<int>(std::ceil(180.0 * t / kAxisStepDeg - 1e-9)) : 1;
    for (int a = 0; a < axes; ++a) {
      const double phi = a * kPi / axes;
      Eigen::Matrix2d Rphi;
      Rphi << std::cos(phi), -std::sin(phi), std::sin(phi), std::cos(phi);
      const Eigen::Matrix2d T = Rphi * Eigen::Vector2d(1, 1 / t).asDiagonal() * Rphi.transpose();
      for (const double s : scales) {
        // The view's map M = U diag(s1, s2) V^T; U (a rotation in the view) changes no SIFT feature.
        const Eigen::Matrix2d M = s * T * F;
        Eigen::JacobiSVD<Eigen::Matrix2d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
        const Eigen::Vector2d sv = svd.singularValues();
        if (std::abs(sv(0) - 1) < kSameViewTolerance && std::abs(sv(1) - 1) < kSameViewTolerance) continue;
        Eigen::Matrix2d V = svd.matrixV();
        if (V.determinant() < 0) V.col(1) *= -1;  // with U's column: M unchanged, V^T a rotation
        addView(crop, offset, V.transpose(), sv(0), sv(1), sift, &views);
      }
    }
  }
  std::vector<cv::Point2f> poly;
  for (const Vec2& p : region) poly.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  Features kept = own;
  const int n_own = kept.size();
  KeptGrid grid(gray.size());
  for (int i = 0; i < n_own; ++i) grid.add(kept, i);
  for (int i = 0; i < views.size(); ++i) {
    const cv::KeyPoint& k = views.keypoints[static_cast<size_t>(i)];
    if (poly.size() >= 3 && cv::pointPolygonTest(poly, k.pt, false) < 0) continue;
    if (grid.repeats(kept, k, views.descriptors.row(i))) continue;
    kept.keypoints.push_back(k);
    kept.descriptors.push_back(views.descriptors.row(i));
    grid.add(kept, kept.size() - 1);
  }
  out.keypoints.assign(kept.keypoints.begin() + n_own, kept.keypoints.end());
  if (kept.size() > n_own) out.descriptors = kept.descriptors.rowRange(n_own, kept.size()).clone();
  return out;
}

}  // namespace refgrasp::detector
