#include "detector/draw.h"

#include <opencv2/imgproc.hpp>

namespace refgrasp::detector {

void drawAxes(cv::Mat& img, const Intrinsics& cam, const Pose& cMo, double len, int thickness) {
  const auto px = [&](const Eigen::Vector3d& Xo) {
    const Eigen::Vector2d p = cam.project(cMo * Xo);
    return cv::Point(cvRound(p.x()), cvRound(p.y()));
  };
  if (cMo.t.z() <= 1e-6) return;
  const cv::Point o = px(Eigen::Vector3d::Zero());
  const Eigen::Vector3d axes[3] = {{len, 0, 0}, {0, len, 0}, {0, 0, len}};
  const cv::Scalar colours[3] = {{0, 0, 255}, {0, 255, 0}, {255, 0, 0}};  // x red, y green, z blue
  for (int a = 0; a < 3; ++a)
    if ((cMo * axes[a]).z() > 1e-6) cv::line(img, o, px(axes[a]), colours[a], thickness, cv::LINE_AA);
}

}  // namespace refgrasp::detector
