// A two-view box on real footage (eval/box_video_eval.h): OpenCV's hand-held box clip
// (media/video/box.mp4) with config/objects/box_video.yaml, checked against the corners labelled by
// hand (media/video/box_corners.txt). The bounds are the measured figures (docs/results.md "Real
// video: box.mp4") with a small margin; the full table: build/bench/bench_box_video.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "core/error.h"
#include "eval/box_video_eval.h"

using namespace refgrasp;
using namespace refgrasp::eval;

namespace {

const std::string kRoot = REFGRASP_SOURCE_DIR;

BoxVideoOptions clipOptions() {
  ::setenv("OPENCV_FFMPEG_LOGLEVEL", "-8", 0);  // the clip's last frame makes FFmpeg complain
  BoxVideoOptions o;
  o.video = kRoot + "/media/video/box.mp4";
  o.camera = kRoot + "/media/video/box_camera.yaml";
  o.object = kRoot + "/config/objects/box_video.yaml";
  o.labels = kRoot + "/media/video/box_corners.txt";
  return o;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? NAN : v[v.size() / 2];
}

}  // namespace

// Measured (view_stride 5): a pose in 455 of 455 frames (2 detected, 453 tracked); at the ten
// labelled frames the mean corner error 4.0-12.1 px, the worst corner 25.8 px (frame 400's back
// corner); the views alone: front 88, top 70, both 68 of 91 frames, their poses 3.0 deg and
// 0.76 % of the distance apart (medians), 8.3 deg at most.
TEST(BoxVideo, TheTwoViewBoxIsFoundAndTrackedThroughTheRealClipAndItsViewsAgree) {
  BoxVideoOptions o = clipOptions();
  o.view_stride = 5;
  const BoxVideoResult r = runBoxVideo(o);

  EXPECT_EQ(r.frames, 455);
  EXPECT_GE(r.detect, 1);
  EXPECT_LE(r.lost, 4);  // >= 99 % of the frames with a pose
  ASSERT_EQ(r.labelled.size(), 10u);
  std::vector<double> worst;
  for (const BoxLabelCheck& c : r.labelled) {
    SCOPED_TRACE("frame " + std::to_string(c.frame));
    ASSERT_TRUE(c.has_pose);
    EXPECT_LE(c.mean_px, 13.0);
    EXPECT_LE(c.max_px, 28.0);
    worst.push_back(c.max_px);
  }
  EXPECT_EQ(r.wrong, 0);
  EXPECT_LE(median(worst), 11.0);

  ASSERT_EQ(r.view_names.size(), 2u);
  EXPECT_EQ(r.view_frames, 91);
  EXPECT_GE(r.view_found[0], 85);  // front
  EXPECT_GE(r.view_found[1], 65);  // top
  ASSERT_GE(r.agreement.size(), 63u);
  std::vector<double> deg, fraction;
  int within_10_deg = 0;
  for (const BoxViewAgreement& a : r.agreement) {
    deg.push_back(a.rotation_deg);
    fraction.push_back(a.translation_m / a.distance_m);
    within_10_deg += a.rotation_deg <= 10;
  }
  EXPECT_LE(median(deg), 3.5);
  EXPECT_LE(median(fraction), 0.010);
  EXPECT_GE(within_10_deg, static_cast<int>(0.95 * r.agreement.size()));
}

// By construction: corners of a known box seen with a known f are fitted back exactly at that f
// (the aspect ratios on their grid), and worse at another f.
TEST(BoxVideo, ABoxFittedToExactCornersRecoversItsAspectRatios) {
  const Intrinsics camera = Intrinsics::pinhole(640, 480, 650, 319.5, 239.5);
  const Eigen::Vector3d size(1, 0.31, 0.69);
  std::vector<BoxLabel> labels;
  const double turns[4][3] = {{0.7, 0.6, 0.2}, {0.5, -0.4, 0.1}, {0.9, 0.2, -0.2}, {0.6, 0.8, 0.3}};
  for (int k = 0; k < 4; ++k) {
    Pose cMo;
    cMo.R = Eigen::AngleAxisd(Eigen::Vector3d(turns[k][0], turns[k][1], turns[k][2]).norm(),
                              Eigen::Vector3d(turns[k][0], turns[k][1], turns[k][2]).normalized())
                .toRotationMatrix();
    cMo.t = Eigen::Vector3d(0.05 * k - 0.1, 0.02, 2.2);
    BoxLabel label;
    label.frame = k;
    const std::array<Eigen::Vector3d, 5> p = boxLabelPoints(size);
    for (size_t i = 0; i < p.size(); ++i) label.corners_px[i] = camera.project(cMo * p[i]);
    labels.push_back(label);
  }
  const BoxFit exact = fitBoxToLabels(labels, 650, 640, 480);
  EXPECT_NEAR(exact.h_over_w, 0.31, 1e-9);
  EXPECT_NEAR(exact.d_over_w, 0.69, 1e-9);
  EXPECT_LT(exact.rms_px, 1e-3);
  EXPECT_GT(fitBoxToLabels(labels, 1000, 640, 480).rms_px, 0.5);
  const std::array<Eigen::Vector2d, 6> corners = fittedBoxCorners(labels[0], size, camera);
  for (int i = 0; i < 5; ++i) EXPECT_LT((corners[i] - labels[0].corners_px[i]).norm(), 1e-3);
}

TEST(BoxVideo, ABadLabelsFileOrOptionIsOneLine) {
  const std::string path = testing::TempDir() + "box_corners_bad.txt";
  {
    std::ofstream f(path);
    f << "# frame A B C D F\n0 1 2 3 4 5 6 7 8 9 10\n50 1 2 3 4 5 6 7 8 9\n";
  }
  try {
    loadBoxLabels(path);
    ADD_FAILURE() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()),
              path + ": line 3: expected a frame number and 10 coordinates (A B C D F, u v each)");
  }
  EXPECT_EQ(loadBoxLabels(kRoot + "/media/video/box_corners.txt").size(), 10u);
  BoxVideoOptions o = clipOptions();
  o.view_stride = -1;
  EXPECT_THROW(o.check(), std::invalid_argument);
  o = clipOptions();
  o.wrong_px = NAN;
  EXPECT_THROW(o.check(), std::invalid_argument);
}
