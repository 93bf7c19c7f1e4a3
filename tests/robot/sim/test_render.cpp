// Renderer and degradations: ground truth by construction (checkerboard corners, ray casting).
#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "robot/sim/synthetic_scene.h"
#include "robot/sim/degrade.h"
#include "robot/sim/render.h"

namespace refgrasp::sim {
namespace {

constexpr int kSquare = 32, kCols = 10, kRows = 8, kBorder = 32;

// Checkerboard with a white margin; inner corners sit on texture pixel edges.
cv::Mat checkerboard() {
  cv::Mat img(kRows * kSquare + 2 * kBorder, kCols * kSquare + 2 * kBorder, CV_8U, cv::Scalar(255));
  for (int r = 0; r < kRows; ++r)
    for (int c = 0; c < kCols; ++c)
      if ((r + c) % 2 == 0)
        img(cv::Rect(kBorder + c * kSquare, kBorder + r * kSquare, kSquare, kSquare)).setTo(0);
  return img;
}

// Max distance (px) between detected inner corners and their true projections; -1 if not found.
double checkerboardError(const Intrinsics& cam, const Pose& cMp, double width_m, int* found_count) {
  const cv::Mat tex = checkerboard();
  const TexturedPlane plane{tex, width_m, width_m * tex.rows / tex.cols, cMp};
  const cv::Mat img = renderView(cam, {plane}, cv::Mat());
  std::vector<cv::Point2f> corners;
  const cv::Size pattern(kCols - 1, kRows - 1);
  *found_count = 0;
  if (!cv::findChessboardCorners(img, pattern, corners, cv::CALIB_CB_ADAPTIVE_THRESH)) return -1;
  cv::cornerSubPix(img, corners, cv::Size(5, 5), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-3));
  *found_count = static_cast<int>(corners.size());
  const double s = width_m / tex.cols;  // metres per texture pixel
  double worst = 0;
  for (const auto& c : corners) {
    double best = 1e9;
    for (int r = 1; r < kRows; ++r)
      for (int k = 1; k < kCols; ++k) {
        // Pixel edge e sits at (e - W/2) * s in the plane.
        const Eigen::Vector3d X(((kBorder + k * kSquare) - tex.cols / 2.0) * s,
                                ((kBorder + r * kSquare) - tex.rows / 2.0) * s, 0);
        const Eigen::Vector2d p = cam.project(cMp * X);
        best = std::min(best, std::hypot(p.x() - c.x, p.y() - c.y));
      }
    worst = std::max(worst, best);
  }
  return worst;
}

TEST(Render, CheckerboardCornersMatchProjection) {
  const Intrinsics cam = testing::sceneCamera();
  const std::vector<Pose> poses = {
      Pose::fromRotationVector({0, 0, 0}, {0, 0, 0.6}),
      Pose::fromRotationVector({0.35, -0.25, 0.2}, {0.03, -0.02, 0.55}),
      Pose::fromRotationVector({-0.2, 0.5, -0.4}, {-0.05, 0.04, 0.7}),
      Pose::fromRotationVector({0.1, 0.2, 0.05}, {0.0, 0.0, 1.6}),  // minified: pyramid level 1
  };
  for (size_t i = 0; i < poses.size(); ++i) {
    int n = 0;
    const double err = checkerboardError(cam, poses[i], 0.3, &n);
    EXPECT_EQ(n, (kCols - 1) * (kRows - 1)) << "pose " << i;
    EXPECT_GE(err, 0) << "pose " << i;
    EXPECT_LT(err, 0.5) << "pose " << i << ": max corner error, px";
  }
}

TEST(Render, CheckerboardCornersWithDistortion) {
  Intrinsics cam = testing::sceneCamera();
  cam.dist = {-0.28, 0.09, 0.001, -0.0015, 0};
  for (const Pose& cMp : {Pose::fromRotationVector({0.2, -0.3, 0.1}, {0.02, 0.01, 0.45}),
                          Pose::fromRotationVector({-0.1, 0.1, 0.0}, {0.0, 0.0, 0.38})}) {
    int n = 0;
    const double err = checkerboardError(cam, cMp, 0.3, &n);
    EXPECT_EQ(n, (kCols - 1) * (kRows - 1));
    EXPECT_GE(err, 0);
    EXPECT_LT(err, 0.5) << "max corner error with distortion, px";
  }
}

TEST(Render, ProjectPlaneCornersAreThePixelEdgeCorners) {
  const Intrinsics cam = Intrinsics::pinhole(640, 480, 500, 319.5, 239.5);
  const TexturedPlane plane{cv::Mat(300, 400, CV_8U, cv::Scalar(255)), 0.4, 0.3,
                            Pose(Eigen::Matrix3d::Identity(), {0, 0, 1})};
  const auto c = projectPlaneCorners(cam, plane);
  const double expect[4][2] = {{219.5, 164.5}, {419.5, 164.5}, {419.5, 314.5}, {219.5, 314.5}};
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(c[i].x(), expect[i][0], 1e-9);
    EXPECT_NEAR(c[i].y(), expect[i][1], 1e-9);
  }
  // Texture pixel centres map through textureToImage: (0,0) -> half a pixel inside TL.
  const Eigen::Vector2d p00 = (textureToImage(cam, plane) * Eigen::Vector3d(0, 0, 1)).hnormalized();
  EXPECT_NEAR(p00.x(), 219.5 + 0.25, 1e-9);  // 0.5 texture px = 0.25 image px at this scale
  EXPECT_NEAR(p00.y(), 164.5 + 0.25, 1e-9);
}

