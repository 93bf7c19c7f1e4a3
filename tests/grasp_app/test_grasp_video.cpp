// enon_grasp's video on the simulated enon: three panels side by side (head camera, external
// view, top-down map), the map's belief heat map and look wedges where their frames put them,
// and a video file that cannot be written.
#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/videoio.hpp>

#include "common/temp_dir.h"
#include "detector/object.h"
#include "grasp/grasp_log.h"
#include "grasp/grasp_map.h"
#include "robot/enon_model.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"

namespace fs = std::filesystem;
using namespace refgrasp;
using namespace refgrasp::grasp_app;

namespace {

const std::string kSource = REFGRASP_SOURCE_DIR;

const sim::Scenario& tableSingle() {
  static const sim::Scenario s = sim::loadScenario(kSource + "/config/scenarios/table_single.yaml");
  return s;
}

cv::Vec3b at(const cv::Mat& img, const TopDownMap& map, const Eigen::Vector2d& p_w) {
  const cv::Point2d q = map.pixel(p_w);
  return img.at<cv::Vec3b>(cvRound(q.y), cvRound(q.x));
}

// The robot far from the cells and wedges the tests read, no path.
MapFrame quietFrame() {
  MapFrame f;
  f.base_w = {-2.0, -3.0, 0.0};
  return f;
}

// got = a heat + (1 - a) under, a the opacity of a cell holding `fraction` of the largest.
void expectBlend(const cv::Vec3b& got, const cv::Vec3b& under, double fraction, const std::string& what) {
  const cv::Vec3b heat = TopDownMap::heatColour(fraction);
  const double a = TopDownMap::heatAlpha(fraction);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(got[i], a * heat[i] + (1 - a) * under[i], 1.0) << what << " channel " << i;
}

}  // namespace

// A belief cell's pixel shows the heat colour of its share of the largest cell over what lies
// under it; a cell with probability 0 is not drawn. With odometry turned and shifted against
// the world, the cell is drawn where odom_in_world puts it.
TEST(GraspMap, BeliefCellsAreDrawnInTheirHeatColourAtTheirPixels) {
  for (const robot::PlanarPose odom : {robot::PlanarPose{0, 0, 0}, robot::PlanarPose{1.0, -0.5, M_PI / 2}}) {
    const TopDownMap map(tableSingle().world, odom);
    servo::SearchBelief b;
    b.cell_m = 0.25;
    b.cols = b.rows = 4;
    b.origin = odom.theta_rad == 0 ? Eigen::Vector2d(2.0, -2.5) : Eigen::Vector2d(-2.5, -2.0);
    b.p.assign(16, 0.f);
    b.p[2 * 4 + 2] = 0.4f;  // cell (2, 2): the largest
    b.p[0] = 0.1f;          // cell (0, 0): a quarter of it
    MapFrame f = quietFrame();
    const cv::Mat plain = map.draw(tableSingle().world, f);
    f.belief = &b;
    const cv::Mat heat = map.draw(tableSingle().world, f);
    const Eigen::Vector2d c22 = map.odomToWorld(b.centre(2, 2)), c00 = map.odomToWorld(b.centre(0, 0)),
                          c11 = map.odomToWorld(b.centre(1, 1));
    // The cells lie on the open floor (the test would read the table otherwise).
    EXPECT_EQ(at(plain, map, c22), at(plain, map, c11));
    expectBlend(at(heat, map, c22), at(plain, map, c22), 1.0, "cell (2, 2)");
    expectBlend(at(heat, map, c00), at(plain, map, c00), 0.25, "cell (0, 0)");
    EXPECT_EQ(at(heat, map, c11), at(plain, map, c11));
  }
  EXPECT_NE(TopDownMap::heatColour(1.0), TopDownMap::heatColour(0.25));
  EXPECT_DOUBLE_EQ(TopDownMap::heatAlpha(1.0), TopDownMap::kHeatAlpha);
}

// A look's wedge covers the floor within its field of view and range, not beside or beyond it.
TEST(GraspMap, LookWedgeCoversItsFieldOfView) {
  const TopDownMap map(tableSingle().world, robot::PlanarPose{});
  MapFrame f = quietFrame();
  const cv::Mat plain = map.draw(tableSingle().world, f);
  servo::SearchLook l;
  l.index = 1;
  l.camera_w = Eigen::Vector2d(0.0, -1.0);
  l.bearing_rad = 0;
  l.half_fov_rad = 0.5;
  l.range_m = 3.0;
  f.looks = {l};
  const cv::Mat look = map.draw(tableSingle().world, f);
  EXPECT_NE(at(look, map, {2.0, -1.0}), at(plain, map, {2.0, -1.0}));   // on the bearing
  EXPECT_EQ(at(look, map, {2.0, 0.5}), at(plain, map, {2.0, 0.5}));     // 37 deg off: outside
  EXPECT_EQ(at(look, map, {3.5, -1.0}), at(plain, map, {3.5, -1.0}));   // beyond the range
}

