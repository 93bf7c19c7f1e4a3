#include "robot/sim/robot_view.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "robot/sim/synthetic_camera.h"

namespace refgrasp::sim {

namespace {

constexpr double kNoHit = std::numeric_limits<double>::infinity();

// A ray o + t rd (rd unit) against a part: the smallest t > near with its outward normal.
struct Hit {
  double t = kNoHit;
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
};

void sphereHit(const Eigen::Vector3d& o, const Eigen::Vector3d& rd, const Eigen::Vector3d& centre, double r,
               double near, Hit* best) {
  const Eigen::Vector3d oc = o - centre;
  const double b = rd.dot(oc), h = b * b - (oc.squaredNorm() - r * r);
  if (h < 0) return;
  const double t = -b - std::sqrt(h);
  if (t > near && t < best->t) *best = {t, (oc + t * rd) / r};
}

// The side of the cylinder of radius r about the segment a-b (between its end discs).
void sideHit(const Eigen::Vector3d& o, const Eigen::Vector3d& rd, const RobotPart& p, double near, Hit* best) {
  const Eigen::Vector3d ba = p.b - p.a, oa = o - p.a;
  const double baba = ba.squaredNorm(), bard = ba.dot(rd), baoa = ba.dot(oa);
  const double a = baba - bard * bard;  // baba sin^2 of the angle between the ray and the axis
  if (a < 1e-12 * baba) return;         // along the axis: only the ends can be hit
  const double b = baba * rd.dot(oa) - baoa * bard;
  const double c = baba * oa.squaredNorm() - baoa * baoa - p.radius_m * p.radius_m * baba;
  const double h = b * b - a * c;
  if (h < 0) return;
  const double t = (-b - std::sqrt(h)) / a;
  const double y = baoa + t * bard;  // position along the axis, times |ba|
  if (y < 0 || y > baba || !(t > near) || t >= best->t) return;
  *best = {t, (oa + t * rd - ba * (y / baba)) / p.radius_m};
}

void discHit(const Eigen::Vector3d& o, const Eigen::Vector3d& rd, const Eigen::Vector3d& centre,
             const Eigen::Vector3d& n, double r, double near, Hit* best) {
  const double den = rd.dot(n);
  if (den >= 0) return;  // seen from behind (the inside of the solid)
  const double t = (centre - o).dot(n) / den;
  if (!(t > near) || t >= best->t) return;
  if ((o + t * rd - centre).squaredNorm() <= r * r) *best = {t, n};
}

Hit intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& rd, const RobotPart& p, double near) {
  Hit h;
  sideHit(o, rd, p, near, &h);
  if (!p.flat_ends) {
    sphereHit(o, rd, p.a, p.radius_m, near, &h);
    sphereHit(o, rd, p.b, p.radius_m, near, &h);
  } else if ((p.b - p.a).squaredNorm() > 0) {
    const Eigen::Vector3d axis = (p.b - p.a).normalized();
    discHit(o, rd, p.a, -axis, p.radius_m, near, &h);
    discHit(o, rd, p.b, axis, p.radius_m, near, &h);
  }
  return h;
}

// Pixels that can show the part: its axis-aligned bounding box projected (the whole image when
// a corner is behind the near plane).
cv::Rect partBounds(const RobotPart& p, const Eigen::Matrix3d& K, const Pose& cMw, double near, cv::Size size) {
  const Eigen::Vector3d lo = p.a.cwiseMin(p.b).array() - p.radius_m, hi = p.a.cwiseMax(p.b).array() + p.radius_m;
  double minx = 1e30, miny = 1e30, maxx = -1e30, maxy = -1e30;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d Xw((i & 1) ? hi.x() : lo.x(), (i & 2) ? hi.y() : lo.y(), (i & 4) ? hi.z() : lo.z());
    const Eigen::Vector3d Xc = cMw * Xw;
    if (Xc.z() < near) return cv::Rect(cv::Point(0, 0), size);
    const Eigen::Vector3d q = K * Xc;
    minx = std::min(minx, q.x() / q.z());
    maxx = std::max(maxx, q.x() / q.z());
    miny = std::min(miny, q.y() / q.z());
    maxy = std::max(maxy, q.y() / q.z());
  }
  const auto clampi = [](double v, int lo_i, int hi_i) {
    return static_cast<int>(std::clamp(v, static_cast<double>(lo_i), static_cast<double>(hi_i)));
  };
  const cv::Point tl(clampi(std::floor(minx) - 1, 0, size.width), clampi(std::floor(miny) - 1, 0, size.height));
  const cv::Point br(clampi(std::ceil(maxx) + 2, 0, size.width), clampi(std::ceil(maxy) + 2, 0, size.height));
  return cv::Rect(tl, br);
}

}  // namespace

