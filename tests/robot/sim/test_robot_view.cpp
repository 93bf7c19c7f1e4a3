// The robot seen from outside: its parts rendered by an external camera where the kinematics puts
// them, and the head camera's frames unchanged by it (the robot never appears in them).
#include <gtest/gtest.h>

#include <cstdint>
#include <opencv2/core.hpp>

#include "robot/enon_model.h"
#include "robot/hal.h"
#include "robot/sim/render.h"
#include "robot/sim/robot_view.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"
#include "sim_test_util.h"

using namespace refgrasp;
using refgrasp::robot::ReturnType;

namespace {

std::string scenarioPath(const std::string& name) {
  return std::string(REFGRASP_SOURCE_DIR) + "/config/scenarios/" + name;
}

// FNV-1a over the pixel rows (a fingerprint of the image's bits).
uint64_t fingerprint(const cv::Mat& img) {
  uint64_t h = 1469598103934665603ull;
  for (int r = 0; r < img.rows; ++r) {
    const uchar* p = img.ptr<uchar>(r);
    for (size_t i = 0; i < img.cols * img.elemSize(); ++i) h = (h ^ p[i]) * 1099511628211ull;
  }
  return h;
}

// The arm raised in front of the head, the head tilted down onto it: the robot's own gripper is
// in the head camera's view.
struct ArmInViewRig {
  testing_util::SimRig rig{sim::loadScenario(scenarioPath("table_single.yaml"))};
  ArmInViewRig() {
    Eigen::VectorXd q(5);
    q << 1.2, 0.2, 0.0, 0.9, 0.0;
    rig.sim->setJointPositions(q);
    rig.run(50, [&](double) { rig.robot->head().setPosition(-0.3, 0.45); });
  }
};

}  // namespace

TEST(RobotView, HeadCameraFrameIsTheSameBitsAsWithoutTheRobotDrawn) {
  ArmInViewRig r;
  ASSERT_FALSE(r.rig.sim->collided()) << r.rig.sim->lastError();
  // The gripper is in the head camera's view, so a robot drawn into it would change the frame.
  const Eigen::Vector3d e_c = r.rig.sim->wMc().inverse() * r.rig.sim->wMe().t;
  const Eigen::Vector2d px = r.rig.model.head.rig.left.project(e_c);
  ASSERT_GT(e_c.z(), 0.1);
  EXPECT_GT(px.x(), 0);
  EXPECT_LT(px.x(), r.rig.model.head.rig.left.width);
  EXPECT_GT(px.y(), 0);
  EXPECT_LT(px.y(), r.rig.model.head.rig.left.height);
  std::optional<robot::StereoFrame> f;
  const double t = 50 * r.rig.dt;
  ASSERT_EQ(r.rig.robot->read(t, r.rig.dt), ReturnType::kOk);
  ASSERT_EQ(r.rig.robot->camera().grab(t, &f), ReturnType::kOk);
  ASSERT_TRUE(f);
  // Fingerprints of this frame as the head camera rendered it before the simulator could draw
  // the robot (computed with that code on this world, seed and state); any change to what the
  // head camera sees changes them.
  EXPECT_EQ(fingerprint(f->left), 10475688829925827852ull);
  EXPECT_EQ(fingerprint(f->right), 6810178805446535941ull);
}

