// The simulated enon's stereo camera: frame timing, drops, delay, rendering from the true pose,
// and bit-identical images for the same seed.
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>
#include <random>

#include "common/noise_image.h"
#include "robot/hal.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"
#include "sim_test_util.h"

using namespace refgrasp;
using namespace refgrasp::robot;
using refgrasp::sim::Scenario;
using refgrasp::sim::SimEnon;

namespace {

std::string scenarioPath(const std::string& name) {
  return std::string(REFGRASP_SOURCE_DIR) + "/config/scenarios/" + name;
}


// A world with one small textured plane 2 m in front of the robot, facing it.
Scenario planeScenario(uint64_t seed) {
  Scenario sc;
  sc.path = "camera_test.yaml";
  sc.seed = seed;
  sim::SimObject o;
  o.name = "poster";
  std::mt19937_64 rng(seed);
  sim::TexturedPlane face;
  face.texture = refgrasp::testing::noiseImage(rng, 64, 64);
  face.width_m = face.height_m = 0.3;
  o.faces.push_back(face);  // face pose = object frame (oMp = I)
  // Object z points away from the robot (texture visible from -z), x along -y_w, y down.
  Eigen::Matrix3d R;
  R.col(0) = Eigen::Vector3d(0, -1, 0);
  R.col(1) = Eigen::Vector3d(0, 0, -1);
  R.col(2) = Eigen::Vector3d(1, 0, 0);
  o.wMo = Pose(R, Eigen::Vector3d(2.0, 0.06, 1.2));
  sc.world.objects.push_back(o);
  return sc;
}

}  // namespace

TEST(SimEnonCamera, FramesComeAtTheFrameRateOnceEach) {
  testing_util::SimRig r(planeScenario(3));
  std::vector<long> indices;
  std::vector<double> stamps;
  const double dt = 0.01;
  for (int k = 0; k <= 50; ++k) {  // 0.5 s polled at 100 Hz
    const double t = k * dt;
    ASSERT_EQ(r.robot->read(t, dt), ReturnType::kOk);
    std::optional<StereoFrame> f;
    ASSERT_EQ(r.robot->camera().grab(t, &f), ReturnType::kOk);
    if (f) {
      indices.push_back(f->index);
      stamps.push_back(f->stamp);
      EXPECT_EQ(f->left.type(), CV_8UC1);
      EXPECT_EQ(f->left.cols, r.model.head.rig.left.width);
      EXPECT_EQ(f->right.rows, r.model.head.rig.right.height);
      EXPECT_LE(f->stamp, t);
    }
  }
  // 48 fps over [0, 0.5] s: frames 0..24, each delivered once (polling at 100 Hz never skips).
  ASSERT_EQ(indices.size(), 25u);
  for (size_t i = 0; i < indices.size(); ++i) {
    EXPECT_EQ(indices[i], static_cast<long>(i));
    EXPECT_NEAR(stamps[i], i / 48.0, 1e-12);
  }
}

TEST(SimEnonCamera, DroppedFramesAreTheOnesTheFaultModelDrops) {
  Scenario sc = planeScenario(5);
  sc.world.objects.clear();  // timing only: keep the rendering cheap
  sc.faults.frame_drop_probability = 0.3;
  testing_util::SimRig r(sc);
  int delivered = 0, expected = 0;
  const int n = 240;  // 5 s of frames, grabbed exactly at each capture time
  for (int k = 0; k < n; ++k) {
    const double t = k / 48.0;
    ASSERT_EQ(r.robot->read(t, 1 / 48.0), ReturnType::kOk);
    std::optional<StereoFrame> f;
    ASSERT_EQ(r.robot->camera().grab(t, &f), ReturnType::kOk);
    EXPECT_EQ(f.has_value(), !r.sim->frameDropped(k)) << k;
    delivered += f ? 1 : 0;
    expected += r.sim->frameDropped(k) ? 0 : 1;
  }
  std::printf("frames delivered %d of %d with p_drop = 0.3\n", delivered, n);
  EXPECT_EQ(delivered, expected);
  EXPECT_NEAR(static_cast<double>(n - delivered) / n, 0.3, 4 * std::sqrt(0.3 * 0.7 / n));
}

TEST(SimEnonCamera, DelayedFramesShowTheTruePoseAtCaptureTime) {
  Scenario sc = planeScenario(9);
  sc.faults.frame_delay_s = 0.1;
  testing_util::SimRig r(sc);
  const double dt = r.model.control_period_s, w = 0.5;
  std::optional<StereoFrame> last;
  for (int k = 0; k <= 50; ++k) {
    const double t = k * dt;
    ASSERT_EQ(r.robot->read(t, dt), ReturnType::kOk);
    std::optional<StereoFrame> f;
    ASSERT_EQ(r.robot->camera().grab(t, &f), ReturnType::kOk);
    if (f) {
      EXPECT_LE(f->stamp, t - 0.1 + 1e-12);
      EXPECT_GT(f->stamp, t - 0.1 - 1 / 48.0 - dt);
      last = f;
    }
    r.robot->base().setVelocity(0, w);  // turning on the spot
    ASSERT_EQ(r.robot->write(t, dt), ReturnType::kOk);
  }
  ASSERT_TRUE(last.has_value());
  // Truth in the frame = the head kinematics on the closed-form base pose at the stamp.
  const double theta = w * last->stamp;
  const Pose wMc = PlanarPose{0, 0, theta}.toPose() * headCameraPose(r.model.head, 0, 0);
  const sim::SyntheticFrame* truth = r.sim->lastFrame();
  ASSERT_NE(truth, nullptr);
  const Pose cMo = wMc.inverse() * r.sim->world().objects[0].wMo;
  EXPECT_NEAR(translationError(truth->left_cMo[0], cMo), 0, 1e-5);
  EXPECT_NEAR(rotationError(truth->left_cMo[0], cMo), 0, 1e-6);
  // The current camera pose is elsewhere: the delay is visible.
  const Pose cMo_now = r.sim->wMc().inverse() * r.sim->world().objects[0].wMo;
  EXPECT_GT(rotationError(truth->left_cMo[0], cMo_now), 0.04);
}

