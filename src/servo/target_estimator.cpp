#include "servo/target_estimator.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "core/error.h"
#include "core/geometry.h"
#include "servo/surface_model.h"

namespace refgrasp::servo {

const char* toString(TargetStatus s) {
  switch (s) {
    case TargetStatus::kNone: return "none";
    case TargetStatus::kLost: return "lost";
    case TargetStatus::kUnconfirmed: return "unconfirmed";
    case TargetStatus::kConfirmed: return "confirmed";
  }
  return "?";
}

void OracleOptions::check() const {
  refgrasp::check(std::isfinite(border_px) && border_px >= 0, "OracleOptions.border_px",
                  "must be >= 0");
  refgrasp::check(std::isfinite(min_side_px) && min_side_px > 0, "OracleOptions.min_side_px",
                  "must be > 0");
  refgrasp::check(std::isfinite(max_view_angle_rad) && max_view_angle_rad > 0 &&
                      max_view_angle_rad < M_PI / 2,
                  "OracleOptions.max_view_angle_rad", "must be in (0, pi/2)");
}

std::vector<Eigen::Vector2d> labelSamples(const CylinderLabel& label,
                                          const std::vector<Eigen::Vector2d>& region_px) {
  constexpr double kColumnArcRad = M_PI / 180;
  constexpr int kRows = 48;
  std::vector<Eigen::Vector2d> samples;
  if (region_px.size() < 3) return samples;
  double lo = region_px[0].x(), hi = lo;
  for (const Eigen::Vector2d& p : region_px) {
    lo = std::min(lo, p.x());
    hi = std::max(hi, p.x());
  }
  const double du = kColumnArcRad * label.radius_m / label.metresPerPixelU();
  const int n = std::max(1, static_cast<int>(std::ceil((hi - lo) / du)));
  constexpr double kFar = 1e9;
  for (int k = 0; k < n; ++k) {
    const double u0 = lo + (hi - lo) * k / n, u1 = lo + (hi - lo) * (k + 1) / n;
    // The region's rows in this column (its top to its bottom).
    const std::vector<Eigen::Vector2d> column =
        clipToBox(region_px, Eigen::Vector2d(u0, -kFar), Eigen::Vector2d(u1, kFar));
    if (column.size() < 3) continue;
    double top = column[0].y(), bottom = top;
    for (const Eigen::Vector2d& p : column) {
      top = std::min(top, p.y());
      bottom = std::max(bottom, p.y());
    }
    const double u = 0.5 * (u0 + u1);
    for (int r = 0; r < kRows; ++r) samples.emplace_back(u, top + (bottom - top) * r / (kRows - 1));
  }
  return samples;
}

VisibleLabel visibleLabel(const CylinderLabel& label, const std::vector<Eigen::Vector2d>& samples_px,
                          const Pose& cMo, const Intrinsics& cam, double border_px,
                          double min_facing_cos) {
  constexpr double kMinDepthM = 0.05;  // as a plane's corners
  VisibleLabel v;
  std::vector<Eigen::Vector2d> px;
  Eigen::Vector2d uv_lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d uv_hi = -uv_lo;
  for (const Eigen::Vector2d& uv : samples_px) {
    if (!label.facesCamera(uv.x(), uv.y(), cMo, min_facing_cos)) continue;
    const Eigen::Vector3d Xc = cMo * label.point(uv);
    if (!(Xc.z() >= kMinDepthM)) continue;
    const Eigen::Vector2d p = cam.project(Xc);
    if (!p.allFinite() || p.x() < border_px || p.y() < border_px ||
        p.x() > cam.width - 1 - border_px || p.y() > cam.height - 1 - border_px)
      continue;
    px.push_back(p);
    uv_lo = uv_lo.cwiseMin(uv);
    uv_hi = uv_hi.cwiseMax(uv);
  }
  v.points = static_cast<int>(px.size());
  if (px.empty()) return v;

  // The axis's direction in the image, near the seen rows (straight down the image when the
  // axis is seen end-on or runs behind the camera).
  Eigen::Vector2d along(0, 1);
  const double y0 = label.point(Eigen::Vector2d(0, uv_lo.y())).y();
  const double y1 = label.point(Eigen::Vector2d(0, uv_hi.y())).y();
  const Eigen::Vector3d A0 = cMo * label.axisPoint(y0), A1 = cMo * label.axisPoint(y0 + std::max(y1 - y0, 0.01));
  if (A0.z() >= kMinDepthM && A1.z() >= kMinDepthM) {
    const Eigen::Vector2d d = cam.project(A1) - cam.project(A0);
    if (d.allFinite() && d.norm() > 1e-6) along = d.normalized();
  }
  const Eigen::Vector2d across(-along.y(), along.x());
  double a_lo = std::numeric_limits<double>::infinity(), a_hi = -a_lo, c_lo = a_lo, c_hi = -a_lo;
  Eigen::Vector2d box_lo = px[0], box_hi = px[0];
  for (const Eigen::Vector2d& p : px) {
    a_lo = std::min(a_lo, p.dot(along));
    a_hi = std::max(a_hi, p.dot(along));
    c_lo = std::min(c_lo, p.dot(across));
    c_hi = std::max(c_hi, p.dot(across));
    box_lo = box_lo.cwiseMin(p);
    box_hi = box_hi.cwiseMax(p);
  }
  v.height_px = a_hi - a_lo;
  v.width_px = c_hi - c_lo;
  std::vector<cv::Point2f> pts, hull;
  pts.reserve(px.size());
  for (const Eigen::Vector2d& p : px) pts.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  cv::convexHull(pts, hull);
  v.area_px2 = hull.size() >= 3 ? cv::contourArea(hull) : 0;

  const std::array<Eigen::Vector2d, 4> uv_corners = {
      uv_lo, Eigen::Vector2d(uv_hi.x(), uv_lo.y()), uv_hi, Eigen::Vector2d(uv_lo.x(), uv_hi.y())};
  for (size_t i = 0; i < 4; ++i) {
    const Eigen::Vector3d Xc = cMo * label.point(uv_corners[i]);
    if (!(Xc.z() >= kMinDepthM)) {
      v.corners = {box_lo, Eigen::Vector2d(box_hi.x(), box_lo.y()), box_hi,
                   Eigen::Vector2d(box_lo.x(), box_hi.y())};
      break;
    }
    v.corners[i] = cam.project(Xc);
  }
  return v;
}

OracleEstimator::OracleEstimator(const detector::ObjectModel& object, const OracleOptions& o)
    : name_(object.name), opt_(o) {
  opt_.check();
  add(object, Pose());
  if (!object.hasPose() || (quads_o_.empty() && labels_.empty()))
    throw std::invalid_argument("OracleEstimator: object '" + object.name +
                                "' has no reference pose (2D only)");
}

void OracleEstimator::add(const detector::ObjectModel& model, const Pose& oMv) {
  if (model.isMultiView()) {
    for (const detector::ObjectView& v : model.views)
      if (v.model) add(*v.model, oMv * v.oMv);
  } else if (model.isCylinder()) {
    labels_.push_back(Label{*model.cylinder, oMv, labelSamples(*model.cylinder, model.pattern_polygon_px)});
  } else {
    for (std::array<Eigen::Vector3d, 4> q : patternQuads(model)) {
      for (Eigen::Vector3d& X : q) X = oMv * X;
      quads_o_.push_back(q);
    }
  }
}

bool OracleEstimator::visible(const Pose& cMo, const Intrinsics& cam,
                              std::array<Eigen::Vector2d, 4>* corners) const {
  if (!quads_o_.empty() && planeVisible(cMo, cam, corners)) return true;
  const double min_cos = std::cos(opt_.max_view_angle_rad);
  for (const Label& L : labels_) {
    const VisibleLabel v = visibleLabel(L.label, L.samples_px, cMo * L.oMv, cam, opt_.border_px, min_cos);
    if (v.area_px2 >= opt_.min_side_px * opt_.min_side_px &&
        std::min(v.width_px, v.height_px) >= 0.5 * opt_.min_side_px) {
      if (corners) *corners = v.corners;
      return true;
    }
  }
  return false;
}

bool OracleEstimator::planeVisible(const Pose& cMo, const Intrinsics& cam,
                                   std::array<Eigen::Vector2d, 4>* corners) const {
  // Several views: the one seen most squarely.
  const std::array<Eigen::Vector3d, 4> corners_o = *facingQuad(quads_o_, cMo);
  const Eigen::Vector3d normal_o =
      (corners_o[1] - corners_o[0]).cross(corners_o[3] - corners_o[0]).normalized();
  std::array<Eigen::Vector2d, 4> px;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < 4; ++i) {
    const Eigen::Vector3d c = cMo * corners_o[i];
    if (c.z() < 0.05) return false;
    px[i] = cam.project(c);
    centre += 0.25 * c;
    if (!px[i].allFinite() || px[i].x() < opt_.border_px || px[i].y() < opt_.border_px ||
        px[i].x() > cam.width - 1 - opt_.border_px || px[i].y() > cam.height - 1 - opt_.border_px)
      return false;
  }
  // The pattern is seen from its front (the planar convention: z_o points away from a viewer of
  // the texture, along the line of sight) and not too obliquely.
  const Eigen::Vector3d n = cMo.R * normal_o;
  const double cos_view = n.dot(centre.normalized());
  if (cos_view < std::cos(opt_.max_view_angle_rad)) return false;
  for (size_t i = 0; i < 4; ++i)
    if ((px[i] - px[(i + 1) % 4]).norm() < opt_.min_side_px) return false;
  if (corners) *corners = px;
  return true;
}

TargetObservation OracleEstimator::observe(const robot::StereoFrame& frame, const StereoRig& rig,
                                           const std::optional<Pose>&) {
  TargetObservation o;
  o.status = TargetStatus::kLost;
  o.source = "truth";
  for (const robot::ObjectTruth& t : frame.truth) {
    if (t.object != name_) continue;
    std::array<Eigen::Vector2d, 4> corners;
    if (!visible(t.cMo, rig.left, &corners)) return o;
    o.status = TargetStatus::kConfirmed;
    o.cMo = t.cMo;
    o.corners = corners;
    return o;
  }
  o.error = "frame " + std::to_string(frame.index) + " carries no ground truth for '" + name_ + "'";
  return o;
}

}  // namespace refgrasp::servo