// A capsule seen head-on, lit from the camera: its centre pixel is the part's colour exactly
// (n . light = 1); a nearer capsule hides it; a pixel off both keeps the background.
TEST(RobotView, CapsuleCentrePixelHasItsColourAndTheNearerPartWins) {
  const Intrinsics cam = Intrinsics::pinhole(160, 120, 100, 80, 60);  // pixel (80, 60) on the axis
  const Pose wMc = sim::lookAt(Eigen::Vector3d(-2, 0, 1), Eigen::Vector3d(0, 0, 1));  // looks along +x
  cv::Mat img(cam.height, cam.width, CV_8UC3, cv::Scalar(128, 128, 128));
  cv::Mat inv_depth(img.size(), CV_32F, cv::Scalar(0));
  sim::RobotPart far{"forearm", {0, -0.3, 1}, {0, 0.3, 1}, 0.1, false, sim::partColour("forearm")};
  // The palm 1 m from the camera, in front of the forearm: its axis along y from 0.05 to 0.1 m,
  // columns 80 - 100 * y / 1 = 75 to 70.
  sim::RobotPart near{"palm", {-1, 0.05, 1}, {-1, 0.1, 1}, 0.02, false, sim::partColour("palm")};
  const Eigen::Vector3d towards_camera(-1, 0, 0);
  sim::drawRobotParts(img, inv_depth, cam.K(), wMc, {far, near}, towards_camera);
  EXPECT_EQ(img.at<cv::Vec3b>(60, 80), sim::partColour("forearm"));
  EXPECT_NEAR(inv_depth.at<float>(60, 80), 1 / 1.9, 1e-3);           // front of the capsule: 1.9 m
  EXPECT_EQ(img.at<cv::Vec3b>(60, 72), sim::partColour("palm"));
  EXPECT_NEAR(inv_depth.at<float>(60, 72), 1 / 0.98, 1e-3);
  EXPECT_EQ(img.at<cv::Vec3b>(60, 90), sim::partColour("forearm"));
  EXPECT_EQ(img.at<cv::Vec3b>(110, 5), cv::Vec3b(128, 128, 128));
  EXPECT_EQ(inv_depth.at<float>(110, 5), 0.f);
  // Lambert: lit from straight above, the capsule's front (normal towards the camera) gets the
  // ambient term only.
  cv::Mat img2(cam.height, cam.width, CV_8UC3, cv::Scalar(0, 0, 0)), z2(img.size(), CV_32F, cv::Scalar(0));
  sim::drawRobotParts(img2, z2, cam.K(), wMc, {far}, Eigen::Vector3d::UnitZ());
  EXPECT_EQ(img2.at<cv::Vec3b>(60, 80), sim::lambert(sim::partColour("forearm"), towards_camera, Eigen::Vector3d::UnitZ()));
}

// The simulated enon's parts from a camera in front of it and to its right: the pixel where
// the kinematics projects the forearm's middle has the forearm's hue, one off the robot the
// same colour as the world rendered without the robot.
TEST(RobotView, PartsProjectWhereTheKinematicsPutsThem) {
  ArmInViewRig r;
  const sim::SimEnon& s = *r.rig.sim;
  const sim::RobotShapes shapes = s.shapes();
  const std::vector<sim::RobotPart> parts = sim::robotParts(r.rig.model, shapes, s.wMb(), s.wMc());
  ASSERT_EQ(parts.size(), 8u);
  const sim::Capsule& forearm = shapes.capsules[1].second;
  ASSERT_EQ(shapes.capsules[1].first, "forearm");
  const Eigen::Vector3d mid = 0.5 * (forearm.a + forearm.b);
  const Pose wMc = sim::lookAt(s.wMb() * Eigen::Vector3d(2.0, -1.5, 1.6), mid);
  const Intrinsics cam = sim::FollowCameraOptions().camera;
  const cv::Mat with = sim::renderExternalView(cam, s.world(), wMc, parts);
  const cv::Mat without = sim::renderExternalView(cam, s.world(), wMc, {});
  ASSERT_EQ(with.type(), CV_8UC3);
  const Eigen::Vector2d px = cam.project(wMc.inverse() * mid);
  EXPECT_NEAR(px.x(), cam.cx, 1e-6);  // looked at
  const cv::Vec3b got = with.at<cv::Vec3b>(cvRound(px.y()), cvRound(px.x()));
  const cv::Vec3b colour = sim::partColour("forearm");
  // Shaded: colour * k with one k in [ambient, 1] for all three channels (+-1 for rounding).
  const double k = got[2] / static_cast<double>(colour[2]);
  EXPECT_GE(k, 0.35 - 0.01);
  EXPECT_LE(k, 1.0 + 0.01);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(got[i], colour[i] * k, 1.5) << i;
  EXPECT_NE(got, without.at<cv::Vec3b>(cvRound(px.y()), cvRound(px.x())));
  // The base body's centre line, 0.5 m up, is drawn too; the image corners show only the world.
  const Eigen::Vector2d base_px = cam.project(wMc.inverse() * (s.wMb() * Eigen::Vector3d(0, 0, 0.5)));
  const cv::Vec3b base = with.at<cv::Vec3b>(cvRound(base_px.y()), cvRound(base_px.x()));
  const double kb = base[0] / static_cast<double>(sim::partColour("base")[0]);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(base[i], sim::partColour("base")[i] * kb, 1.5) << i;
  for (const cv::Point c : {cv::Point(2, 2), cv::Point(cam.width - 3, 2), cv::Point(2, cam.height - 3)})
    EXPECT_EQ(with.at<cv::Vec3b>(c), without.at<cv::Vec3b>(c)) << c;
}

