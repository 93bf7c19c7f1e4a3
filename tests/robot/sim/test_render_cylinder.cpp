// The renderer's cylinders: ground truth by construction (label points projected at a known
// pose, the silhouette's closed-form width, the depth test against a plane).
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>

#include "core/cylinder.h"
#include "robot/sim/render.h"

namespace refgrasp::sim {
namespace {

// A smooth random label: noise blurred with sigma 4 px, so that sampling a pyramid level
// or the level below changes a value by a grey level or two at most.
cv::Mat smoothLabel(int W, int H, uint64_t seed) {
  cv::Mat noise(H, W, CV_32F);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 4, 4, cv::BORDER_REFLECT);
  cv::normalize(noise, noise, 30, 230, cv::NORM_MINMAX);
  cv::Mat out;
  noise.convertTo(out, CV_8U);
  return out;
}

TexturedCylinder can(const cv::Mat& label, const Pose& cMo) {
  TexturedCylinder c;
  c.label = label;
  c.radius_m = 0.04;
  c.label_width_m = 2 * M_PI * 0.04;
  c.label_height_m = 0.1;
  c.height_m = 0.14;
  c.cMo = cMo;
  return c;
}

TEST(RenderCylinder, LabelPointsLandWhereThePoseProjectsThem) {
  const cv::Mat label = smoothLabel(640, 200, 3);
  const Intrinsics cam = Intrinsics::pinhole(640, 480, 600, 319.5, 239.5);
  // Turned 30 deg about its axis and tilted 15 deg towards the camera, 0.45 m away.
  const Pose cMo = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.02, -0.01, 0.45)) *
                   Pose::fromRotationVector(Eigen::Vector3d(0.26, 0, 0), Eigen::Vector3d::Zero()) *
                   Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, 0.04)) *
                   Pose::fromRotationVector(Eigen::Vector3d(0, 0.52, 0), Eigen::Vector3d::Zero()) *
                   Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, -0.04));
  const cv::Mat img = renderView(cam, {}, {can(label, cMo)}, cv::Mat(), {});
  const CylinderLabel geom{0.04, 2 * M_PI * 0.04, 0.1, 640, 200};
  double sum = 0;
  int n = 0;
  for (int v = 10; v < 190; v += 7)
    for (int u = 0; u < 640; u += 5) {
      if (!geom.facesCamera(u, v, cMo, 0.5)) continue;  // well inside the visible half
      const Eigen::Vector2d p = cam.project(cMo * geom.point({u, v}));
      const int x = static_cast<int>(std::lround(p.x())), y = static_cast<int>(std::lround(p.y()));
      if (std::abs(p.x() - x) > 0.25 || std::abs(p.y() - y) > 0.25) continue;  // near a pixel centre
      sum += std::abs(img.at<uchar>(y, x) - label.at<uchar>(v, u));
      ++n;
    }
  ASSERT_GT(n, 100);
  EXPECT_LT(sum / n, 3.0) << "mean |rendered - label| over " << n << " points";
}

TEST(RenderCylinder, SilhouetteHasTheClosedFormWidth) {
  const cv::Mat white(100, 400, CV_8U, cv::Scalar(255));
  const Intrinsics cam = Intrinsics::pinhole(640, 480, 600, 319.5, 239.5);
  RenderOptions opt;
  opt.background_gray = 0;
  for (const double z : {0.3, 0.6, 1.2}) {
    // Axis straight ahead at distance D = z + r: the limbs are asin(r / D) off the optical axis.
    const Pose cMo(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, z));
    TexturedCylinder c = can(white, cMo);
    c.side_gray = 255;
    const cv::Mat img = renderView(cam, {}, {c}, cv::Mat(), opt);
    const double width = cv::sum(img.row(240))[0] / 255.0;
    const double expected = 2 * 600 * std::tan(std::asin(0.04 / (z + 0.04)));
    EXPECT_NEAR(width, expected, 0.3) << "z " << z;
  }
}

TEST(RenderCylinder, APlaneInFrontHidesItAndOneBehindDoesNot) {
  const cv::Mat white(100, 400, CV_8U, cv::Scalar(255));
  const cv::Mat black(64, 64, CV_8U, cv::Scalar(0));
  const Intrinsics cam = Intrinsics::pinhole(640, 480, 600, 319.5, 239.5);
  TexturedCylinder c = can(white, Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, 0.6)));
  c.side_gray = 255;
  const TexturedPlane front{black, 0.02, 0.02, Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, 0.5))};
  const TexturedPlane behind{black, 0.5, 0.5, Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, 0.8))};
  const cv::Mat img = renderView(cam, {front, behind}, {c}, cv::Mat(), {});
  EXPECT_EQ(img.at<uchar>(240, 320), 0);    // the small plane in front
  EXPECT_EQ(img.at<uchar>(240, 340), 255);  // the cylinder, beside it, over the plane behind
  EXPECT_EQ(img.at<uchar>(240, 420), 0);    // the plane behind, beside the cylinder
}

}  // namespace
}  // namespace refgrasp::sim
