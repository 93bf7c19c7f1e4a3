// Synthetic stereo camera: disparity, ground-truth poses, motion blur from velocity, determinism.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "robot/sim/synthetic_scene.h"
#include "robot/sim/synthetic_camera.h"

namespace refgrasp::sim {
namespace {

const std::string kScenarios = std::string(REFGRASP_SOURCE_DIR) + "/config/scenarios/";

StereoRig idealRig(double baseline) {
  StereoRig rig;
  rig.left = rig.right = Intrinsics::pinhole(640, 480, 500, 319.5, 239.5);
  rig.lMr = Pose(Eigen::Matrix3d::Identity(), {baseline, 0, 0});
  return rig;
}

// A world with one large textured wall facing the camera at depth z (camera at the world origin
// looking along world z).
World wallAt(double z) {
  World w;
  SimObject wall;
  wall.name = "wall";
  wall.wMo = Pose(Eigen::Matrix3d::Identity(), {0, 0, z});
  wall.faces.push_back({testing::loadMedia("targets/book_cover.png"), 1.6 * z, 1.2 * z, Pose()});
  w.objects.push_back(wall);
  return w;
}

// Horizontal shift of `b` relative to `a` over a central window, by phase correlation.
double horizontalShift(const cv::Mat& a, const cv::Mat& b) {
  const cv::Rect win(160, 120, 320, 240);
  cv::Mat fa, fb;
  a(win).convertTo(fa, CV_64F);
  b(win).convertTo(fb, CV_64F);
  cv::Mat hann;
  cv::createHanningWindow(hann, win.size(), CV_64F);
  return cv::phaseCorrelate(fa, fb, hann).x;
}

TEST(SyntheticCamera, DisparityOfAFrontoParallelPlaneIsFBaselineOverDepth) {
  const StereoRig rig = idealRig(0.12);
  SyntheticStereoCamera cam(rig, Degradation{}, 1);
  for (const double z : {1.5, 2.5, 4.0}) {
    const SyntheticFrame f = cam.render(wallAt(z), Pose(), Twist(), 0);
    const double expected = 500 * 0.12 / z;  // the right eye sees the plane shifted left
    const double measured = -horizontalShift(f.left, f.right);
    EXPECT_NEAR(measured, expected, 0.1) << "disparity at depth " << z << " m, px";
  }
}

TEST(SyntheticCamera, GroundTruthPosesMatchTheRenderedTarget) {
  const StereoRig rig = idealRig(0.12);
  Scenario s = loadScenario(kScenarios + "table_clutter.yaml");
  SyntheticStereoCamera cam(rig, Degradation{}, 3);
  Eigen::Matrix3d optical;
  optical << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  const Pose wMl(optical * axisAngle(Eigen::Vector3d::UnitX(), -0.3), {0.6, 0.0, 1.2});
  const SyntheticFrame f = cam.render(s.world, wMl, Twist(), 0.5);
  ASSERT_EQ(f.left_cMo.size(), s.world.objects.size());
  EXPECT_DOUBLE_EQ(f.stamp, 0.5);
  for (size_t i = 0; i < s.world.objects.size(); ++i) {
    const Pose expect_l = wMl.inverse() * s.world.objects[i].wMo;
    EXPECT_LT((f.left_cMo[i].matrix() - expect_l.matrix()).norm(), 1e-12);
    EXPECT_LT((f.right_cMo[i].matrix() - (rig.lMr.inverse() * expect_l).matrix()).norm(), 1e-12);
  }
  // Warp each eye back into the target's texture with the ground-truth pose: it must be the texture.
  const SimObject& target = s.world.objects[0];
  ASSERT_TRUE(target.is_target);
  const TexturedPlane& front = target.faces[4];  // -z face: the front
  for (const auto& [img, cMo, intr] : {std::make_tuple(f.left, f.left_cMo[0], rig.left),
                                       std::make_tuple(f.right, f.right_cMo[0], rig.right)}) {
    const TexturedPlane seen{front.texture, front.width_m, front.height_m, cMo * front.cMp};
    const Eigen::Matrix3d H = textureToImage(intr, seen);
    cv::Mat Hcv(3, 3, CV_64F);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) Hcv.at<double>(r, c) = H(r, c);
    cv::Mat back, tex_small;
    cv::warpPerspective(img, back, Hcv, front.texture.size(), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP);
    // The target covers ~70 px: compare at that resolution, away from the outline.
    const cv::Size small(64, 64);
    cv::resize(back, back, small, 0, 0, cv::INTER_AREA);
    cv::resize(front.texture, tex_small, small, 0, 0, cv::INTER_AREA);
    const cv::Rect inner(4, 4, 56, 56);
    cv::Mat ncc;
    cv::matchTemplate(back(inner), tex_small(inner), ncc, cv::TM_CCOEFF_NORMED);
    EXPECT_GT(ncc.at<float>(0, 0), 0.9) << "NCC of the target re-projected through the ground truth, "
                                        << (img.data == f.left.data ? "left" : "right") << " eye";
  }
}

// Rotating about the camera y axis at w rad/s during an exposure T smears the image by f w T px
// horizontally: the same image as a static render blurred by that kernel.
TEST(SyntheticCamera, MotionBlurFollowsTheCameraVelocity) {
  const StereoRig rig = idealRig(0.12);
  const World world = wallAt(2.0);
  const double exposure = 0.01;
  for (const auto& [twist, blur_px] : {std::make_pair(Twist{{0, 0, 0}, {0, 1.2, 0}}, 500 * 1.2 * 0.01),
                                       std::make_pair(Twist{{0.6, 0, 0}, {0, 0, 0}}, 500 * 0.6 / 2.0 * 0.01)}) {
    SyntheticStereoCamera moving(rig, Degradation{}, 4, exposure);
    const SyntheticFrame f = moving.render(world, Pose(), twist, 0);
    SyntheticStereoCamera still(rig, Degradation{}, 4, exposure);
    const SyntheticFrame g = still.render(world, Pose(), Twist(), 0);
    cv::Mat expected = g.left.clone();
    std::mt19937_64 rng(0);
    Degradation d;
    d.motion_blur_px = blur_px;
    degrade(expected, d, rng);
    EXPECT_EQ(cv::norm(f.left, expected, cv::NORM_INF), 0) << "blur " << blur_px;
    EXPECT_GT(cv::norm(f.left, g.left, cv::NORM_L1) / f.left.total(), 0.5);  // visibly blurred
  }
}

TEST(SyntheticCamera, SameSeedSameImagesBitForBit) {
  const Scenario s = loadScenario(kScenarios + "table_clutter.yaml");
  const StereoRig rig = loadStereoRig(std::string(REFGRASP_SOURCE_DIR) + "/config/cameras/bb2_rig.yaml");
  Eigen::Matrix3d optical;
  optical << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  const auto run = [&](uint64_t seed) {
    SyntheticStereoCamera cam(rig, s.camera, seed, s.exposure_s);
    std::vector<SyntheticFrame> frames;
    for (int k = 0; k < 3; ++k) {
      const Pose wMl(axisAngle(Eigen::Vector3d::UnitZ(), 0.05 * k) * optical, {0.1 * k, 0, 1.2});
      frames.push_back(cam.render(s.world, wMl, Twist{{0.2, 0, 0}, {0, 0.3, 0}}, 0.1 * k));
    }
    return frames;
  };
  const auto a = run(11), b = run(11), c = run(12);
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(cv::norm(a[k].left, b[k].left, cv::NORM_INF), 0);
    EXPECT_EQ(cv::norm(a[k].right, b[k].right, cv::NORM_INF), 0);
    EXPECT_GT(cv::norm(a[k].left, c[k].left, cv::NORM_INF), 0);  // other noise
  }
  EXPECT_GT(cv::norm(a[0].left, a[1].left, cv::NORM_INF), 0);  // the rng moves on between frames
}

