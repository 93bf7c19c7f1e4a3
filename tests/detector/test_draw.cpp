// drawAxes: x red, y green, z blue from the projected origin; nothing for a pose behind the camera.
#include <gtest/gtest.h>

#include "detector/draw.h"

using namespace refgrasp;

namespace {
// Only channel `ch` lit (anti-aliased lines are dimmer at their edges).
bool only(const cv::Vec3b& p, int ch) {
  for (int c = 0; c < 3; ++c)
    if ((c == ch) != (p[c] > 100) || (c != ch && p[c] != 0)) return false;
  return true;
}
}  // namespace

TEST(DrawAxes, ColoursAndDirectionsFollowTheProjection) {
  const Intrinsics cam = Intrinsics::pinhole(200, 200, 100, 99.5, 99.5);
  cv::Mat img(200, 200, CV_8UC3, cv::Scalar(0, 0, 0));
  const Pose cMo(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, 1));
  detector::drawAxes(img, cam, cMo, 0.5, 1);
  // Half-way along x (u = 99.5 + 25), along y (v = 99.5 + 25): pure red and pure green.
  EXPECT_TRUE(only(img.at<cv::Vec3b>(100, 125), 2)) << img.at<cv::Vec3b>(100, 125);
  EXPECT_TRUE(only(img.at<cv::Vec3b>(125, 100), 1)) << img.at<cv::Vec3b>(125, 100);
  EXPECT_EQ(img.at<cv::Vec3b>(150, 150), cv::Vec3b(0, 0, 0));
  // z seen end-on from the centre: a tilted pose makes it visible, in blue.
  cv::Mat tilted(200, 200, CV_8UC3, cv::Scalar(0, 0, 0));
  detector::drawAxes(tilted, cam, Pose::fromRotationVector({0.6, 0, 0}, {0, 0, 1}), 0.5, 1);
  int blue = 0;
  for (int r = 0; r < 200; ++r)
    for (int c = 0; c < 200; ++c) blue += only(tilted.at<cv::Vec3b>(r, c), 0);
  EXPECT_GT(blue, 10);
  cv::Mat behind(200, 200, CV_8UC3, cv::Scalar(0, 0, 0));
  detector::drawAxes(behind, cam, Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, -1)), 0.5);
  EXPECT_EQ(cv::countNonZero(behind.reshape(1)), 0);
}