cv::Vec3b partColour(const std::string& name) {
  // BGR, chosen far apart in hue (the base and head neutral, the arm warm, the hand cool).
  if (name == "base") return {190, 160, 120};
  if (name == "neck") return {130, 130, 130};
  if (name == "head") return {80, 80, 80};
  if (name == "upper_arm") return {30, 120, 245};
  if (name == "forearm") return {40, 215, 250};
  if (name == "palm") return {60, 180, 60};
  if (name == "finger_x+") return {220, 80, 210};
  if (name == "finger_x-") return {240, 200, 60};
  return {160, 160, 160};
}

Eigen::Vector3d viewLight(const Pose& wMc) {
  return (-wMc.R.col(2) - 0.4 * wMc.R.col(0) + 0.8 * Eigen::Vector3d::UnitZ()).normalized();
}

cv::Vec3b lambert(const cv::Vec3b& bgr, const Eigen::Vector3d& n_w, const Eigen::Vector3d& light_w, double ambient) {
  const double k = ambient + (1 - ambient) * std::max(0.0, n_w.dot(light_w));
  cv::Vec3b out;
  for (int i = 0; i < 3; ++i) out[i] = cv::saturate_cast<uchar>(bgr[i] * k);
  return out;
}

std::vector<RobotPart> robotParts(const robot::EnonModel& model, const RobotShapes& shapes, const Pose& wMb,
                                  const Pose& wMc) {
  std::vector<RobotPart> parts;
  const Pose wMp = wMb * model.head.bMp;
  const VerticalCylinder& body = shapes.base;
  const double top = std::min(body.z0_m + body.height_m, wMp.t.z());
  parts.push_back({"base", Eigen::Vector3d(body.centre.x(), body.centre.y(), body.z0_m),
                   Eigen::Vector3d(body.centre.x(), body.centre.y(), top), body.radius_m, true, partColour("base")});
  parts.push_back({"neck", wMp.t, wMp * Eigen::Vector3d(0, 0, model.head.tilt_height_m), 0.05, false,
                   partColour("neck")});
  parts.push_back({"head", wMc.t, wMc * model.head.rig.lMr.t, 0.05, false, partColour("head")});
  for (const auto& [name, c] : shapes.capsules) parts.push_back({name, c.a, c.b, c.radius_m, false, partColour(name)});
  return parts;
}

void drawRobotParts(cv::Mat& bgr, cv::Mat& inv_depth, const Eigen::Matrix3d& K, const Pose& wMc,
                    const std::vector<RobotPart>& parts, const Eigen::Vector3d& light_w, double near_m) {
  refgrasp::check(bgr.type() == CV_8UC3 && inv_depth.type() == CV_32F && bgr.size() == inv_depth.size(),
                  "drawRobotParts", "needs a BGR image and a CV_32F depth buffer of its size");
  const Pose cMw = wMc.inverse();
  const Eigen::Matrix3d Kinv = K.inverse();
  const Eigen::Vector3d& o = wMc.t;
  for (const RobotPart& p : parts) {
    const cv::Rect roi = partBounds(p, K, cMw, near_m, bgr.size());
    for (int y = roi.y; y < roi.y + roi.height; ++y) {
      cv::Vec3b* d = bgr.ptr<cv::Vec3b>(y);
      float* zb = inv_depth.ptr<float>(y);
      for (int x = roi.x; x < roi.x + roi.width; ++x) {
        // The ray with camera z = 1 per unit of s; its unit direction rd, t = s |d|.
        const Eigen::Vector3d dw = wMc.R * (Kinv * Eigen::Vector3d(x, y, 1));
        const double len = dw.norm();
        const Eigen::Vector3d rd = dw / len;
        const Hit h = intersect(o, rd, p, near_m * len);
        if (!std::isfinite(h.t)) continue;
        const float iz = static_cast<float>(len / h.t);
        if (iz < zb[x]) continue;
        zb[x] = iz;
        d[x] = lambert(p.bgr, h.n, light_w);
      }
    }
  }
}