// Coverage of a white fronto-parallel rectangle on black: area and centroid to sub-pixel accuracy.
TEST(Render, AntialiasedCoverageHasSubpixelArea) {
  const Intrinsics cam = Intrinsics::pinhole(640, 480, 500, 319.5, 239.5);
  for (const double shift_px : {0.0, 0.3, 0.55}) {
    const double dx = shift_px / 500.0;  // metres at z = 1
    const TexturedPlane plane{cv::Mat(300, 400, CV_8U, cv::Scalar(255)), 0.4, 0.3,
                              Pose(Eigen::Matrix3d::Identity(), {dx, 0, 1})};
    cv::Mat img;
    renderView(cam, {plane}, cv::Mat(), RenderOptions{true, true, 0.01, 0}).convertTo(img, CV_64F, 1 / 255.0);
    const cv::Moments m = cv::moments(img);
    EXPECT_NEAR(m.m00, 200.0 * 150.0, 0.001 * 200 * 150) << shift_px;  // within 0.1 %
    EXPECT_NEAR(m.m10 / m.m00, 319.5 + shift_px, 0.05) << shift_px;
    EXPECT_NEAR(m.m01 / m.m00, 239.5, 0.05) << shift_px;
  }
}

TEST(Render, BackFacesAreCulled) {
  const Intrinsics cam = testing::sceneCamera();
  const cv::Mat bg = testing::clutterBackground(3);
  const TexturedPlane front{cv::Mat(100, 100, CV_8U, cv::Scalar(255)), 0.2, 0.2,
                            Pose(Eigen::Matrix3d::Identity(), {0, 0, 1})};
  TexturedPlane back = front;
  back.cMp.R = axisAngle(Eigen::Vector3d::UnitY(), M_PI);  // +z towards the camera
  const cv::Mat img_back = renderView(cam, {back}, bg);
  EXPECT_EQ(cv::norm(img_back, bg, cv::NORM_INF), 0);
  const cv::Mat img_front = renderView(cam, {front}, bg);
  EXPECT_EQ(img_front.at<uchar>(240, 320), 255);
}

TEST(Render, NearerPlanesOccludeFartherOnesWhateverTheOrder) {
  const Intrinsics cam = testing::sceneCamera();
  const TexturedPlane near{cv::Mat(50, 50, CV_8U, cv::Scalar(250)), 0.1, 0.1,
                           Pose(Eigen::Matrix3d::Identity(), {0, 0, 0.8})};
  const TexturedPlane far{cv::Mat(50, 50, CV_8U, cv::Scalar(10)), 0.5, 0.5,
                          Pose(axisAngle({0, 1, 0}, 0.3), {0.02, 0, 1.5})};
  for (const auto& planes : {std::vector<TexturedPlane>{near, far}, std::vector<TexturedPlane>{far, near}}) {
    const cv::Mat img = renderView(cam, planes, cv::Mat());
    EXPECT_EQ(img.at<uchar>(240, 320), 250);  // near plane in front
    EXPECT_EQ(img.at<uchar>(240, 320 + 60), 10);  // far plane around it
  }
}

