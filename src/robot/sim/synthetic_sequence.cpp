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

namespace {

cv::Mat renderEye(const Intrinsics& cam, const Pose& cMo, const cv::Mat& texture, double w,
                  double h, const cv::Mat& wall, double wall_behind_m, double blur_px,
                  double blur_angle, double noise, uint64_t seed) {
  const Pose oMwall(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, wall_behind_m));
  const sim::TexturedPlane target{texture, w, h, cMo};
  const sim::TexturedPlane backdrop{wall, 8.0, 6.0, cMo * oMwall};
  SceneSpec spec;
  spec.seed = seed;
  spec.noise_sigma = 0;
  spec.motion_blur_px = blur_px;
  spec.motion_blur_angle_rad = blur_angle;
  cv::Mat img = renderTargets(cam, {target, backdrop}, spec).image;
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
  s.camera = sceneCamera();
  s.rig.left = s.rig.right = s.camera;
  s.rig.lMr = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.12, 0, 0));
  const cv::Mat texture = loadMedia(spec.texture);
  const cv::Mat wall = loadMedia(spec.wall);
  const double w = spec.width_m, h = w * texture.rows / texture.cols;
  const auto path = spec.path ? spec.path : orbitPath;
  const int n = spec.frames;
  std::vector<Pose> oMc(static_cast<size_t>(n));
  for (int k = 0; k < n; ++k) oMc[static_cast<size_t>(k)] = viewPointPose(path(n > 1 ? double(k) / (n - 1) : 0));
  for (int k = 0; k < n; ++k) {
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
    const cv::Mat left = renderEye(s.camera, cMo, texture, w, h, wall, spec.wall_behind_m, blur,
                                   angle, spec.noise_sigma, seed);
    s.truth.push_back(cMo);
    if (stereo) {
      robot::StereoFrame f;
      f.left = left;
      const Pose rMo = s.rig.lMr.inverse() * cMo;
      f.right = renderEye(s.camera, rMo, texture, w, h, wall, spec.wall_behind_m, blur, angle,
                          spec.noise_sigma, seed + 7919);
      f.stamp = stamp;
      f.index = k;
      f.capture = capture;
      f.truth.push_back({"target", cMo, rMo});
      s.stereo.push_back(f);
    } else {
      robot::MonoFrame f;
      f.image = left;
      f.stamp = stamp;
      f.index = k;
      f.capture = capture;
      f.truth.push_back({"target", cMo, std::nullopt});
      s.mono.push_back(f);
    }
  }
  return s;
}

}  // namespace refgrasp::testing