cv::Mat renderExternalView(const Intrinsics& cam, const World& world, const Pose& wMc,
                           const std::vector<RobotPart>& parts, const RenderOptions& opt) {
  cv::Mat inv_depth;
  const cv::Mat gray = renderViewWithDepth(cam, worldPlanes(world, wMc), worldCylinders(world, wMc),
                                           world.background, opt, &inv_depth);
  cv::Mat bgr;
  cv::cvtColor(gray, bgr, cv::COLOR_GRAY2BGR);
  drawRobotParts(bgr, inv_depth, cam.K(), wMc, parts, viewLight(wMc), opt.near_m);
  return bgr;
}

Pose lookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - eye).normalized();
  const Eigen::Vector3d side = z.cross(Eigen::Vector3d::UnitZ());
  refgrasp::check(side.norm() > 1e-9, "lookAt", "the view direction must not be vertical");
  const Eigen::Vector3d x = side.normalized();
  Eigen::Matrix3d R;
  R << x, z.cross(x), z;
  return Pose(R, eye);
}

void FollowCameraOptions::check() const {
  refgrasp::check(std::isfinite(behind_m) && std::isfinite(right_m) && std::isfinite(above_m) &&
                      std::isfinite(look_ahead_m) && std::isfinite(look_at_height_m) && above_m > look_at_height_m,
                  "FollowCameraOptions", "the eye must be finite and above the point looked at");
  refgrasp::check(std::isfinite(smoothing_s) && smoothing_s >= 0, "FollowCameraOptions.smoothing_s",
                  "must be >= 0");
  refgrasp::check(!camera.hasDistortion(), "FollowCameraOptions.camera", "must have no lens distortion");
  camera.check();
}

FollowCamera::FollowCamera(const FollowCameraOptions& o) : opt_(o) { opt_.check(); }

Pose FollowCamera::update(const robot::PlanarPose& base, Seconds t) {
  const Eigen::Vector2d xy(base.x_m, base.y_m);
  if (!started_) {
    started_ = true;
    xy_ = xy;
    theta_ = base.theta_rad;
  } else {
    const double dt = std::max(0.0, t - last_t_);
    const double alpha = opt_.smoothing_s > 0 ? 1 - std::exp(-dt / opt_.smoothing_s) : 1.0;
    xy_ += alpha * (xy - xy_);
    // The heading unwrapped: the camera turns the short way round.
    theta_ += alpha * std::remainder(base.theta_rad - theta_, 2 * M_PI);
  }
  last_t_ = t;
  const Eigen::Vector2d ahead(std::cos(theta_), std::sin(theta_)), left(-ahead.y(), ahead.x());
  const Eigen::Vector2d eye = xy_ - opt_.behind_m * ahead - opt_.right_m * left;
  const Eigen::Vector2d at = xy + opt_.look_ahead_m * Eigen::Vector2d(std::cos(base.theta_rad), std::sin(base.theta_rad));
  return lookAt(Eigen::Vector3d(eye.x(), eye.y(), opt_.above_m), Eigen::Vector3d(at.x(), at.y(), opt_.look_at_height_m));
}

}  // namespace refgrasp::sim