// A large oblique plane whose centre is nearer than a small plane's, but which lies behind it at
// the image centre: ordering by centre distance alone would draw it over the small plane.
TEST(Render, DepthTestBeatsCentreDistanceOrdering) {
  const Intrinsics cam = testing::sceneCamera();
  const TexturedPlane small{cv::Mat(50, 50, CV_8U, cv::Scalar(250)), 0.2, 0.2,
                            Pose(Eigen::Matrix3d::Identity(), {0, 0, 1.5})};
  const Eigen::Matrix3d R = axisAngle(Eigen::Vector3d::UnitY(), M_PI / 3);
  const Eigen::Vector3d centre = Eigen::Vector3d(0, 0, 2.5) + 2.0 * R.col(0);
  const TexturedPlane big{cv::Mat(50, 50, CV_8U, cv::Scalar(10)), 5.0, 5.0, Pose(R, centre)};
  ASSERT_LT(big.cMp.t.norm(), small.cMp.t.norm());
  const cv::Mat img = renderView(cam, {small, big}, cv::Mat());
  EXPECT_EQ(img.at<uchar>(240, 320), 250);
  EXPECT_EQ(img.at<uchar>(240, 320 + 100), 10);
}

// A large textured plane crossing the camera plane (like a floor): every pixel is compared with a
// ray cast, so clipping at the near plane leaves no garbage.
TEST(Render, PlaneCrossingTheCameraMatchesRayCasting) {
  const Intrinsics cam = testing::sceneCamera();
  cv::Mat tex(256, 256, CV_8U);
  for (int v = 0; v < 256; ++v)
    for (int u = 0; u < 256; ++u) tex.at<uchar>(v, u) = static_cast<uchar>(u);
  // Floor 0.3 m below the camera, texture facing up (plane z axis points down = camera +y).
  const Eigen::Matrix3d R = axisAngle(Eigen::Vector3d::UnitX(), -M_PI / 2);  // plane z -> camera +y
  const TexturedPlane floor{tex, 4.0, 4.0, Pose(R, {0.2, 0.3, 1.0})};
  ASSERT_NEAR((R * Eigen::Vector3d::UnitZ()).y(), 1.0, 1e-12);
  const int bg = 77;
  const cv::Mat img = renderView(cam, {floor}, cv::Mat(), RenderOptions{true, false, 0.01, bg});

  const Pose pMc = floor.cMp.inverse();
  // Texture u at the ray through pixel (x,y), or NaN when the ray misses the plane rectangle.
  const auto cast = [&](double x, double y) {
    const Eigen::Vector3d d = pMc.R * cam.K().inverse() * Eigen::Vector3d(x, y, 1);
    const double lambda = -pMc.t.z() / d.z();
    if (!(lambda > 0)) return std::nan("");
    const Eigen::Vector3d P = pMc.t + lambda * d;
    if (std::abs(P.x()) > 2.0 || std::abs(P.y()) > 2.0 || (cam.K().inverse() * Eigen::Vector3d(x, y, 1) * lambda).z() < 0.01)
      return std::nan("");
    return P.x() / (4.0 / 256) + 127.5;
  };
  int checked_in = 0, checked_out = 0, bad = 0;
  for (int y = 0; y < cam.height; y += 3)
    for (int x = 0; x < cam.width; x += 3) {
      const double u = cast(x, y);
      bool edge = false;  // skip pixels within 2 px of the plane's outline
      for (const auto& o : {Eigen::Vector2d(2, 0), Eigen::Vector2d(-2, 0), Eigen::Vector2d(0, 2), Eigen::Vector2d(0, -2)})
        edge |= std::isnan(cast(x + o.x(), y + o.y())) != std::isnan(u);
      if (edge) continue;
      const int got = img.at<uchar>(y, x);
      if (std::isnan(u)) {
        ++checked_out;
        bad += got != bg;
      } else {
        ++checked_in;
        bad += std::abs(got - std::clamp(u, 0.0, 255.0)) > 1.5;
      }
    }
  EXPECT_GT(checked_in, 5000);
  EXPECT_GT(checked_out, 5000);
  EXPECT_EQ(bad, 0);
}

TEST(Render, PlaneEntirelyBehindTheCameraDrawsNothing) {
  const Intrinsics cam = testing::sceneCamera();
  const TexturedPlane behind{cv::Mat(50, 50, CV_8U, cv::Scalar(255)), 0.5, 0.5,
                             Pose(Eigen::Matrix3d::Identity(), {0, 0, -1})};
  const cv::Mat img = renderView(cam, {behind}, cv::Mat(), RenderOptions{true, true, 0.01, 3});
  EXPECT_EQ(cv::countNonZero(img != 3), 0);
}

TEST(Render, BackgroundIsResizedToTheOutput) {
  const Intrinsics cam = testing::sceneCamera();
  cv::Mat bg(48, 64, CV_8U, cv::Scalar(42));
  const cv::Mat img = renderView(cam, {}, bg);
  EXPECT_EQ(img.size(), cv::Size(640, 480));
  EXPECT_EQ(cv::countNonZero(img != 42), 0);
}