// renderViewWithDepth draws the same bits as renderView and returns 1 / z of what each pixel shows.
TEST(RobotView, RenderViewWithDepthIsRenderViewPlusItsDepth) {
  const Intrinsics cam = Intrinsics::pinhole(120, 90, 100, 59.5, 44.5);
  sim::TexturedPlane p;
  p.texture = cv::Mat(32, 32, CV_8U);
  cv::randu(p.texture, 0, 255);
  p.width_m = p.height_m = 0.5;
  p.cMp = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, 2.0));
  cv::Mat inv_depth;
  const cv::Mat a = sim::renderView(cam, {p}, {}, cv::Mat(), {});
  const cv::Mat b = sim::renderViewWithDepth(cam, {p}, {}, cv::Mat(), {}, &inv_depth);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0);
  EXPECT_NEAR(inv_depth.at<float>(45, 60), 0.5, 1e-6);
  EXPECT_EQ(inv_depth.at<float>(2, 2), 0.f);
  Intrinsics distorted = cam;
  distorted.dist[0] = 0.1;
  EXPECT_THROW(sim::renderViewWithDepth(distorted, {p}, {}, cv::Mat(), {}, &inv_depth), std::invalid_argument);
}

// The follow camera: behind, right of and above the base, the point ahead of and above the base
// at the image centre; after the base jumps, the smoothed eye has moved 1 - exp(-dt / tau) of
// the way.
TEST(RobotView, FollowCameraSitsBehindAndAboveAndSmoothes) {
  sim::FollowCameraOptions o;
  sim::FollowCamera f(o);
  const Pose a = f.update({1.0, 2.0, M_PI / 2}, 0.0);  // heading +y: behind is -y, right is +x
  EXPECT_NEAR((a.t - Eigen::Vector3d(1.0 + o.right_m, 2.0 - o.behind_m, o.above_m)).norm(), 0, 1e-12);
  const Eigen::Vector2d c = o.camera.project(a.inverse() * Eigen::Vector3d(1.0, 2.0 + o.look_ahead_m, o.look_at_height_m));
  EXPECT_NEAR(c.x(), o.camera.cx, 1e-9);
  EXPECT_NEAR(c.y(), o.camera.cy, 1e-9);
  const Pose b = f.update({2.0, 2.0, M_PI / 2}, 0.4);
  EXPECT_NEAR(b.t.x(), 1.0 + o.right_m + (1 - std::exp(-0.4 / o.smoothing_s)), 1e-12);
  EXPECT_NEAR(b.t.z(), o.above_m, 1e-12);
  // The image's x axis stays horizontal.
  EXPECT_NEAR(b.R.col(0).z(), 0, 1e-12);
}
