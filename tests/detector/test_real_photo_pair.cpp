// The detector on a real photograph pair (OpenCV's sample box.png / box_in_scene.png, shipped as
// media/photos/cookie_box*.png, media/README.md): the box face as the reference, the scene
// photographed by another camera, rotated, tilted and half hidden behind another packet. Ground
// truth measured by hand on 16x enlargements of both photos (continuous pixel coordinates, the
// centre of the top-left pixel at (0, 0), reading error about 0.7 px): three landmarks that can be
// seen in the scene (its right half is hidden).
#include <gtest/gtest.h>

#include <cstdio>

#include "common/format.h"
#include "detector/detector.h"
#include "detector/homography.h"
#include "detector/object.h"
#include "robot/sim/synthetic_scene.h"

using namespace refgrasp;

TEST(RealPhotoPair, TheCookieBoxIsFoundWhereItIsMeasuredByHand) {
  const cv::Mat ref = refgrasp::testing::loadMedia("photos/cookie_box.png");
  const cv::Mat scene = refgrasp::testing::loadMedia("photos/cookie_box_in_scene.png");
  ASSERT_EQ(ref.size(), cv::Size(324, 223));
  ASSERT_EQ(scene.size(), cv::Size(512, 384));
  struct Landmark {
    const char* what;
    Eigen::Vector2d ref_px, scene_px;
  };
  const Landmark marks[] = {
      {"box face, top-left corner", {-0.5, -0.5}, {117.5, 161.5}},
      {"photo window, top-left corner", {140.2, 18.7}, {184.6, 176.4}},
      {"photo window, bottom-left corner", {138.6, 202.5}, {165.0, 271.5}},
  };
  for (const char* matcher : {"paper", "ratio"}) {
    detector::DetectorOptions opt;
    opt.match.matcher = std::string(matcher) == "paper" ? detector::MatcherType::kPaper : detector::MatcherType::kRatio;
    detector::Detector det(opt);
    det.addObject(detector::textureObject("cookie_box", ref, 0.20));
    const Intrinsics cam = Intrinsics::pinhole(scene.cols, scene.rows, 500, 255.5, 191.5);
    const auto d = det.detect(scene, cam).find(0);
    ASSERT_TRUE(d.has_value()) << matcher;
    double worst = 0;
    std::string landmarks;  // each landmark's distance, for the message of a failure
    for (const Landmark& m : marks) {
      const double e = (detector::applyHomography(d->H, m.ref_px) - m.scene_px).norm();
      landmarks += refgrasp::testing::formatted("\n  %s %.2f px from the hand measurement", m.what, e);
      worst = std::max(worst, e);
    }
    EXPECT_LT(worst, 2.5) << matcher << " matcher, " << d->inliers << " inliers:" << landmarks;
  }
}

// The same pair with the box face registered 2D-only (no reference pose: H and corners only, the
// use of a photo nobody measured): its corners come from the dense alignment of the whole face,
// not from a few keypoints, and land as close to the hand measurements.
TEST(RealPhotoPair, TheCookieBoxRegistered2DOnlyIsFoundWhereItIsMeasuredByHand) {
  const cv::Mat ref = refgrasp::testing::loadMedia("photos/cookie_box.png");
  const cv::Mat scene = refgrasp::testing::loadMedia("photos/cookie_box_in_scene.png");
  const Eigen::Vector2d marks[][2] = {{{-0.5, -0.5}, {117.5, 161.5}}, {{140.2, 18.7}, {184.6, 176.4}},
                                      {{138.6, 202.5}, {165.0, 271.5}}};
  detector::Detector det;
  det.addObject(detector::makeObjectModel("cookie_box", ref, std::nullopt, std::nullopt));
  ASSERT_FALSE(det.object(0).has3d());
  const Intrinsics cam = Intrinsics::pinhole(scene.cols, scene.rows, 500, 255.5, 191.5);
  const auto d = det.detect(scene, cam).find(0);
  ASSERT_TRUE(d.has_value());
  EXPECT_FALSE(d->cMo.has_value());
  double worst = 0;
  for (const auto& m : marks) worst = std::max(worst, (detector::applyHomography(d->H, m[0]) - m[1]).norm());
  std::printf("2D-only: %d inliers, worst landmark %.2f px\n", d->inliers, worst);
  EXPECT_LT(worst, 2.5);
}