TEST(Render, RejectsBadInput) {
  const Intrinsics cam = testing::sceneCamera();
  TexturedPlane p{cv::Mat(10, 10, CV_8UC3), 0.1, 0.1, Pose()};
  EXPECT_THROW(renderView(cam, {p}, cv::Mat()), std::invalid_argument);
  p.texture = cv::Mat(10, 10, CV_8U);
  p.width_m = 0;
  EXPECT_THROW(renderView(cam, {p}, cv::Mat()), std::invalid_argument);
  RenderOptions opt;
  opt.near_m = 0;
  EXPECT_THROW(opt.check(), std::invalid_argument);
}

TEST(Degrade, NoiseHasTheConfiguredSigma) {
  std::mt19937_64 rng(7);
  for (const double sigma : {2.0, 5.0, 12.0}) {
    cv::Mat img(480, 640, CV_8U, cv::Scalar(120));
    Degradation d;
    d.noise_sigma = sigma;
    degrade(img, d, rng);
    cv::Scalar mean, sd;
    cv::meanStdDev(img, mean, sd);
    // Rounding to integers adds variance 1/12.
    EXPECT_NEAR(sd[0], std::sqrt(sigma * sigma + 1.0 / 12), 0.02 * sigma);
    EXPECT_NEAR(mean[0], 120, 0.05);
  }
}

TEST(Degrade, GainAndOffset) {
  std::mt19937_64 rng(1);
  cv::Mat img(10, 10, CV_8U, cv::Scalar(100));
  Degradation d;
  d.brightness_gain = 1.5;
  d.brightness_offset = -20;
  degrade(img, d, rng);
  EXPECT_EQ(cv::countNonZero(img != 130), 0);
  d.brightness_gain = 3;  // saturates
  degrade(img, d, rng);
  EXPECT_EQ(cv::countNonZero(img != 255), 0);
}

// A point spread into a segment of the configured length and direction: variance L^2/12 along it.
TEST(Degrade, MotionBlurSpreadsAPointAlongTheDirection) {
  std::mt19937_64 rng(1);
  const double L = 15;
  for (const double angle : {0.0, M_PI / 2, M_PI / 4}) {
    cv::Mat img = cv::Mat::zeros(101, 101, CV_8U);
    img.at<uchar>(50, 50) = 255;
    cv::Mat f;
    motionBlurKernel(L, angle).copyTo(f);
    EXPECT_NEAR(cv::sum(f)[0], 1.0, 1e-5);
    Degradation d;
    d.motion_blur_px = L;
    d.motion_blur_angle_rad = angle;
    cv::Mat src = cv::Mat::zeros(101, 101, CV_32F);
    src.at<float>(50, 50) = 1;
    cv::Mat out;
    cv::filter2D(src, out, CV_32F, motionBlurKernel(L, angle));
    const double c = std::cos(angle), s = std::sin(angle);
    double m0 = 0, m_along = 0, v_along = 0, v_across = 0;
    for (int y = 0; y < 101; ++y)
      for (int x = 0; x < 101; ++x) {
        const double w = out.at<float>(y, x), a = (x - 50) * c + (y - 50) * s, b = -(x - 50) * s + (y - 50) * c;
        m0 += w;
        m_along += w * a;
        v_along += w * a * a;
        v_across += w * b * b;
      }
    EXPECT_NEAR(m_along / m0, 0, 1e-6);  // no shift
    EXPECT_NEAR(v_along / m0, L * L / 12, 0.08 * L * L / 12) << angle;
    EXPECT_LT(v_across / m0, 0.35) << angle;
    degrade(img, d, rng);  // the 8-bit path: lit 4 px along the direction, dark 4 px across
    EXPECT_GT(img.at<uchar>(50 + static_cast<int>(std::lround(4 * s)), 50 + static_cast<int>(std::lround(4 * c))), 5);
    EXPECT_EQ(img.at<uchar>(50 + static_cast<int>(std::lround(4 * c)), 50 - static_cast<int>(std::lround(4 * s))), 0);
  }
}

TEST(Degrade, DeterministicGivenTheRng) {
  const cv::Mat base = testing::clutterBackground(5);
  Degradation d;
  d.noise_sigma = 3;
  d.motion_blur_px = 4;
  cv::Mat a = base.clone(), b = base.clone();
  std::mt19937_64 ra(99), rb(99);
  degrade(a, d, ra);
  degrade(b, d, rb);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0);
  cv::Mat c = base.clone();
  degrade(c, d, ra);  // the rng moved on: different noise
  EXPECT_GT(cv::norm(a, c, cv::NORM_INF), 0);
  d.noise_sigma = -1;
  EXPECT_THROW(d.check(), std::invalid_argument);
}

}  // namespace
}  // namespace refgrasp::sim