// The frame reports the head joints and the camera pose at its exposure, not at delivery: with a
// 0.1 s frame delay and the head panning at a constant rate, they follow the closed form at the
// stamp; the odometry at capture is the base's (no odometry noise configured) at the stamp.
TEST(SimEnonCamera, DelayedFramesCarryTheHeadStateAtCapture) {
  Scenario sc = planeScenario(10);
  sc.faults.frame_delay_s = 0.1;
  testing_util::SimRig r(sc);
  const double dt = r.model.control_period_s, pan_rate = 0.3, w = 0.2;
  int frames = 0;
  for (int k = 0; k <= 40; ++k) {
    const double t = k * dt;
    ASSERT_EQ(r.robot->read(t, dt), ReturnType::kOk);
    std::optional<StereoFrame> f;
    ASSERT_EQ(r.robot->camera().grab(t, &f), ReturnType::kOk);
    if (f && f->stamp > 0) {
      ++frames;
      ASSERT_TRUE(f->capture.head && f->capture.bMc && f->capture.wMb_odom);
      EXPECT_NEAR(f->capture.head->pan_rad, pan_rate * f->stamp, 1e-9) << f->stamp;
      EXPECT_LT(rotationError(*f->capture.bMc, headCameraPose(r.model.head, pan_rate * f->stamp, 0)),
                1e-9);
      const Pose wMb = PlanarPose{0, 0, w * f->stamp}.toPose();
      EXPECT_LT(rotationError(*f->capture.wMb_odom, wMb), 1e-9);
      EXPECT_GT(std::abs(r.robot->state().pan_rad - f->capture.head->pan_rad), 0.02);
    }
    r.robot->head().setVelocity(pan_rate, 0);
    r.robot->base().setVelocity(0, w);
    ASSERT_EQ(r.robot->write(t, dt), ReturnType::kOk);
  }
  EXPECT_GE(frames, 5);
}

TEST(SimEnonCamera, SameSeedSameImagesBitForBit) {
  auto run = [](uint64_t seed) {
    Scenario sc = sim::loadScenario(scenarioPath("table_clutter.yaml"));
    sc.seed = seed;
    testing_util::SimRig r(sc);
    std::vector<cv::Mat> images;
    for (int k = 0; k < 12; ++k) {
      const double t = k * 0.05;
      EXPECT_EQ(r.robot->read(t, 0.05), ReturnType::kOk);
      std::optional<StereoFrame> f;
      EXPECT_EQ(r.robot->camera().grab(t, &f), ReturnType::kOk);
      if (f) {
        images.push_back(f->left);
        images.push_back(f->right);
      }
      r.robot->base().setVelocity(0.2, 0.3);
      r.robot->head().setVelocity(0.2, 0.1);
      EXPECT_EQ(r.robot->write(t, 0.05), ReturnType::kOk);
    }
    return images;
  };
  const auto a = run(21), b = run(21), c = run(22);
  ASSERT_EQ(a.size(), b.size());
  ASSERT_GE(a.size(), 10u);
  for (size_t i = 0; i < a.size(); ++i) EXPECT_EQ(cv::norm(a[i], b[i], cv::NORM_INF), 0) << i;
  double diff = 0;
  for (size_t i = 0; i < std::min(a.size(), c.size()); ++i) diff += cv::norm(a[i], c[i], cv::NORM_L1);
  EXPECT_GT(diff, 0);  // the seed matters (sensor noise)
}

TEST(SimEnonCamera, EveryShippedScenarioRunsOnTheSimulatedEnon) {
  for (const char* name : {"table_single.yaml", "table_clutter.yaml", "faults.yaml"}) {
    const Scenario sc = sim::loadScenario(scenarioPath(name));
    auto robot = sim::makeSimRobot(testing_util::enonModel(), sc);
    ASSERT_EQ(robot->configure(), ReturnType::kOk);
    ASSERT_EQ(robot->activate(), ReturnType::kOk);
    int frames = 0;
    for (int k = 0; k < 10; ++k) {
      const double t = k * 0.05;
      ASSERT_EQ(robot->read(t, 0.05), ReturnType::kOk);
      std::optional<StereoFrame> f;
      ASSERT_EQ(robot->camera().grab(t, &f), ReturnType::kOk);
      frames += f ? 1 : 0;
      robot->base().setVelocity(0.1, 0.0);
      ASSERT_EQ(robot->write(t, 0.05), ReturnType::kOk);
    }
    EXPECT_GT(frames, 0) << name;
  }
}
