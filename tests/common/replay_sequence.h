#pragma once
// A rendered sequence with ground truth for the pose replay tests: the tea box (0.20 m wide,
// config/objects/tea_box.yaml) moves at 0.9 m in front of a cluttered backdrop, leaves the view
// on the right, comes back, passes behind an occluding panel (0.6 m from the camera) and
// reappears on its left. Each frame also says how much of the target is visible, computed from
// the geometry (not from the image), so that tests know where detection must succeed and where
// it must not. Deterministic (fixed seeds).
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "robot/camera.h"
#include "robot/sim/render.h"
#include "robot/sim/synthetic_scene.h"

namespace refgrasp::testing {

struct SequenceFrame {
  robot::MonoFrame frame;   ///< image, stamp, index and truth ("tea_box")
  double visible = 0;       ///< fraction of the target's area in the image and not occluded
};

inline constexpr double kSequenceFps = 15;

/// x / z of the target centre per frame (see the header comment).
inline std::vector<double> sequencePath() {
  std::vector<double> s;
  for (int k = 0; k < 6; ++k) s.push_back(0.22 + 0.045 * k);    // visible, moving right
  for (int k = 0; k < 6; ++k) s.push_back(0.5 + 0.1 * k);        // leaves the view
  for (int k = 0; k < 6; ++k) s.push_back(0.85 - 0.11 * k);      // comes back
  for (int k = 0; k < 10; ++k) s.push_back(0.2 - 0.0722 * k);    // behind the occluder
  for (int k = 0; k < 4; ++k) s.push_back(-0.44 - 0.005 * k);    // out on its left
  return s;
}

inline std::vector<SequenceFrame> renderOcclusionSequence() {
  const Intrinsics cam = sceneCamera();
  const cv::Mat target = loadMedia("targets/tea_box.png");
  const cv::Mat panel = loadMedia("clutter/clutter_03.png");
  const double w = 0.20, h = w * target.rows / target.cols, z = 0.9;
  const sim::TexturedPlane occluder{panel, 0.24, 0.55,
                                    Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(-0.06, 0, 0.6))};
  const std::vector<double> path = sequencePath();
  std::vector<SequenceFrame> out;
  for (size_t k = 0; k < path.size(); ++k) {
    const double a = 0.25 * std::sin(k / 5.0), b = 0.1 * std::cos(k / 7.0);
    const Pose cMo = Pose::fromRotationVector({b, a, 0.05 * std::sin(k / 3.0)},
                                              {path[k] * z, 0.02, z});
    const sim::TexturedPlane t{target, w, h, cMo};
    SceneSpec spec;
    spec.seed = 77;  // the same backdrop in every frame
    spec.noise_sigma = 0;
    RenderedScene sc = renderTargets(cam, {t, occluder}, spec);
    // Sensor noise, new in every frame (sigma 2 gray levels).
    cv::Mat noise(sc.image.size(), CV_16SC1);
    cv::RNG rng(1000 + k);
    rng.fill(noise, cv::RNG::NORMAL, 0, 2.0);
    cv::Mat img16;
    sc.image.convertTo(img16, CV_16SC1);
    cv::Mat noisy;
    cv::add(img16, noise, noisy);
    noisy.convertTo(sc.image, CV_8UC1);

    // Visible fraction: target polygon inside the image, minus the occluder's polygon.
    const auto poly = [](const std::array<Eigen::Vector2d, 4>& c) {
      std::vector<cv::Point> p;
      for (const auto& v : c) p.emplace_back(cvRound(v.x()), cvRound(v.y()));
      return p;
    };
    const std::vector<cv::Point> tp = poly(sim::projectPlaneCorners(cam, t));
    const std::vector<cv::Point> op = poly(sim::projectPlaneCorners(cam, occluder));
    cv::Mat tm = cv::Mat::zeros(cam.height, cam.width, CV_8UC1), om = tm.clone();
    cv::fillConvexPoly(tm, tp, 255);
    cv::fillConvexPoly(om, op, 255);
    const double area = cv::contourArea(tp);
    const double seen = cv::countNonZero(tm & ~om);

    SequenceFrame f;
    f.frame.image = sc.image;
    f.frame.stamp = k / kSequenceFps;
    f.frame.index = static_cast<int64_t>(k);
    f.frame.truth.push_back({"tea_box", cMo, std::nullopt});
    f.visible = area > 0 ? std::min(1.0, seen / area) : 0;
    out.push_back(f);
  }
  return out;
}

}  // namespace refgrasp::testing