namespace refgrasp::testing {
namespace {

TEST(SyntheticScene, RandomVisiblePosesRespectTheirRanges) {
  const Intrinsics cam = sceneCamera();
  std::mt19937_64 rng(21);
  const double max_tilt = 50 * M_PI / 180;
  double max_seen_tilt = 0;
  for (int i = 0; i < 300; ++i) {
    const Pose cMo = randomVisiblePose(rng, cam, 0.2, 0.15, 0.4, 1.2, max_tilt);
    const double dist = cMo.t.norm();
    EXPECT_GE(dist, 0.4);
    EXPECT_LE(dist, 1.2);
    const double tilt = std::acos(cMo.R.col(2).dot(cMo.t.normalized()));
    EXPECT_LE(tilt, max_tilt + 1e-9);
    max_seen_tilt = std::max(max_seen_tilt, tilt);
    EXPECT_NEAR((cMo.R.transpose() * cMo.R - Eigen::Matrix3d::Identity()).norm(), 0, 1e-12);
    EXPECT_NEAR(cMo.R.determinant(), 1, 1e-12);
    for (const auto& c : sim::projectPlaneCorners(cam, {cv::Mat(), 0.2, 0.15, cMo})) {
      EXPECT_GE(c.x(), 10);
      EXPECT_GE(c.y(), 10);
      EXPECT_LE(c.x(), cam.width - 11);
      EXPECT_LE(c.y(), cam.height - 11);
    }
  }
  EXPECT_GT(max_seen_tilt, 0.9 * max_tilt);  // the range is used, not just near-frontal poses
  EXPECT_THROW(randomVisiblePose(rng, cam, 3.0, 3.0, 0.3, 0.4, 0.1), std::runtime_error);
}

TEST(SyntheticScene, RenderTargetPutsTheTextureAtItsCorners) {
  const Intrinsics cam = sceneCamera();
  const cv::Mat tex = loadMedia("targets/cereal_box.png");
  std::mt19937_64 rng(5);
  SceneSpec spec;
  spec.cMo = randomVisiblePose(rng, cam, 0.2, 0.2, 0.5, 0.8, 0.6);
  spec.seed = 9;
  const RenderedScene a = renderTarget(cam, tex, 0.2, 0.2, spec);
  const RenderedScene b = renderTarget(cam, tex, 0.2, 0.2, spec);
  EXPECT_EQ(cv::norm(a.image, b.image, cv::NORM_INF), 0);  // deterministic
  ASSERT_EQ(a.all_corners.size(), 1u);
  // Rectify the image with the homography from the corners: it is the texture.
  std::vector<cv::Point2f> img_pts, tex_pts = {{-0.5f, -0.5f}, {399.5f, -0.5f}, {399.5f, 399.5f}, {-0.5f, 399.5f}};
  for (const auto& c : a.corners) img_pts.emplace_back(static_cast<float>(c.x()), static_cast<float>(c.y()));
  const cv::Mat H = cv::getPerspectiveTransform(tex_pts, img_pts);
  cv::Mat back;
  cv::warpPerspective(a.image, back, H, tex.size(), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP);
  cv::Mat ncc;
  cv::matchTemplate(back(cv::Rect(20, 20, 360, 360)), tex(cv::Rect(20, 20, 360, 360)), ncc, cv::TM_CCOEFF_NORMED);
  EXPECT_GT(ncc.at<float>(0, 0), 0.85);
  // Another seed: another background and noise, the same target.
  spec.seed = 10;
  EXPECT_GT(cv::norm(renderTarget(cam, tex, 0.2, 0.2, spec).image, a.image, cv::NORM_L1) / a.image.total(), 5);
  EXPECT_THROW(loadMedia("targets/no_such_texture.png"), std::runtime_error);
}

TEST(SyntheticScene, ClutterBackgroundsAreDeterministicAndVaried) {
  const cv::Mat a = clutterBackground(1), b = clutterBackground(1), c = clutterBackground(2);
  EXPECT_EQ(a.size(), cv::Size(640, 480));
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_L1) / a.total(), 10);
  cv::Scalar mean, sd;
  cv::meanStdDev(a, mean, sd);
  EXPECT_GT(sd[0], 25);  // textured, not flat
}

}  // namespace
}  // namespace refgrasp::testing
