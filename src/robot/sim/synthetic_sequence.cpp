#include "robot/sim/synthetic_sequence.h"

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "robot/sim/render.h"
#include "robot/sim/synthetic_scene.h"

namespace refgrasp::testing {

ViewPoint orbitPath(double t) {
  ViewPoint v;
  v.distance_m = 1.1 + 0.7 * std::cos(2 * M_PI * t);           // 1.8 -> 0.4 -> 1.8 m
  v.tilt_rad = (50 * M_PI / 180) * std::sin(3 * M_PI * t);      // swings to +-50 deg
  v.tilt_dir_rad = 0.6 * std::sin(2 * M_PI * t);
  v.roll_rad = (20 * M_PI / 180) * std::sin(2 * M_PI * 1.5 * t);
  // Off-centre framing, scaled with the distance so the target stays in the view.
  v.look_x_m = 0.12 * v.distance_m * std::sin(2 * M_PI * 2 * t);
  v.look_y_m = 0.06 * v.distance_m * std::cos(2 * M_PI * 1.3 * t);
  return v;
}

Pose viewPointPose(const ViewPoint& v) {
  const double st = std::sin(v.tilt_rad);
  const Eigen::Vector3d c = v.distance_m * Eigen::Vector3d(st * std::cos(v.tilt_dir_rad),
                                                           st * std::sin(v.tilt_dir_rad),
                                                           -std::cos(v.tilt_rad));
  const Eigen::Vector3d look(v.look_x_m, v.look_y_m, 0);
  const Eigen::Vector3d z = (look - c).normalized();
  const Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R << x, y, z;
  R = R * axisAngle(Eigen::Vector3d::UnitZ(), v.roll_rad);
  return Pose(R, c);
}

ViewPoint swayPath(double t, double cycles) {
  const double a = 2 * M_PI * cycles * t;
  ViewPoint v;
  v.distance_m = 0.75 + 0.2 * std::sin(a);
  v.tilt_rad = 0.35 * (0.5 + 0.5 * std::sin(0.5 * a));
  v.tilt_dir_rad = 0.3 * a;
  v.roll_rad = 0.25 * std::sin(0.7 * a);
  v.look_x_m = 0.04 * std::sin(1.3 * a);
  v.look_y_m = 0.03 * std::cos(0.9 * a);
  return v;
}

ViewPoint sidewaysView(double x_m, double y_m, double distance_m) {
  ViewPoint v;
  const double r = std::hypot(x_m, y_m);
  v.distance_m = std::hypot(r, distance_m);
  v.tilt_rad = std::atan2(r, distance_m);
  v.tilt_dir_rad = std::atan2(y_m, x_m);
  v.look_x_m = x_m;
  v.look_y_m = y_m;
  return v;
}

namespace {

struct Scene {
  const cv::Mat& texture;
  double w, h;
  const cv::Mat& wall;
  double wall_behind_m;
  const std::vector<sim::TexturedPlane>& occluders;
};

/// The planes seen from a camera at cMo: target (when shown), wall, occluders.
std::vector<sim::TexturedPlane> planesSeen(const Scene& sc, const Pose& cMo, bool target) {
  const Pose oMwall(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, sc.wall_behind_m));
  std::vector<sim::TexturedPlane> planes;
  if (target) planes.push_back({sc.texture, sc.w, sc.h, cMo});
  planes.push_back({sc.wall, 8.0, 6.0, cMo * oMwall});
  for (const sim::TexturedPlane& o : sc.occluders) planes.push_back({o.texture, o.width_m, o.height_m, cMo * o.cMp});
  return planes;
}

/// Fraction of the target's area inside the image and not behind an occluder (from geometry).
double visibleFraction(const Intrinsics& cam, const Scene& sc, const Pose& cMo) {
  const auto poly = [&](const sim::TexturedPlane& p, std::vector<cv::Point>* out) {
    for (int i = 0; i < 4; ++i) {
      const double x = (i == 1 || i == 2 ? 0.5 : -0.5) * p.width_m, y = (i >= 2 ? 0.5 : -0.5) * p.height_m;
      const Eigen::Vector3d Xc = p.cMp * Eigen::Vector3d(x, y, 0);
      if (!(Xc.z() > 1e-3)) return false;
      const Eigen::Vector2d px = cam.project(Xc);
      out->emplace_back(cvRound(px.x() * 4), cvRound(px.y() * 4));
    }
    return true;
  };
  // On a quarter-pixel grid of the image; the area is the whole polygon's, in or out of it.
  std::vector<cv::Point> tp;
  if (!poly({sc.texture, sc.w, sc.h, cMo}, &tp)) return 0;
  const double area = std::abs(cv::contourArea(tp));
  if (!(area > 0)) return 0;
  cv::Mat seen = cv::Mat::zeros(cam.height * 4, cam.width * 4, CV_8UC1);
  cv::fillConvexPoly(seen, tp, 255);
  for (const sim::TexturedPlane& o : sc.occluders) {
    std::vector<cv::Point> op;
    if (poly({o.texture, o.width_m, o.height_m, cMo * o.cMp}, &op)) cv::fillConvexPoly(seen, op, 0);
  }
  return std::min(1.0, cv::countNonZero(seen) / area);
}

cv::Mat renderEye(const Intrinsics& cam, const Scene& sc, const Pose& cMo, bool target, double blur_px,
                  double blur_angle, double noise, uint64_t seed) {
  SceneSpec spec;
  spec.seed = seed;
  spec.noise_sigma = 0;
  spec.motion_blur_px = blur_px;
  spec.motion_blur_angle_rad = blur_angle;
  cv::Mat img = renderTargets(cam, planesSeen(sc, cMo, target), spec).image;
  if (noise > 0) {
    cv::Mat n(img.size(), CV_16SC1), img16, noisy;
    cv::RNG rng(seed);
    rng.fill(n, cv::RNG::NORMAL, 0, noise);
    img.convertTo(img16, CV_16SC1);
    cv::add(img16, n, noisy);
    noisy.convertTo(img, CV_8UC1);
  }
  return img;
}

}  // namespace

