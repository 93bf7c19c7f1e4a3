#include "detector/registered_object.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <opencv2/imgproc.hpp>

#include "core/geometry.h"
#include "detector/cylinder_detection.h"
#include "detector/homography.h"
#include "detector/plane_views.h"

namespace refgrasp::detector {

namespace {

// poseFromDenseH with a prior: the pose continuing it is kept unless the other fits this much
// better (RMS px over the grid of densely aligned pattern points).
constexpr double kAmbiguityMarginPx = 0.5;

// Reference px -> the pattern plane (its frame oMp; metres scaled to about the reference's px):
// the inverse of x_ref ~ K_ref [r1 r2 t] (x, y, 1), [r1 r2 t] of the reference's cMp (as in
// poseFromHomography). Identity when that inverse is not finite.
Eigen::Matrix3d rectification(const PlanarTarget& target, double diagonal_px) {
  const Pose ref_cMp = target.ref_cMo * target.oMp;
  Eigen::Matrix3d A_ref;
  A_ref << ref_cMp.R.col(0), ref_cMp.R.col(1), ref_cMp.t;
  const double scale = diagonal_px / std::max(1e-12, (target.corners_o[2] - target.corners_o[0]).norm());
  const Eigen::Matrix3d R = Eigen::Vector3d(scale, scale, 1).asDiagonal() * (target.K_ref * A_ref).inverse();
  return R.allFinite() ? R : Eigen::Matrix3d::Identity();
}

// The linear map from reference px to the pattern plane seen fronto-parallel, at the pattern
// region's centre (the rectification's Jacobian there, any scale); identity without a reference
// pose.
Eigen::Matrix2d frontalMap(const ObjectModel& object) {
  if (!object.target) return Eigen::Matrix2d::Identity();
  const Eigen::Matrix3d R = rectification(*object.target, 1.0);
  Eigen::Vector2d c = Eigen::Vector2d(object.reference.cols - 1, object.reference.rows - 1) / 2;
  if (object.pattern_polygon_px.size() >= 3) c = polygonCentroid(object.pattern_polygon_px);
  const Eigen::Vector3d y = R * c.homogeneous();
  if (!(std::abs(y.z()) > 1e-12)) return Eigen::Matrix2d::Identity();
  const double u = y.x() / y.z(), v = y.y() / y.z();
  Eigen::Matrix2d J;
  J << R(0, 0) - u * R(2, 0), R(0, 1) - u * R(2, 1), R(1, 0) - v * R(2, 0), R(1, 1) - v * R(2, 1);
  J /= y.z();
  return J.allFinite() ? J : Eigen::Matrix2d::Identity();
}

}  // namespace

RegisteredObject registerObject(const ObjectModel& object, const DetectorOptions& opt) {
  RegisteredObject obj;
  obj.model = object;
  Features f = extractSift(object.reference, opt.sift);
  std::vector<Eigen::Vector2d> polygon = object.pattern_polygon_px;
  // A cylinder on its cylinder model has its own views (cylinder_views.h); under the paper pose it
  // is its flat label on the planar path, as a planar object of the same reference.
  const bool cylinder_model = object.isCylinder() && opt.pose == PoseMethod::kRefined;
  // The pattern as it looks tilted and from further off (plane_views.h), for the second index.
  Features views;
  if (opt.match.plane_views && !cylinder_model)
    views = synthesisedPlaneFeatures(object.reference, f, polygon, frontalMap(object), opt.sift);
  if (object.camera) {
    undistortKeypoints(&f.keypoints, *object.camera);
    undistortKeypoints(&views.keypoints, *object.camera);
    for (auto& p : polygon) p = object.camera->undistortPixel(p);
  }
  for (int i = 0; i < 4; ++i)
    obj.corners_und_px[i] =
        object.camera ? object.camera->undistortPixel(object.corners_px[i]) : object.corners_px[i];
  // A 2D-only pattern's final fit uses every reference feature (RegisteredObject::uncapped_index).
  std::optional<ReferenceIndex> all;
  if (!object.target) {
    MatchOptions uncapped = opt.match;
    uncapped.max_reference_features = std::numeric_limits<int>::max();
    all = buildReferenceIndex(f, polygon, uncapped);
  }
  Features own_and_views;
  if (views.size() > 0) {
    own_and_views = f;
    own_and_views.keypoints.insert(own_and_views.keypoints.end(), views.keypoints.begin(), views.keypoints.end());
    own_and_views.descriptors.push_back(views.descriptors);
  }
  obj.index = buildReferenceIndex(std::move(f), polygon, opt.match);
  if (object.target) obj.index.rectify_px = rectification(*object.target, obj.index.diagonal_px);
  if (all && all->features.size() > obj.index.features.size()) obj.uncapped_index = std::move(*all);
  obj.polygon_und_px = obj.index.polygon_px;
  obj.periods = repeatPeriods(obj.index);
  obj.pyramid = buildReferencePyramid(object.reference);
  // Dense refinement needs an undistorted reference and a region that is the pattern (one that
  // is not its bounding box is a mask on the template).
  obj.dense_usable = (!object.camera || !object.camera->hasDistortion()) && object.pattern_region_exact;
  double minx = 1e300, miny = 1e300, maxx = -1e300, maxy = -1e300;
  for (const Eigen::Vector2d& p : obj.polygon_und_px) {
    minx = std::min(minx, p.x()), maxx = std::max(maxx, p.x());
    miny = std::min(miny, p.y()), maxy = std::max(maxy, p.y());
  }
  obj.region_is_rect = std::abs(signedArea(obj.polygon_und_px)) >= 0.98 * (maxx - minx) * (maxy - miny);
  if (cylinder_model) registerCylinder(&obj, opt);
  if (own_and_views.size() > 0) {
    // The same object matched on its own features and the views together; the cap grows with
    // the views, so that they add to the reference's own features, not replace them.
    auto with = std::make_shared<RegisteredObject>(obj);
    MatchOptions match = opt.match;
    match.max_reference_features += views.size();
    with->index = buildReferenceIndex(std::move(own_and_views), polygon, match);
    with->index.rectify_px = obj.index.rectify_px;
    const int n = with->index.features.size();
    with->index.features_per_place = std::max(1.0, static_cast<double>(n) / std::max(1, n - views.size()));
    obj.with_views = std::move(with);
  }
  return obj;
}

void undistortKeypoints(std::vector<cv::KeyPoint>* kps, const Intrinsics& cam) {
  if (!cam.hasDistortion()) return;
  for (auto& k : *kps) {
    const Eigen::Vector2d u = cam.undistortPixel(Eigen::Vector2d(k.pt.x, k.pt.y));
    k.pt = cv::Point2f(static_cast<float>(u.x()), static_cast<float>(u.y()));
  }
}

Eigen::Vector2d distortPixel(const Intrinsics& cam, const Eigen::Vector2d& und) {
  if (!cam.hasDistortion()) return und;
  return cam.distortNormalized(Eigen::Vector2d((und.x() - cam.cx) / cam.fx,
                                               (und.y() - cam.cy) / cam.fy));
}

double patternDiagonal(const RegisteredObject& obj, const Eigen::Matrix3d& H) {
  std::array<Eigen::Vector2d, 4> q;
  for (int i = 0; i < 4; ++i) q[i] = applyHomography(H, obj.corners_und_px[i]);
  return 0.5 * ((q[2] - q[0]).norm() + (q[3] - q[1]).norm());
}

double densePixelInScene(const RegisteredObject& obj, const DenseRefineResult& d) {
  if (d.level < 0) return 0;
  std::array<Eigen::Vector2d, 4> q;
  for (int i = 0; i < 4; ++i) q[i] = applyHomography(d.H, obj.corners_und_px[i]);
  return std::ldexp(1.0, d.level) * std::sqrt(std::abs(signedArea(q)) / std::abs(signedArea(obj.corners_und_px)));
}

double inViewFraction(const RegisteredObject& obj, const Eigen::Matrix3d& H, const Intrinsics& camera) {
  std::vector<Eigen::Vector2d> q;
  double w0 = 0;
  for (const auto& c : obj.corners_und_px) {
    const Eigen::Vector3d p = H * c.homogeneous();
    if (q.empty()) w0 = p.z();
    if (!(p.z() * w0 > 0)) return 0;
    q.push_back(p.hnormalized());
  }
  const double area = std::abs(signedArea(q));
  if (!(area > 1e-9) || !std::isfinite(area)) return 0;
  const auto in = clipToBox(q, Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(camera.width - 0.5, camera.height - 0.5));
  return in.size() < 3 ? 0 : std::min(1.0, std::abs(signedArea(in)) / area);
}

std::vector<Eigen::Vector2d> verificationRegion(const RegisteredObject& obj, const MatchCandidate& cand) {
  if (obj.model.pattern_region_exact) return obj.polygon_und_px;
  std::vector<cv::Point2f> pts, hull;
  for (const Correspondence& c : cand.inliers)
    pts.push_back(obj.index.features.keypoints[static_cast<size_t>(c.ref)].pt);
  if (pts.size() < 3) return {};
  cv::convexHull(pts, hull);
  std::vector<Eigen::Vector2d> convex;
  for (const cv::Point2f& p : hull) convex.emplace_back(p.x, p.y);
  return clipToConvex(obj.polygon_und_px, convex);
}

DenseRefineResult refineDense(const RegisteredObject& obj, const Eigen::Matrix3d& H, const cv::Mat& image,
                              const Intrinsics& camera, const DenseRefineOptions& opt) {
  // The template is the region's bounding box; a polygon region masks it.
  std::array<Eigen::Vector2d, 4> rect = obj.corners_und_px;
  const std::vector<Eigen::Vector2d>* mask = nullptr;
  if (!obj.region_is_rect) {
    Eigen::Vector2d lo = obj.polygon_und_px[0], hi = lo;
    for (const auto& p : obj.polygon_und_px) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    rect = {lo, Eigen::Vector2d(hi.x(), lo.y()), hi, Eigen::Vector2d(lo.x(), hi.y())};
    mask = &obj.polygon_und_px;
  }
  if (!camera.hasDistortion())
    return refineHomographyDense(obj.pyramid, image, H, rect, opt, mask);
  // H lives in undistorted pixels: resample only the pattern's neighbourhood of the image onto
  // the ideal pinhole grid (never the whole frame), refine there, and move H back.
  Eigen::Vector2d lo(1e9, 1e9), hi(-1e9, -1e9);
  for (const auto& c : rect) {
    const Eigen::Vector2d p = applyHomography(H, c);
    if (!p.allFinite()) return {};
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double margin = opt.max_corner_shift_px + 8;
  const int x0 = static_cast<int>(std::floor(lo.x() - margin));
  const int y0 = static_cast<int>(std::floor(lo.y() - margin));
  const int w = static_cast<int>(std::ceil(hi.x() + margin)) - x0 + 1;
  const int h = static_cast<int>(std::ceil(hi.y() + margin)) - y0 + 1;
  if (w <= 0 || h <= 0 || w > 4 * camera.width || h > 4 * camera.height) return {};
  cv::Mat mapx(h, w, CV_32FC1), mapy(h, w, CV_32FC1);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      const Eigen::Vector2d d = camera.distortNormalized(
          Eigen::Vector2d((x0 + u - camera.cx) / camera.fx, (y0 + v - camera.cy) / camera.fy));
      mapx.at<float>(v, u) = static_cast<float>(d.x());
      mapy.at<float>(v, u) = static_cast<float>(d.y());
    }
  cv::Mat crop;
  cv::remap(image, crop, mapx, mapy, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  Eigen::Matrix3d T = Eigen::Matrix3d::Identity();  // undistorted px -> crop px
  T(0, 2) = -x0;
  T(1, 2) = -y0;
  DenseRefineResult r = refineHomographyDense(obj.pyramid, crop, T * H, rect, opt, mask);
  r.H = T.inverse() * r.H;
  return r;
}

PoseResult poseFromDenseH(const RegisteredObject& obj, const DetectorOptions& opt, const Eigen::Matrix3d& H,
                          const Intrinsics& camera, const Pose* prior) {
  const PlanarTarget& target = *obj.model.target;
  const int n = opt.dense.pose_grid;
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> y;
  const auto& c = obj.corners_und_px;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double a = (i + 0.5) / n, b = (j + 0.5) / n;
      const Eigen::Vector2d r =
          (1 - b) * ((1 - a) * c[0] + a * c[1]) + b * ((1 - a) * c[3] + a * c[2]);
      const auto Xo = target.backProject(r);
      if (!Xo) continue;
      X.push_back(*Xo);
      y.push_back(applyHomography(H, r));
    }
  if (prior && prior->isFinite())
    return estimatePoseRefinedNear(X, y, target, camera.K(), opt.pose_options, *prior, kAmbiguityMarginPx);
  return estimatePoseRefined(X, y, target, camera.K(), opt.pose_options);
}

PoseResult estimatePose(const RegisteredObject& obj, const DetectorOptions& opt, const MatchCandidate& match,
                        const Features& scene, const Intrinsics& camera, PoseMethod method,
                        const DenseRefineResult* dense, bool* from_features) {
  if (from_features) *from_features = false;
  if (!obj.model.target) return {};
  const PlanarTarget& target = *obj.model.target;
  if (method == PoseMethod::kPaper)
    return estimatePosePaper(match.H, target, camera.K(), opt.pose_options);
  if (opt.dense.enabled && obj.dense_usable && !scene.image.empty()) {
    const DenseRefineResult dr = dense ? *dense : refineDense(obj, match.H, scene.image, camera, opt.dense);
    if (dr.ok) {
      const PoseResult p = poseFromDenseH(obj, opt, dr.H, camera);
      if (p.ok) return p;
    }
  }
  if (from_features) *from_features = true;
  // The features' pose: each inlier weighted by its scene keypoint's size (finer = more precise).
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> y;
  std::vector<double> sigma;
  X.reserve(match.inliers.size());
  y.reserve(match.inliers.size());
  const double k = opt.pose_options.keypoint_sigma_per_size;
  for (const auto& c : match.inliers) {
    const cv::Point2f& pr = obj.index.features.keypoints[c.ref].pt;
    const auto Xo = target.backProject(Eigen::Vector2d(pr.x, pr.y));
    if (!Xo) continue;
    const cv::KeyPoint& ks = scene.keypoints[c.scene];
    X.push_back(*Xo);
    y.emplace_back(ks.pt.x, ks.pt.y);
    if (k > 0) sigma.push_back(std::max(0.05, k * ks.size));
  }
  return estimatePoseRefined(X, y, target, camera.K(), opt.pose_options, sigma);
}

}  // namespace refgrasp::detector
