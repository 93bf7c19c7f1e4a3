#include "detector/search_region.h"

#include <algorithm>
#include <cmath>

#include "detector/cylinder_detection.h"
#include "detector/homography.h"

namespace refgrasp::detector {

namespace {

// The box [lo, hi] (real image px) grown by the prior's margin, clamped just outside the image
// (the caller clips it to the image).
bool growRegion(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, const ObjectPrior& p, const Intrinsics& cam,
                cv::Rect* roi, double* margin_px) {
  const double m = p.roi_margin * std::max(hi.x() - lo.x(), hi.y() - lo.y());
  *margin_px = std::floor(m);
  auto clampX = [&](double x) { return static_cast<int>(std::clamp(x, -1.0, cam.width + 1.0)); };
  auto clampY = [&](double y) { return static_cast<int>(std::clamp(y, -1.0, cam.height + 1.0)); };
  *roi = cv::Rect(cv::Point(clampX(std::floor(lo.x() - m)), clampY(std::floor(lo.y() - m))),
                  cv::Point(clampX(std::ceil(hi.x() + m) + 1), clampY(std::ceil(hi.y() + m) + 1)));
  return true;
}

// The region a predicted pose gives a cylinder on its cylinder model: the projection of the
// label's visible part (real image px) and the sizes its features would have there, widened by
// scale_margin, as predictRegion does for a plane.
bool predictCylinderRegion(const RegisteredObject& obj, const ObjectPrior& p, const Intrinsics& cam,
                           Eigen::Vector2d* lo, Eigen::Vector2d* hi, double* min_size, double* max_size) {
  const CylinderLabel& L = *obj.model.cylinder;
  constexpr int kGrid = 9;  // points per side of the grid over the visible part
  const std::vector<Eigen::Vector2d> px = projectVisibleLabel(L, *p.cMo, cam, kGrid);
  if (px.size() < 4) return false;
  *lo = Eigen::Vector2d(1e300, 1e300);
  *hi = -*lo;
  for (const auto& q : px) {
    *lo = lo->cwiseMin(q);
    *hi = hi->cwiseMax(q);
  }
  const auto sizes = predictedKeypointSizes(obj, *p.cMo, cam);
  if (!sizes) return false;
  *min_size = sizes->first / p.scale_margin;
  *max_size = sizes->second * p.scale_margin;
  return lo->allFinite() && hi->allFinite();
}

// What a predicted H (undistorted reference px -> undistorted scene px) gives: the range of the
// reference keypoint sizes scaled by H's local scale at each, widened by scale_margin, and the
// largest local scale (scene px per reference px). False when H maps none finitely.
bool predictSizes(const RegisteredObject& obj, const Eigen::Matrix3d& H, const ObjectPrior& p, double* min_size,
                  double* max_size, double* max_scale) {
  double smin = 1e300, smax = 0, scale = 0;
  for (const cv::KeyPoint& k : obj.index.features.keypoints) {
    const Eigen::Vector3d y = H * Eigen::Vector3d(k.pt.x, k.pt.y, 1);
    const double u = y.x() / y.z(), v = y.y() / y.z();
    Eigen::Matrix2d J;  // d(scene px) / d(reference px), times y.z
    J << H(0, 0) - u * H(2, 0), H(0, 1) - u * H(2, 1), H(1, 0) - v * H(2, 0), H(1, 1) - v * H(2, 1);
    const double local = std::sqrt(std::abs(J.determinant())) / std::abs(y.z());
    const double s = k.size * local;
    if (!std::isfinite(s)) continue;
    smin = std::min(smin, s);
    smax = std::max(smax, s);
    scale = std::max(scale, local);
  }
  if (smax <= 0) return false;
  *min_size = smin / p.scale_margin;
  *max_size = smax * p.scale_margin;
  *max_scale = scale;
  return true;
}

// The region a predicted pose (or, without one, a predicted H) gives: the projected pattern's
// bounding box (real image px) grown by roi_margin, the keypoint sizes (predictSizes) and the
// largest local scale. False when the pattern is not in front of the camera.
bool predictRegion(const RegisteredObject& obj, const ObjectPrior& p, const Intrinsics& cam,
                   cv::Rect* roi, double* min_size, double* max_size, double* margin_px, double* max_scale) {
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  if (obj.cylinder_model) {
    if (!predictCylinderRegion(obj, p, cam, &lo, &hi, min_size, max_size)) return false;
    return growRegion(lo, hi, p, cam, roi, margin_px);
  }
  Eigen::Matrix3d H;
  if (p.cMo) {
    const PlanarTarget& t = *obj.model.target;
    std::vector<Eigen::Vector2d> ref(4), und(4);
    for (int i = 0; i < 4; ++i) {
      const Eigen::Vector3d Xc = *p.cMo * t.corners_o[i];
      if (!(Xc.z() > 1e-6)) return false;
      ref[i] = t.corners_ref_px[i];
      und[i] = projectPinhole(cam.K(), Xc);
      const Eigen::Vector2d px = cam.project(Xc);
      lo = lo.cwiseMin(px);
      hi = hi.cwiseMax(px);
    }
    H = fitHomographyLeastSquares(ref, und);
  } else {
    H = *p.H;
    for (const Eigen::Vector2d& c : obj.corners_und_px) {
      const Eigen::Vector3d y = H * c.homogeneous();
      if (!(y.z() > 1e-12)) return false;  // the corner is beyond the vanishing line
      const Eigen::Vector2d px = distortPixel(cam, y.hnormalized());
      lo = lo.cwiseMin(px);
      hi = hi.cwiseMax(px);
    }
  }
  if (!H.allFinite() || !lo.allFinite() || !hi.allFinite()) return false;
  if (!predictSizes(obj, H, p, min_size, max_size, max_scale)) return false;
  return growRegion(lo, hi, p, cam, roi, margin_px);
}

}  // namespace

Search searchFor(const RegisteredObject& obj, const ObjectPrior* prior, const DetectionQuery& q,
                 const Intrinsics& camera) {
  Search s;
  if (!prior && q.only_priors) {
    s.searched = false;
    return s;
  }
  const cv::Rect full(0, 0, camera.width, camera.height);
  cv::Rect roi = full;
  if (prior) {
    cv::Rect predicted;
    double margin_px = 0, max_scale = 0;
    const bool from_pose = prior->cMo && (obj.model.target || obj.cylinder_model);
    const bool from_h = !from_pose && prior->H && !obj.cylinder_model && !obj.model.isMultiView();
    const bool has_prediction = (from_pose || from_h) &&
                                predictRegion(obj, *prior, camera, &predicted, &s.region.min_size_px,
                                              &s.region.max_size_px, &margin_px, &max_scale);
    if (prior->roi.area() > 0) {
      roi = prior->roi;
    } else if (has_prediction) {
      roi = predicted;
      // The pattern lies margin_px inside the region: that much of the crop's context is there.
      if (!q.roi || (roi & *q.roi) == roi) s.region.inner_margin_px = margin_px;
      if (prior->max_scale > 0) s.region.downsample = std::max(1.0, max_scale / prior->max_scale);
    }
  }
  if (q.roi) roi &= *q.roi;
  s.roi = roi & full;
  s.region.roi = s.roi == full ? cv::Rect() : s.roi;
  return s;
}

}  // namespace refgrasp::detector