TrackingSequence renderTrackingSequence(const TrackingSequenceSpec& spec, bool stereo) {
  TrackingSequence s;
  s.camera = spec.camera ? *spec.camera : sceneCamera();
  s.rig.left = s.rig.right = s.camera;
  s.rig.lMr = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.12, 0, 0));
  const cv::Mat texture = loadMedia(spec.texture);
  const cv::Mat wall = loadMedia(spec.wall);
  const double w = spec.width_m, h = w * texture.rows / texture.cols;
  const Scene scene{texture, w, h, wall, spec.wall_behind_m, spec.occluders};
  const auto path = spec.path ? spec.path : orbitPath;
  const int n = spec.frames;
  std::vector<Pose> oMc(static_cast<size_t>(n));
  for (int k = 0; k < n; ++k) oMc[static_cast<size_t>(k)] = viewPointPose(path(n > 1 ? double(k) / (n - 1) : 0));
  const int rendered = spec.render_frames < 0 ? n : std::min(n, spec.render_frames);
  for (int k = 0; k < rendered; ++k) {
    const Pose cMo = oMc[static_cast<size_t>(k)].inverse();
    // Blur along the image motion of the target centre around this frame.
    const Pose& a = oMc[static_cast<size_t>(std::max(0, k - 1))];
    const Pose& b = oMc[static_cast<size_t>(std::min(n - 1, k + 1))];
    const Eigen::Vector2d d = (s.camera.project(b.inverse() * Eigen::Vector3d::Zero()) -
                               s.camera.project(a.inverse() * Eigen::Vector3d::Zero())) /
                              (k > 0 && k < n - 1 ? 2.0 : 1.0);
    const double blur = spec.exposure_fraction * d.norm();
    const double angle = std::atan2(d.y(), d.x());
    const uint64_t seed = spec.seed * 100003 + static_cast<uint64_t>(k);
    robot::CaptureState capture;
    if (spec.capture_state) capture.bMc = oMc[static_cast<size_t>(k)];
    const double stamp = k / spec.fps;
    const bool shown = !spec.target_shown || spec.target_shown(k);
    const cv::Mat left = renderEye(s.camera, scene, cMo, shown, blur, angle, spec.noise_sigma, seed);
    s.truth.push_back(cMo);
    s.visible.push_back(shown ? visibleFraction(s.camera, scene, cMo) : 0);
    if (stereo) {
      robot::StereoFrame f;
      f.left = left;
      const Pose rMo = s.rig.lMr.inverse() * cMo;
      f.right = renderEye(s.camera, scene, rMo, shown, blur, angle, spec.noise_sigma, seed + 7919);
      f.stamp = stamp;
      f.index = k;
      f.capture = capture;
      if (shown) f.truth.push_back({"target", cMo, rMo});
      s.stereo.push_back(f);
    } else {
      robot::MonoFrame f;
      f.image = left;
      f.stamp = stamp;
      f.index = k;
      f.capture = capture;
      if (shown) f.truth.push_back({"target", cMo, std::nullopt});
      s.mono.push_back(f);
    }
  }
  return s;
}

}  // namespace refgrasp::testing
