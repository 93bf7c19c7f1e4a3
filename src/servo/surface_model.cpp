#include "servo/surface_model.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "core/geometry.h"

namespace refgrasp::servo {

namespace {

/// Arc of one strip of a cylinder's label (radians): the strip's outline is drawn with straight
/// edges, within a fraction of a pixel of the curve for a can filling the image.
constexpr double kStripArcRad = 5 * M_PI / 180;

/// Crossing-number test of a point against a polygon (any orientation).
bool insidePolygon(const std::vector<Eigen::Vector2d>& poly, const Eigen::Vector2d& p) {
  bool in = false;
  for (size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const Eigen::Vector2d& a = poly[i];
    const Eigen::Vector2d& b = poly[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x())
      in = !in;
  }
  return in;
}

/// Cos of the angle between an outward normal at X and the ray from X to the camera centre o.
double facingCos(const Eigen::Vector3d& n_out, const Eigen::Vector3d& X, const Eigen::Vector3d& o) {
  const Eigen::Vector3d v = o - X;
  const double len = v.norm();
  return len > 0 ? n_out.dot(v) / len : -1;
}

}  // namespace

SurfaceModel::SurfaceModel(const detector::ObjectModel& object) {
  if (!object.hasPose())
    throw std::invalid_argument(object.name + ": tracking needs a 3D object (reference_pose, cylinder "
                                              "or views)");
  add(object, Pose());
}

void SurfaceModel::add(const detector::ObjectModel& model, const Pose& oMs) {
  if (model.isMultiView()) {
    for (const detector::ObjectView& v : model.views) {
      if (!v.model) throw std::invalid_argument(model.name + ": view '" + v.name + "' has no model");
      add(*v.model, oMs * v.oMv);
    }
    return;
  }
  if (!model.has3d())
    throw std::invalid_argument(model.name + ": a surface needs metric geometry (reference_pose or cylinder)");
  Surface s;
  s.oMs = oMs;
  if (model.isCylinder()) {
    const CylinderLabel& L = *model.cylinder;
    s.cylinder = L;
    s.label_polygon_px = model.pattern_polygon_px;
    const double lo = -0.5, hi = L.image_width - 0.5;
    const double du = kStripArcRad * L.radius_m / L.metresPerPixelU();
    const int n = std::max(1, static_cast<int>(std::ceil((hi - lo) / du)));
    constexpr double kFar = 1e9;
    for (int k = 0; k < n; ++k) {
      const double u0 = lo + (hi - lo) * k / n, u1 = lo + (hi - lo) * (k + 1) / n;
      std::vector<Eigen::Vector2d> strip =
          clipToBox(s.label_polygon_px, Eigen::Vector2d(u0, -kFar), Eigen::Vector2d(u1, kFar));
      if (strip.size() >= 3) s.strips_px.push_back(std::move(strip));
    }
  } else {
    for (const Eigen::Vector2d& px : model.pattern_polygon_px) {
      const Eigen::Vector2d und = model.camera ? model.camera->undistortPixel(px) : px;
      const std::optional<Eigen::Vector3d> X = model.target->backProject(und);
      if (!X) throw std::invalid_argument(model.name + ": pattern polygon vertex off the pattern plane");
      s.polygon_s.push_back(*X);
    }
    s.normal_s = model.plane_normal_o;
    s.offset_m = model.plane_offset_m;
    // The reference camera saw the pattern: its side of the plane is the outer one.
    if (model.reference_cMo) {
      const Eigen::Vector3d o = model.reference_cMo->inverse().t;
      s.outer_sign = s.normal_s.dot(o) - s.offset_m >= 0 ? 1 : -1;
    }
  }
  surfaces_.push_back(std::move(s));
}

std::optional<SurfaceHit> SurfaceModel::intersect(const Pose& cMo, const Intrinsics& cam,
                                                  const Eigen::Vector2d& px) const {
  const Eigen::Vector2d xn = cam.undistortToNormalized(px);
  const Eigen::Vector3d ray_c(xn.x(), xn.y(), 1);
  const bool several = surfaces_.size() > 1;
  std::optional<SurfaceHit> best;
  double best_depth = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < surfaces_.size(); ++i) {
    const Surface& S = surfaces_[i];
    const Pose cMs = several ? cMo * S.oMs : cMo;
    Eigen::Vector3d X_s, n_s;
    double depth = 0;  // along the ray, in units of ray_c (camera z)
    if (S.cylinder) {
      const Pose sMc = cMs.inverse();
      const Eigen::Vector3d o = sMc.t, d = sMc.R * ray_c;
      const std::optional<double> t = S.cylinder->intersect(o, d);
      if (!t) continue;
      X_s = o + *t * d;
      n_s = Eigen::Vector3d(X_s.x(), 0, X_s.z() - S.cylinder->radius_m).normalized();  // away from the axis
      depth = *t;
      if (several) {
        const std::optional<Eigen::Vector2d> uv = S.cylinder->pixel(X_s);
        if (!uv || !insidePolygon(S.label_polygon_px, *uv)) continue;
      }
    } else {
      // Plane n.X_s = d in the camera frame: n_c = R n, d_c = d + n_c . t.
      const Eigen::Vector3d n_c = cMs.R * S.normal_s;
      const double d_c = S.offset_m + n_c.dot(cMs.t);
      const double den = n_c.dot(ray_c);
      if (std::abs(den) < 1e-9) continue;
      depth = d_c / den;
      if (!(depth > 1e-6)) continue;
      X_s = cMs.inverse() * (depth * ray_c);
      n_s = S.outer_sign * S.normal_s.normalized();
      if (several) {
        // Seen from its outer side, and within the pattern polygon.
        if (!(S.outer_sign * den < 0)) continue;
        const Eigen::Vector3d n = S.normal_s.normalized();
        const Eigen::Vector3d e1 = n.unitOrthogonal(), e2 = n.cross(e1);
        std::vector<Eigen::Vector2d> poly;
        for (const Eigen::Vector3d& V : S.polygon_s) poly.emplace_back(V.dot(e1), V.dot(e2));
        if (!insidePolygon(poly, Eigen::Vector2d(X_s.dot(e1), X_s.dot(e2)))) continue;
      }
    }
    if (depth < best_depth) {
      best_depth = depth;
      best = SurfaceHit{several ? S.oMs * X_s : X_s, several ? S.oMs.R * n_s : n_s, static_cast<int>(i)};
    }
  }
  return best;
}