TEST(SyntheticCamera, MeasuredNoiseMatchesTheScenario) {
  const StereoRig rig = idealRig(0.12);
  World flat;
  flat.background = cv::Mat(480, 640, CV_8U, cv::Scalar(100));
  Degradation d;
  d.noise_sigma = 4;
  SyntheticStereoCamera cam(rig, d, 5);
  const SyntheticFrame f = cam.render(flat, Pose(), Twist(), 0);
  for (const cv::Mat& img : {f.left, f.right}) {
    cv::Scalar mean, sd;
    cv::meanStdDev(img, mean, sd);
    EXPECT_NEAR(sd[0], std::sqrt(16 + 1.0 / 12), 0.08);
    EXPECT_NEAR(mean[0], 100, 0.05);
  }
  EXPECT_GT(cv::norm(f.left, f.right, cv::NORM_INF), 0);  // independent noise per eye
}

TEST(SyntheticCamera, BadWorldThrowsOnTheCallersThread) {
  World bad = wallAt(2.0);
  bad.objects[0].faces[0].texture = cv::Mat();  // empty texture: std::invalid_argument from either eye
  SyntheticStereoCamera cam(idealRig(0.12), Degradation{}, 1);
  EXPECT_THROW(cam.render(bad, Pose(), Twist(), 0), std::invalid_argument);
  Degradation nonsense;
  nonsense.noise_sigma = -1;
  EXPECT_THROW(SyntheticStereoCamera(idealRig(0.12), nonsense, 1), std::invalid_argument);
}

}  // namespace
}  // namespace refgrasp::sim
