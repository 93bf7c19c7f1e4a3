#include "eval/cylinder_eval.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/cylinder.h"
#include "robot/sim/degrade.h"
#include "robot/sim/realistic_scene.h"
#include "robot/sim/synthetic_scene.h"

namespace refgrasp::eval {

namespace {

constexpr double kPi = 3.14159265358979323846;

CylinderLabel geometry(const LabelledCylinder& c) {
  return {c.radius_m, c.label_width_m, c.label_height_m, c.label.cols, c.label.rows};
}

Pose translation(const Eigen::Vector3d& t) { return Pose(Eigen::Matrix3d::Identity(), t); }

}  // namespace

detector::ObjectModel LabelledCylinder::object() const {
  return detector::cylinderObject(name, label, radius_m, label_width_m, label_height_m);
}

sim::TexturedCylinder LabelledCylinder::body(const Pose& cMo) const {
  sim::TexturedCylinder b;
  b.label = label;
  b.radius_m = radius_m;
  b.label_width_m = label_width_m;
  b.label_height_m = label_height_m;
  b.height_m = height_m;
  b.cMo = cMo;
  return b;
}

LabelledCylinder labelledCylinder(const std::string& photo, double radius_m, double label_height_m,
                                  double wrap_fraction, int rows) {
  LabelledCylinder c;
  c.photo = photo;
  c.name = photo.substr(photo.find_last_of('/') + 1);
  c.name = c.name.substr(0, c.name.find('.'));
  c.radius_m = radius_m;
  c.label_width_m = wrap_fraction * 2 * kPi * radius_m;
  c.label_height_m = label_height_m;
  c.height_m = 1.25 * label_height_m;
  const cv::Mat img = testing::loadMedia(photo);
  const double aspect = c.label_width_m / c.label_height_m;
  const int cols = static_cast<int>(std::lround(rows * aspect));
  // The largest centred crop of the label's aspect.
  int cw = img.cols, ch = static_cast<int>(std::lround(img.cols / aspect));
  if (ch > img.rows) {
    ch = img.rows;
    cw = static_cast<int>(std::lround(img.rows * aspect));
  }
  const cv::Rect crop((img.cols - cw) / 2, (img.rows - ch) / 2, cw, ch);
  cv::resize(img(crop), c.label, cv::Size(cols, rows), 0, 0, cv::INTER_AREA);
  return c;
}

Pose cylinderPose(const Intrinsics& cam, const LabelledCylinder& c, const CylinderViewSpec& s) {
  const Eigen::Vector3d dir =
      Eigen::Vector3d(s.offset.x() * (cam.width / 2.0) / cam.fx, s.offset.y() * (cam.height / 2.0) / cam.fy, 1)
          .normalized();
  const Eigen::Matrix3d R = axisAngle(Eigen::Vector3d::UnitZ(), s.roll_rad) *
                            axisAngle(Eigen::Vector3d::UnitX(), s.tilt_rad) *
                            axisAngle(Eigen::Vector3d::UnitY(), s.turn_rad);
  // The axis' middle at the given distance along dir; the label's centre a radius in front of it.
  return translation(s.distance_m * dir) * Pose(R, Eigen::Vector3d::Zero()) *
         translation(Eigen::Vector3d(0, 0, -c.radius_m));
}

bool CylinderView::counted() const { return visible_width_px >= 40 && centre_angle_rad <= 60 * kPi / 180; }

CylinderView renderCylinderView(const Intrinsics& cam, const LabelledCylinder* c, const CylinderViewSpec& spec,
                                const std::vector<sim::TexturedCylinder>& others) {
  CylinderView v;
  cv::Mat backdrop;
  if (spec.backdrop.empty()) {
    std::vector<std::string> exclude = spec.exclude_from_backdrop;
    if (c) exclude.push_back(c->photo);
    backdrop = testing::photoClutterBackground(spec.seed, cam.width, cam.height, exclude);
  } else {
    cv::resize(testing::loadMedia(spec.backdrop), backdrop, cv::Size(cam.width, cam.height), 0, 0, cv::INTER_AREA);
  }
  std::vector<sim::TexturedCylinder> bodies = others;
  if (c) {
    v.cMo = cylinderPose(cam, *c, spec);
    bodies.push_back(c->body(v.cMo));
    // The visible part's width on the label's middle row, and how its centre column faces.
    const CylinderLabel g = geometry(*c);
    const double v_mid = (g.image_height - 1) / 2.0;
    std::vector<Eigen::Vector2d> row;
    for (double u = 0; u < g.image_width; u += 0.5)
      if (g.facesCamera(u, v_mid, v.cMo, 0)) row.push_back(cam.project(v.cMo * g.point({u, v_mid})));
    for (const auto& a : row)
      for (const auto& b : {row.front(), row.back()}) v.visible_width_px = std::max(v.visible_width_px, (a - b).norm());
    if (!g.fullWrap()) {
      const double uc = (g.image_width - 1) / 2.0;
      const Eigen::Vector3d X = g.point({uc, v_mid});
      const Eigen::Vector3d ray = (v.cMo.inverse().t - X).normalized();
      v.centre_angle_rad = std::acos(std::clamp(g.normal(uc).dot(ray), -1.0, 1.0));
    }
  }
  v.image = sim::renderView(cam, {}, bodies, backdrop);
  std::mt19937_64 rng(spec.seed * 7919 + 17);
  sim::Degradation d;
  d.noise_sigma = spec.noise_sigma;
  d.motion_blur_px = spec.motion_blur_px;
  d.motion_blur_angle_rad = std::uniform_real_distribution<double>(0, kPi)(rng);
  sim::degrade(v.image, d, rng);
  if (spec.jpeg_quality > 0) {
    std::vector<uchar> buf;
    cv::imencode(".jpg", v.image, buf, {cv::IMWRITE_JPEG_QUALITY, spec.jpeg_quality});
    v.image = cv::imdecode(buf, cv::IMREAD_GRAYSCALE);
  }
  return v;
}

std::vector<CylinderViewSpec> randomCylinderViews(std::mt19937_64& rng, int n, double min_distance_m,
                                                  double max_distance_m, double max_turn_rad, double max_tilt_rad) {
  auto uni = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  std::vector<CylinderViewSpec> out;
  for (int i = 0; i < n; ++i) {
    CylinderViewSpec s;
    s.distance_m = uni(min_distance_m, max_distance_m);
    s.turn_rad = uni(-max_turn_rad, max_turn_rad);
    s.tilt_rad = uni(-max_tilt_rad, max_tilt_rad);
    s.roll_rad = uni(-0.3, 0.3);
    // Near the camera the can fills the frame: kept nearer the middle.
    const double reach = 0.5 * std::clamp((s.distance_m - 0.25) / 0.5, 0.0, 1.0);
    s.offset = Eigen::Vector2d(uni(-reach, reach), uni(-reach, reach));
    s.noise_sigma = uni(1, 3);
    s.motion_blur_px = uni(0, 2);
    s.jpeg_quality = uni(0, 1) < 0.5 ? static_cast<int>(uni(60, 95)) : 0;
    s.seed = rng();
    out.push_back(s);
  }
  return out;
}

CylinderPoseError cylinderPoseError(const std::optional<Pose>& cMo, const Pose& truth) {
  CylinderPoseError e;
  if (!cMo || !cMo->isFinite()) return e;
  e.found = true;
  e.rotation_deg = rotationError(*cMo, truth) * 180 / kPi;
  e.translation_fraction = translationError(*cMo, truth) / truth.t.norm();
  return e;
}

CylinderPoseError cylinderPoseError(const std::optional<detector::Detection>& d, const Pose& truth) {
  if (!d || !d->found) return {};
  return cylinderPoseError(d->cMo, truth);
}

}  // namespace refgrasp::eval