// The map shows the room: floor, the table, the target in its colour, the robot where it is.
TEST(GraspMap, RoomTableTargetAndRobotAreWhereTheWorldPutsThem) {
  const TopDownMap map(tableSingle().world, robot::PlanarPose{});
  MapFrame f;
  f.base_w = {0.0, 0.0, 0.0};
  const cv::Mat img = map.draw(tableSingle().world, f);
  EXPECT_EQ(img.size(), cv::Size(640, 480));
  const cv::Vec3b floor = at(img, map, {3.0, -2.0}), table = at(img, map, {1.75, 1.5}),
                  target = at(img, map, {1.35, 1.1}), robot = at(img, map, {0.0, -0.15});
  EXPECT_NE(floor, table);
  EXPECT_NE(table, target);
  EXPECT_GT(target[2], 150);  // red (BGR)
  EXPECT_LT(target[0], 100);
  EXPECT_NE(robot, floor);
  // The room's 8 m across fill the panel's height but for the margins.
  EXPECT_NEAR(map.pixelsPerMetre(), 480 / 8.6, 1e-9);
}

TEST(GraspVideo, SideBySideScalesPanelsToTheFirstHeight) {
  const cv::Mat a(480, 640, CV_8UC3, cv::Scalar(1, 2, 3)), b(240, 320, CV_8UC3, cv::Scalar(4, 5, 6));
  const cv::Mat out = GraspVideo::sideBySide({a, b, a});
  EXPECT_EQ(out.size(), cv::Size(1920, 480));
  EXPECT_EQ(out.at<cv::Vec3b>(100, 700), cv::Vec3b(4, 5, 6));
  EXPECT_EQ(out.at<cv::Vec3b>(100, 1300), cv::Vec3b(1, 2, 3));
}

// With the simulator, each video frame is the head camera (as draw() makes it), the external view
// and the map: 1920 x 480 for a 640 x 480 camera.
TEST(GraspVideo, SimulatedRunsGiveThreePanelFrames) {
  const robot::EnonModel model = robot::loadEnonModel(kSource + "/config/enon.yaml");
  sim::SimEnon sim(model, tableSingle());
  const detector::ObjectModel target = detector::loadObjectDefinition(kSource + "/config/objects/cereal_box.yaml");
  const fs::path dir = refgrasp::testing::tempDir("refgrasp_test_grasp_video");
  const fs::path file = dir / "three.mp4";
  fs::remove(file);
  {  // the file is complete once the video is closed
    GraspVideo video(file.string(), target, model.head.rig.left, 10);
    video.showOutside(sim, model);
    servo::GraspIteration it;
    it.frame = robot::StereoFrame{};
    it.frame->left = cv::Mat(480, 640, CV_8UC1, cv::Scalar(90));
    std::string error;
    for (int k = 0; k < 3; ++k) ASSERT_TRUE(video.add(it, &error)) << error;
    EXPECT_EQ(video.frames(), 3);
    // The panels as the video draws them: the head view first, unchanged.
    const cv::Mat head = GraspVideo::draw(it, target, model.head.rig.left);
    const cv::Mat frame = GraspVideo::sideBySide({head, video.externalPanel(), video.mapPanel()});
    EXPECT_EQ(frame.size(), cv::Size(1920, 480));
    EXPECT_EQ(cv::norm(frame(cv::Rect(0, 0, 640, 480)), head, cv::NORM_INF), 0);
  }
  cv::VideoCapture v(file.string());
  ASSERT_TRUE(v.isOpened());
  int frames = 0;
  for (cv::Mat f; v.read(f); ++frames) EXPECT_EQ(f.size(), cv::Size(1920, 480));
  EXPECT_EQ(frames, 3);
}

// A video file that cannot be opened: add() says so in one line naming the file.
TEST(GraspVideo, UnwritableFileIsOneLineNamingIt) {
  const robot::EnonModel model = robot::loadEnonModel(kSource + "/config/enon.yaml");
  sim::SimEnon sim(model, tableSingle());
  const detector::ObjectModel target = detector::loadObjectDefinition(kSource + "/config/objects/cereal_box.yaml");
  const std::string path = "/nonexistent_refgrasp_dir/sub/v.mp4";
  GraspVideo video(path, target, model.head.rig.left, 10);
  video.showOutside(sim, model);
  servo::GraspIteration it;
  it.frame = robot::StereoFrame{};
  it.frame->left = cv::Mat(480, 640, CV_8UC1, cv::Scalar(90));
  std::string error;
  EXPECT_FALSE(video.add(it, &error));
  EXPECT_EQ(error.rfind(path + ": ", 0), 0u) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos);
}