bool SurfaceModel::facingOutlines(const Surface& S, const Pose& cMo, const Intrinsics& cam,
                                  double min_facing_cos,
                                  std::vector<std::vector<Eigen::Vector2d>>* out) const {
  const Pose cMs = surfaces_.size() > 1 ? cMo * S.oMs : cMo;
  const Eigen::Vector3d o = cMs.inverse().t;  // camera centre, surface frame
  const auto project = [&](const Eigen::Vector3d& X_s, std::vector<Eigen::Vector2d>* px) {
    const Eigen::Vector3d Xc = cMs * X_s;
    if (!(Xc.z() > 1e-6)) return false;
    px->push_back(cam.project(Xc));
    return true;
  };
  if (S.cylinder) {
    const CylinderLabel& L = *S.cylinder;
    const double v_mid = (L.image_height - 1) / 2.0;
    for (const std::vector<Eigen::Vector2d>& strip : S.strips_px) {
      double u = 0;
      for (const Eigen::Vector2d& p : strip) u += p.x() / static_cast<double>(strip.size());
      if (!(facingCos(L.normal(u), L.point(Eigen::Vector2d(u, v_mid)), o) > min_facing_cos)) continue;
      std::vector<Eigen::Vector2d> px;
      for (const Eigen::Vector2d& p : strip)
        if (!project(L.point(p), &px)) return false;
      out->push_back(std::move(px));
    }
    return true;
  }
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& V : S.polygon_s) centre += V / static_cast<double>(S.polygon_s.size());
  if (!(facingCos(S.outer_sign * S.normal_s.normalized(), centre, o) > min_facing_cos)) return true;
  std::vector<Eigen::Vector2d> px;
  for (const Eigen::Vector3d& V : S.polygon_s)
    if (!project(V, &px)) return false;
  out->push_back(std::move(px));
  return true;
}

