#include "detector/reference_index.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/geometry.h"
#include "detector/homography.h"
#include "detector/matching.h"

namespace refgrasp::detector {
namespace {

using Vec2 = Eigen::Vector2d;
constexpr int kDim = 128;

}  // namespace

ReferenceIndex buildReferenceIndex(Features f, const std::vector<Vec2>& polygon,
                                   const MatchOptions& opt) {
  opt.check();
  refgrasp::check(polygon.empty() || polygon.size() >= 3, "buildReferenceIndex",
                  "pattern polygon needs >= 3 vertices");
  refgrasp::check(f.descriptors.rows == f.size() && (f.size() == 0 || f.descriptors.cols == kDim),
                  "buildReferenceIndex", "descriptors must be N x 128");
  ReferenceIndex ri;
  ri.polygon_px = polygon;
  if (ri.polygon_px.empty()) {
    const double w = f.image_size.width, h = f.image_size.height;
    ri.polygon_px = {Vec2(-0.5, -0.5), Vec2(w - 0.5, -0.5), Vec2(w - 0.5, h - 0.5), Vec2(-0.5, h - 0.5)};
  }
  for (const auto& p : ri.polygon_px) refgrasp::check(p.allFinite(), "buildReferenceIndex", "non-finite polygon vertex");
  std::vector<cv::Point2f> poly, hull;
  for (const auto& p : ri.polygon_px) poly.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  cv::convexHull(poly, hull, /*clockwise=*/false);
  for (const auto& p : hull) ri.hull_px.emplace_back(p.x, p.y);
  // Centroid of the polygon (area-weighted), bounding-box diagonal.
  refgrasp::check(std::abs(shoelace2(ri.polygon_px.data(), ri.polygon_px.size())) > 1e-9,
                  "buildReferenceIndex", "pattern polygon has zero area");
  ri.centre_px = polygonCentroid(ri.polygon_px);
  Eigen::Vector2d lo = ri.polygon_px[0], hi = ri.polygon_px[0];
  for (const auto& p : ri.polygon_px) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  ri.diagonal_px = (hi - lo).norm();

  // Inside the polygon, strongest first.
  std::vector<int> keep;
  for (int i = 0; i < f.size(); ++i)
    if (cv::pointPolygonTest(poly, f.keypoints[i].pt, false) >= 0) keep.push_back(i);
  auto stronger = [&](int a, int b) { return f.keypoints[a].response > f.keypoints[b].response; };
  std::stable_sort(keep.begin(), keep.end(), stronger);
  if (static_cast<int>(keep.size()) > opt.max_reference_features) {
    // Round robin over octaves (strongest first within each): coarse features are few and weak
    // but the only ones left when the object is far away, so the cap must not drop them.
    std::map<int, std::vector<int>> octaves;
    for (int i : keep) octaves[static_cast<int>(std::floor(std::log2(std::max(1e-3f, f.keypoints[i].size))))].push_back(i);
    std::vector<int> picked;
    for (size_t rank = 0; static_cast<int>(picked.size()) < opt.max_reference_features; ++rank)
      for (const auto& [oct, list] : octaves)
        if (rank < list.size() && static_cast<int>(picked.size()) < opt.max_reference_features)
          picked.push_back(list[rank]);
    std::stable_sort(picked.begin(), picked.end(), stronger);
    keep = picked;
  }
  ri.features.image_size = f.image_size;
  ri.features.descriptors.create(static_cast<int>(keep.size()), kDim, CV_32F);
  for (size_t k = 0; k < keep.size(); ++k) {
    ri.features.keypoints.push_back(f.keypoints[keep[k]]);
    f.descriptors.row(keep[k]).copyTo(ri.features.descriptors.row(static_cast<int>(k)));
  }
  ri.descriptors = integerDescriptors(ri.features.descriptors, /*byte_split=*/true);
  if (!ri.features.keypoints.empty()) {
    std::vector<cv::Point2f> pts, fh;
    for (const auto& k : ri.features.keypoints) pts.push_back(k.pt);
    cv::convexHull(pts, fh);
    ri.feature_hull_area_px2 = cv::contourArea(fh);
  }

  // About 8 features a cell: a nearest-first walk then visits few cells (O(n) memory, O(n) build).
  const int n = ri.features.size();
  const double area = std::max(1.0, static_cast<double>(f.image_size.area()));
  const int cell_px = static_cast<int>(std::clamp(std::sqrt(area * 8.0 / std::max(1, n)), 4.0, 256.0));
  ri.neighbours = GridIndex(ri.features.keypoints, f.image_size, cell_px);
  return ri;
}

std::vector<NearestTwo> nearestTwo(const ReferenceIndex& ref, const Features& scene, KnnKernel kernel) {
  return nearestTwo(ref.descriptors, integerDescriptors(scene.descriptors, /*byte_split=*/false), kernel);
}

std::vector<Eigen::Vector2d> repeatPeriods(const ReferenceIndex& ref, int max_periods) {
  const int n = ref.features.size();
  if (n < 2 || ref.features.descriptors.empty()) return {};
  constexpr double kLookAlike = 200;  // SIFT descriptor distance (norm ~512)
  constexpr double kBin = 3;          // rectified units per vote bin
  cv::Mat d;
  ref.features.descriptors.convertTo(d, CV_32F);
  cv::Mat gram = d * d.t();  // |a - b|^2 = |a|^2 + |b|^2 - 2 a.b
  std::vector<Eigen::Vector2d> p(n);
  for (int i = 0; i < n; ++i) {
    const cv::Point2f& q = ref.features.keypoints[i].pt;
    p[i] = applyHomography(ref.rectify_px, Eigen::Vector2d(q.x, q.y));
  }
  std::map<std::pair<long, long>, int> votes;
  for (int i = 0; i < n; ++i) {
    const cv::KeyPoint& ki = ref.features.keypoints[i];
    for (int j = i + 1; j < n; ++j) {
      const cv::KeyPoint& kj = ref.features.keypoints[j];
      if (std::abs(kj.size - ki.size) > 0.3 * std::max(ki.size, kj.size)) continue;
      if (std::hypot(kj.pt.x - ki.pt.x, kj.pt.y - ki.pt.y) < std::max(ki.size, kj.size)) continue;
      const double d2 = gram.at<float>(i, i) + gram.at<float>(j, j) - 2.0 * gram.at<float>(i, j);
      if (!(d2 < kLookAlike * kLookAlike)) continue;
      const Eigen::Vector2d v = p[j] - p[i];
      if (!v.allFinite()) continue;
      const std::pair<long, long> key(std::lround(v.x() / kBin), std::lround(v.y() / kBin));
      ++votes[key];
      ++votes[{-key.first, -key.second}];
    }
  }
  const int min_votes = std::max(4, n / 100);
  std::vector<std::pair<int, std::pair<long, long>>> modes;
  for (const auto& [key, count] : votes)
    if (count >= min_votes) modes.push_back({count, key});
  std::stable_sort(modes.begin(), modes.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<Eigen::Vector2d> out;
  for (const auto& m : modes) {
    if (static_cast<int>(out.size()) >= max_periods) break;
    out.emplace_back(kBin * m.second.first, kBin * m.second.second);
  }
  return out;
}

}  // namespace refgrasp::detector