cv::Mat SurfaceModel::mask(const Pose& cMo, const Intrinsics& cam, double border_px,
                           double min_facing_cos) const {
  cv::Mat mask = cv::Mat::zeros(cam.height, cam.width, CV_8UC1);
  const int border = static_cast<int>(std::ceil(border_px));
  cv::Mat one;
  for (const Surface& S : surfaces_) {
    std::vector<std::vector<Eigen::Vector2d>> outlines;
    if (!facingOutlines(S, cMo, cam, min_facing_cos, &outlines) || outlines.empty()) continue;
    one = cv::Mat::zeros(mask.size(), CV_8UC1);
    for (const std::vector<Eigen::Vector2d>& poly : outlines) {
      std::vector<cv::Point> p;
      for (const Eigen::Vector2d& v : poly) p.emplace_back(cvRound(v.x()), cvRound(v.y()));
      cv::fillPoly(one, std::vector<std::vector<cv::Point>>{p}, cv::Scalar(255));
    }
    if (border > 0)
      cv::erode(one, one, cv::getStructuringElement(cv::MORPH_RECT, {2 * border + 1, 2 * border + 1}));
    mask |= one;
  }
  // Also keep off the image border (KLT windows there are truncated).
  if (border > 0) cv::rectangle(mask, cv::Rect(0, 0, mask.cols, mask.rows), cv::Scalar(0), border);
  return mask;
}

double SurfaceModel::visibleFraction(const Pose& cMo, const Intrinsics& cam) const {
  double area = 0, inside = 0;
  const Eigen::Vector2d lo(-0.5, -0.5), hi(cam.width - 0.5, cam.height - 0.5);
  for (const Surface& S : surfaces_) {
    std::vector<std::vector<Eigen::Vector2d>> outlines;
    if (!facingOutlines(S, cMo, cam, 0, &outlines)) return 0;
    for (const std::vector<Eigen::Vector2d>& px : outlines) {
      if (px.size() < 3) continue;
      area += std::abs(signedArea(px));
      const std::vector<Eigen::Vector2d> in = clipToBox(px, lo, hi);
      if (in.size() >= 3) inside += std::abs(signedArea(in));
    }
  }
  if (!(area > 1e-9)) return 0;
  return std::min(1.0, inside / area);
}

std::vector<std::array<Eigen::Vector3d, 4>> patternQuads(const detector::ObjectModel& object) {
  std::vector<std::array<Eigen::Vector3d, 4>> quads;
  if (object.isMultiView()) {
    for (const detector::ObjectView& v : object.views) {
      if (!v.model) continue;
      for (std::array<Eigen::Vector3d, 4> q : patternQuads(*v.model)) {
        for (Eigen::Vector3d& X : q) X = v.oMv * X;
        quads.push_back(q);
      }
    }
  } else if (object.target) {
    quads.push_back(object.target->corners_o);
  }
  return quads;
}

std::optional<std::array<Eigen::Vector3d, 4>> facingQuad(
    const std::vector<std::array<Eigen::Vector3d, 4>>& quads, const Pose& cMo) {
  if (quads.size() == 1) return quads[0];
  std::optional<std::array<Eigen::Vector3d, 4>> best;
  double best_cos = -std::numeric_limits<double>::infinity();
  const Eigen::Vector3d o = cMo.inverse().t;
  for (const std::array<Eigen::Vector3d, 4>& q : quads) {
    const Eigen::Vector3d into = (q[1] - q[0]).cross(q[3] - q[0]).normalized();
    const Eigen::Vector3d centre = 0.25 * (q[0] + q[1] + q[2] + q[3]);
    const double c = facingCos(-into, centre, o);
    if (c > best_cos) {
      best_cos = c;
      best = q;
    }
  }
  return best;
}

}  // namespace refgrasp::servo
