// Scenario files: every shipped scenario loads and means what it says; bad files give one-line
// ConfigErrors naming the file and the field.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <unistd.h>

#include "robot/sim/synthetic_scene.h"
#include "core/error.h"
#include "core/image_io.h"
#include "robot/sim/render.h"
#include "robot/sim/scenario.h"
#include "robot/sim/synthetic_camera.h"

namespace refgrasp::sim {
namespace {

namespace fs = std::filesystem;
const std::string kScenarios = std::string(REFGRASP_SOURCE_DIR) + "/config/scenarios/";
const std::string kMedia = std::string(REFGRASP_SOURCE_DIR) + "/media/";

// Camera at the robot's start, 1.2 m above the floor, looking along the robot's heading.
Pose startCamera(const Scenario& s) {
  Eigen::Matrix3d optical;  // camera z = heading, x = right, y = down
  optical << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  return Pose(axisAngle(Eigen::Vector3d::UnitZ(), s.start_theta_rad) * optical,
              Eigen::Vector3d(s.start_x_m, s.start_y_m, 1.2));
}

const SimObject& target(const Scenario& s) {
  for (const auto& o : s.world.objects)
    if (o.is_target) return o;
  throw std::runtime_error("no target");
}

bool inView(const Intrinsics& cam, const Pose& wMc, const Eigen::Vector3d& Xw) {
  const Eigen::Vector3d Xc = wMc.inverse() * Xw;
  if (Xc.z() <= 0) return false;
  const Eigen::Vector2d p = cam.project(Xc);
  return p.x() >= 0 && p.y() >= 0 && p.x() < cam.width && p.y() < cam.height;
}

TEST(Scenario, EveryShippedScenarioLoads) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(kScenarios)) {
    if (e.path().extension() != ".yaml") continue;
    ++n;
    SCOPED_TRACE(e.path().string());
    const Scenario s = loadScenario(e.path().string());
    int targets = 0;
    for (const auto& o : s.world.objects) {
      EXPECT_FALSE(o.faces.empty() && o.cylinders.empty()) << o.name;
      for (const auto& f : o.faces) EXPECT_EQ(f.texture.type(), CV_8UC1) << o.name;
      for (const auto& c : o.cylinders) EXPECT_EQ(c.label.type(), CV_8UC1) << o.name;
      if (!o.is_target) continue;
      ++targets;
      EXPECT_TRUE(fs::is_regular_file(o.definition)) << o.definition;
    }
    EXPECT_EQ(targets, 1);
    EXPECT_GT(s.max_duration_s, 0);
  }
  EXPECT_GE(n, 3);
}

TEST(Scenario, ShippedScenariosPlaceTheTargetAsDocumented) {
  const Intrinsics bb2 = loadCameraFile(std::string(REFGRASP_SOURCE_DIR) + "/config/cameras/bb2_left.yaml");
  for (const std::string name : {"table_single.yaml", "faults.yaml", "table_clutter.yaml"}) {
    SCOPED_TRACE(name);
    const Scenario s = loadScenario(kScenarios + name);
    const SimObject& t = target(s);
    const Eigen::Vector3d start(s.start_x_m, s.start_y_m, 0);
    const double dist = (t.wMo.t - start).head<2>().norm();
    EXPECT_GE(dist, 1.5);
    EXPECT_LE(dist, 3.0);
    // Resting on the table: the bottom of the box (object y = +height/2) at the table-top height.
    const SimObject* table = nullptr;
    for (const auto& o : s.world.objects)
      if (o.name == "table") table = &o;
    ASSERT_NE(table, nullptr);
    const double bottom = (t.wMo * Eigen::Vector3d(0, t.faces.back().height_m / 2, 0)).z();
    EXPECT_NEAR(bottom, table->wMo.t.z(), 1e-3);
    const bool visible = inView(bb2, startCamera(s), t.wMo.t);
    EXPECT_EQ(visible, name == "table_clutter.yaml");
  }
  const Scenario f = loadScenario(kScenarios + "faults.yaml");
  EXPECT_DOUBLE_EQ(f.faults.frame_drop_probability, 0.1);
  EXPECT_DOUBLE_EQ(f.faults.command_latency_s, 0.1);
  EXPECT_DOUBLE_EQ(f.faults.frame_delay_s, 0.05);
}

// can_table: the can stands upright on the table in view of the start, its grasp frame on its
// axis, approaching horizontally and closing across the diameter.
TEST(Scenario, TheCanStandsOnTheTableWithItsSideGraspFrame) {
  const Intrinsics bb2 = loadCameraFile(std::string(REFGRASP_SOURCE_DIR) + "/config/cameras/bb2_left.yaml");
  const Scenario s = loadScenario(kScenarios + "can_table.yaml");
  const SimObject& can = target(s);
  ASSERT_EQ(can.cylinders.size(), 1u);
  ASSERT_EQ(can.solids.size(), 1u);
  EXPECT_TRUE(can.faces.empty());
  const TexturedCylinder& c = can.cylinders[0];
  EXPECT_EQ(c.radius_m, 0.033);
  EXPECT_EQ(c.height_m, 0.122);
  EXPECT_EQ(c.label_width_m, 0.2073);
  EXPECT_EQ(c.label_height_m, 0.115);
  EXPECT_EQ(c.label.size(), cv::Size(512, 284));
  EXPECT_TRUE(c.side_texture.empty());
  EXPECT_NEAR((c.cMo.t).norm() + c.cMo.rotationVector().norm(), 0, 0);  // oMc = identity
  // Upright: y_o down the axis (-z_w), z_o horizontal into the can.
  EXPECT_NEAR((can.wMo.R.col(1) - Eigen::Vector3d(0, 0, -1)).norm(), 0, 1e-4);
  EXPECT_NEAR(can.wMo.R.col(2).z(), 0, 1e-4);
  // The solid: a cylinder about a vertical axis through (0, y, r), spanning the side.
  const Solid& sd = can.solids[0];
  EXPECT_TRUE(sd.cylinder);
  const Pose wMs = can.wMo * sd.oMs;
  EXPECT_NEAR(std::abs(wMs.R(2, 2)), 1, 1e-4);
  EXPECT_NEAR((sd.half_m - Eigen::Vector3d(0.033, 0.033, 0.061)).norm(), 0, 1e-15);
  EXPECT_NEAR((sd.oMs.t - Eigen::Vector3d(0, 0, 0.033)).norm(), 0, 1e-15);
  // Its bottom on the table top.
  const SimObject* table = nullptr;
  for (const auto& o : s.world.objects)
    if (o.name == "table") table = &o;
  ASSERT_NE(table, nullptr);
  EXPECT_NEAR(wMs.t.z() - sd.half_m.z(), table->wMo.t.z(), 1e-3);
  // The grasp frame: on the axis, z_g and x_g horizontal.
  const Pose wMg = can.wMo * can.oMg;
  EXPECT_NEAR((wMg.t - wMs.t).head<2>().norm(), 0, 1e-3);
  EXPECT_NEAR(wMg.R.col(2).z(), 0, 1e-4);
  EXPECT_NEAR(wMg.R.col(0).z(), 0, 1e-4);
  EXPECT_GT(wMg.t.z(), wMs.t.z());  // above the middle, below the top
  EXPECT_LT(wMg.t.z(), wMs.t.z() + sd.half_m.z());
  EXPECT_TRUE(inView(bb2, startCamera(s), can.wMo.t));
  // A distractor cylinder with side and cap textures.
  int cylinders = 0;
  for (const auto& o : s.world.objects)
    if (!o.is_target && !o.cylinders.empty()) {
      ++cylinders;
      EXPECT_FALSE(o.cylinders[0].side_texture.empty());
      EXPECT_FALSE(o.cylinders[0].cap_texture.empty());
    }
  EXPECT_EQ(cylinders, 1);
}

// The can of can_table rendered by the world's renderer (renderWorld, and the stereo camera
// without degradations) is the renderer's own drawing of that cylinder at cMo = cMw wMo.
TEST(Scenario, ACanRendersAtItsWorldPoseAsTheRendererDrawsIt) {
  const Scenario s = loadScenario(kScenarios + "can_table.yaml");
  const SimObject& can = target(s);
  TexturedCylinder direct;
  direct.label = readImage(kMedia + "labels/soda_can_label.png", ImageMode::kGray).image;
  direct.radius_m = 0.033;
  direct.label_width_m = 0.2073;
  direct.label_height_m = 0.115;
  direct.height_m = 0.122;
  const Intrinsics cam = testing::sceneCamera();
  // Cameras 0.4 m from the axis, at the can's middle, looking at it from the front and 70 deg
  // round to its left, and 0.3 m above it looking down on its cap.
  const Eigen::Vector3d axis = (can.wMo * Eigen::Vector3d(0, 0, 0.033));
  std::vector<Pose> views;
  for (const double a : {0.0, 70.0 * M_PI / 180}) {
    const Eigen::Vector3d z(std::cos(a), std::sin(a), 0);  // viewing direction, horizontal
    Eigen::Matrix3d R;
    R << z.cross(Eigen::Vector3d::UnitZ()), -Eigen::Vector3d::UnitZ(), z;
    views.emplace_back(R, axis - 0.4 * z);
  }
  Eigen::Matrix3d down;
  down << 0, -1, 0, -1, 0, 0, 0, 0, -1;
  views.emplace_back(down, axis + Eigen::Vector3d(0, 0, 0.3));
  World alone;
  alone.objects = {can};
  StereoRig rig;
  rig.left = rig.right = cam;
  SyntheticStereoCamera stereo(rig, Degradation{}, 1);
  for (size_t i = 0; i < views.size(); ++i) {
    SCOPED_TRACE(i);
    direct.cMo = views[i].inverse() * can.wMo;
    const cv::Mat expected = renderView(cam, {}, {direct}, cv::Mat());
    const cv::Mat world = renderWorld(cam, alone, views[i]);
    EXPECT_EQ(cv::norm(world, expected, cv::NORM_INF), 0);
    EXPECT_EQ(cv::norm(stereo.render(alone, views[i], Twist(), 0).left, expected, cv::NORM_INF), 0);
    // The can fills a good part of the view (not a blank image compared with a blank image).
    cv::Mat drawn;
    cv::compare(expected, RenderOptions().background_gray, drawn, cv::CMP_NE);
    EXPECT_GT(cv::countNonZero(drawn), 12000);
  }
  // In the whole world, the can hides what is behind it: the same pixels around its centre.
  direct.cMo = views[0].inverse() * can.wMo;
  const cv::Mat expected = renderView(cam, {}, {direct}, cv::Mat());
  const cv::Rect centre(cam.width / 2 - 20, cam.height / 2 - 20, 40, 40);
  EXPECT_EQ(cv::norm(renderWorld(cam, s.world, views[0])(centre), expected(centre), cv::NORM_INF), 0);
}

// Each face of a box seen from outside along its outward normal shows its own texture; seen from
// inside it is culled.
TEST(Scenario, BoxFacesFaceOutwards) {
  std::array<cv::Mat, 6> tex;
  for (int i = 0; i < 6; ++i) tex[static_cast<size_t>(i)] = cv::Mat(20, 20, CV_8U, cv::Scalar(30 + 40 * i));
  const Eigen::Vector3d size(0.3, 0.2, 0.1), centre(0.1, -0.2, 0.3);
  const auto faces = boxFaces(size, centre, tex,
                              {Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ(),
                               Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitY()});
  ASSERT_EQ(faces.size(), 6u);
  const Intrinsics cam = testing::sceneCamera();
  for (int i = 0; i < 6; ++i) {
    const int axis = i / 2;
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    n[axis] = i % 2 ? 1 : -1;
    EXPECT_LT((faces[static_cast<size_t>(i)].cMp.t - (centre + n * size[axis] / 2)).norm(), 1e-12);
    // Camera 1 m outside the face, looking at the box centre (camera z = -n).
    Eigen::Matrix3d wRc;
    const Eigen::Vector3d z = -n, up = axis == 1 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitY();
    const Eigen::Vector3d x = up.cross(z).normalized();
    wRc << x, z.cross(x), z;
    const Pose wMc(wRc, centre + n * (size[axis] / 2 + 1.0));
    std::vector<TexturedPlane> planes;
    for (const auto& f : faces) planes.push_back({f.texture, f.width_m, f.height_m, wMc.inverse() * f.cMp});
    const cv::Mat img = renderView(cam, planes, cv::Mat(), RenderOptions{true, true, 0.01, 0});
    EXPECT_EQ(img.at<uchar>(240, 320), 30 + 40 * i) << "face " << i;
    // From the box centre every face is seen from inside: nothing is drawn.
    const Pose inside(wRc, centre);
    planes.clear();
    for (const auto& f : faces) planes.push_back({f.texture, f.width_m, f.height_m, inside.inverse() * f.cMp});
    EXPECT_EQ(cv::countNonZero(renderView(cam, planes, cv::Mat(), RenderOptions{true, true, 0.01, 0})), 0);
  }
}

class BadScenario : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("refgrasp_bad_scenario_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string good() const {
    return "seed: 5\n"
           "robot_start: {x: 0, y: 0, theta: 0}\n"
           "table: {size_m: [0.7, 1.2, 0.72], pose: {translation: [2, 0, 0], rotation_vector: [0, 0, 0]}, "
           "texture: " + kMedia + "backgrounds/table_wood.png}\n"
           "objects:\n"
           "  - name: box\n"
           "    target: true\n"
           "    definition: " + std::string(REFGRASP_SOURCE_DIR) + "/config/objects/cereal_box.yaml\n"
           "    shape: box\n"
           "    size_m: [0.2, 0.2, 0.07]\n"
           "    side_texture: " + kMedia + "boxes/box_side_a.png\n"
           "    faces: {front: " + kMedia + "targets/cereal_box.png}\n"
           "    pose: {translation: [1.7, 0, 0.82], rotation_vector: [-1.2092, 1.2092, -1.2092]}\n"
           "camera: {noise_sigma: 2}\n"
           "faults: {frame_drop_probability: 0.1}\n";
  }

  std::string write(const std::string& text) const {
    const std::string path = (dir_ / "s.yaml").string();
    std::ofstream(path) << text;
    return path;
  }

  // Loads `text`; expects a one-line ConfigError naming the file and containing `field` and `problem`.
  void expectError(const std::string& text, const std::string& field, const std::string& problem) {
    const std::string path = write(text);
    try {
      loadScenario(path);
      ADD_FAILURE() << "no error for field " << field;
    } catch (const ConfigError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
      EXPECT_EQ(what.rfind(path + ": ", 0), 0u) << what;
      EXPECT_NE(what.find(field), std::string::npos) << what;
      EXPECT_NE(what.find(problem), std::string::npos) << what;
    }
  }

  static std::string replace(std::string s, const std::string& from, const std::string& to) {
    const size_t pos = s.find(from);
    EXPECT_NE(pos, std::string::npos) << from;
    return pos == std::string::npos ? s : s.replace(pos, from.size(), to);
  }

  fs::path dir_;
};

TEST_F(BadScenario, TheGoodBaseLoads) {
  const Scenario s = loadScenario(write(good()));
  ASSERT_EQ(s.world.objects.size(), 2u);  // the box and the table
  EXPECT_EQ(s.world.objects[0].faces.size(), 6u);
  EXPECT_EQ(s.seed, 5u);
}

TEST_F(BadScenario, MissingFile) {
  const std::string path = (dir_ / "nope.yaml").string();
  try {
    loadScenario(path);
    ADD_FAILURE();
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), path + ": file not found");
  }
}

TEST_F(BadScenario, InvalidYaml) { expectError("seed: [1, 2\nobjects: {", "", "invalid YAML"); }

TEST_F(BadScenario, MissingFields) {
  expectError(replace(good(), "seed: 5\n", ""), "seed", "missing");
  expectError(replace(good(), "{x: 0, y: 0, theta: 0}", "{x: 0, theta: 0}"), "robot_start.y", "missing");
  expectError(replace(good(), "    shape: box\n", ""), "objects[0].shape", "missing");
  expectError(replace(good(), "    pose: {translation: [1.7, 0, 0.82], rotation_vector: [-1.2092, 1.2092, -1.2092]}\n", ""),
              "objects[0].pose", "missing");
  expectError(replace(good(), "    definition: ", "    unused: "), "objects[0].unused", "unknown field");
}

TEST_F(BadScenario, WrongTypesAndValues) {
  expectError(replace(good(), "size_m: [0.2, 0.2, 0.07]", "size_m: big"), "objects[0].size_m", "list of numbers");
  expectError(replace(good(), "size_m: [0.2, 0.2, 0.07]", "size_m: [0.2, 0.2]"), "objects[0].size_m", "expected 3 numbers");
  expectError(replace(good(), "size_m: [0.2, 0.2, 0.07]", "size_m: [0.2, -0.2, 0.07]"), "objects[0].size_m", "positive");
  expectError(replace(good(), "translation: [1.7, 0, 0.82]", "translation: [.nan, 0, 0.82]"),
              "objects[0].pose.translation", "not finite");
  expectError(replace(good(), "theta: 0}", "theta: .inf}"), "robot_start.theta", "finite");
  expectError(replace(good(), "shape: box", "shape: sphere"), "objects[0].shape", "'plane' or 'box'");
  expectError(replace(good(), "seed: 5", "seed: -1"), "seed", "non-negative integer");
  expectError(replace(good(), "frame_drop_probability: 0.1", "frame_drop_probability: 1.5"),
              "faults.frame_drop_probability", "[0, 1]");
  expectError(replace(good(), "noise_sigma: 2", "noise_sigma: -2"), "camera.noise_sigma", ">= 0");
  expectError(replace(good(), "objects:\n", "objects: []\nunused:\n"), "", "");  // any error, one line
}

TEST_F(BadScenario, MassAndSolids) {
  const std::string with_mass = replace(good(), "    shape: box\n", "    shape: box\n    mass_kg: 0.8\n");
  const Scenario s = loadScenario(write(with_mass));
  EXPECT_EQ(s.world.objects[0].mass_kg, 0.8);
  EXPECT_EQ(loadScenario(write(good())).world.objects[0].mass_kg, kDefaultObjectMassKg);
  // The box's solid spans its faces: front at z_o = 0, back at the depth.
  ASSERT_EQ(s.world.objects[0].solids.size(), 1u);
  EXPECT_NEAR((s.world.objects[0].solids[0].oMs.t - Eigen::Vector3d(0, 0, 0.035)).norm(), 0, 1e-12);
  EXPECT_NEAR((s.world.objects[0].solids[0].half_m - Eigen::Vector3d(0.1, 0.1, 0.035)).norm(), 0, 1e-12);
  // The table's block: from the floor to its top (its frame is on the top).
  EXPECT_EQ(s.world.objects[1].kind, ObjectKind::kTable);
  EXPECT_NEAR((s.world.objects[1].wMo * s.world.objects[1].solids[0].oMs).t.z(), 0.36, 1e-12);
  expectError(replace(good(), "    shape: box\n", "    shape: box\n    mass_kg: 0\n"), "objects[0].mass_kg",
              "must be positive");
  expectError(replace(good(), "    shape: box\n", "    shape: box\n    mass_kg: heavy\n"), "objects[0].mass_kg",
              "expected a number");
  expectError(replace(good(), "    shape: box\n", "    shape: box\n    mass_kg: .nan\n"), "objects[0].mass_kg",
              "finite");
}

TEST_F(BadScenario, MissingTextureAndDefinition) {
  expectError(replace(good(), "boxes/box_side_a.png", "boxes/nope.png"), "objects[0].side_texture",
              "texture file not found");
  expectError(replace(good(), "targets/cereal_box.png", "targets/nope.png"), "objects[0].faces.front",
              "texture file not found");
  expectError(replace(good(), "backgrounds/table_wood.png", "README.md"), "table.texture", "cannot read image");
  expectError(replace(good(), "config/objects/cereal_box.yaml", "config/objects/nope.yaml"),
              "objects[0].definition", "file not found");
  expectError(replace(good(), "    definition: ", "    # "), "objects[0].definition", "target needs");
}

// good() with its box replaced by a can: shape: cylinder and its fields.
std::string goodCan(const std::string& good) {
  const size_t start = good.find("    shape: box\n"), end = good.find("    pose: {translation: [1.7");
  return good.substr(0, start) +
         "    shape: cylinder\n"
         "    radius_m: 0.033\n"
         "    height_m: 0.122\n"
         "    label: " + kMedia + "labels/soda_can_label.png\n"
         "    label_size_m: [0.2073, 0.115]\n"
         "    side_texture: " + kMedia + "boxes/box_side_a.png\n"
         "    cap_texture: " + kMedia + "boxes/box_top.png\n" +
         good.substr(end);
}

TEST_F(BadScenario, ACylinderLoadsWithItsFields) {
  const Scenario s = loadScenario(write(goodCan(good())));
  const SimObject& o = s.world.objects[0];
  ASSERT_EQ(o.cylinders.size(), 1u);
  EXPECT_TRUE(o.faces.empty());
  EXPECT_EQ(o.cylinders[0].radius_m, 0.033);
  EXPECT_EQ(o.cylinders[0].height_m, 0.122);
  EXPECT_EQ(o.cylinders[0].label_width_m, 0.2073);
  EXPECT_EQ(o.cylinders[0].label_height_m, 0.115);
  EXPECT_EQ(o.cylinders[0].side_texture.size(), cv::Size(400, 300));
  EXPECT_EQ(o.cylinders[0].cap_texture.size(), cv::Size(400, 400));
  ASSERT_EQ(o.solids.size(), 1u);
  EXPECT_TRUE(o.solids[0].cylinder);
  // The solid's axis z_s along the object's y, through (0, 0, r).
  EXPECT_NEAR((o.solids[0].oMs.R.col(2) - Eigen::Vector3d::UnitY()).norm(), 0, 1e-15);
  EXPECT_NEAR((o.solids[0].oMs.t - Eigen::Vector3d(0, 0, 0.033)).norm(), 0, 1e-15);
  // Side and cap textures are optional; a label all the way round (+1 %) is allowed.
  const std::string bare = replace(replace(goodCan(good()), "    side_texture: " + kMedia + "boxes/box_side_a.png\n", ""),
                                   "    cap_texture: " + kMedia + "boxes/box_top.png\n", "");
  EXPECT_TRUE(loadScenario(write(bare)).world.objects[0].cylinders[0].side_texture.empty());
  EXPECT_NO_THROW(loadScenario(write(replace(bare, "[0.2073, 0.115]", "[0.2094, 0.115]"))));
}

TEST_F(BadScenario, CylinderFields) {
  const std::string can = goodCan(good());
  expectError(replace(can, "radius_m: 0.033", "radius_m: 0"), "objects[0].radius_m", "must be positive");
  expectError(replace(can, "radius_m: 0.033", "radius_m: -0.03"), "objects[0].radius_m", "must be positive");
  expectError(replace(can, "    radius_m: 0.033\n", ""), "objects[0].radius_m", "missing");
  expectError(replace(can, "height_m: 0.122", "height_m: 0"), "objects[0].height_m", "must be positive");
  expectError(replace(can, "height_m: 0.122", "height_m: tall"), "objects[0].height_m", "expected a number");
  expectError(replace(can, "height_m: 0.122", "height_m: .nan"), "objects[0].height_m", "finite");
  expectError(replace(can, "[0.2073, 0.115]", "[0.2073, -0.115]"), "objects[0].label_size_m", "positive");
  expectError(replace(can, "[0.2073, 0.115]", "[0.2073]"), "objects[0].label_size_m", "expected 2 numbers");
  // Wider than the circumference 2 pi r (+1 %), taller than the side.
  expectError(replace(can, "[0.2073, 0.115]", "[0.2100, 0.115]"), "objects[0].label_size_m", "circumference");
  expectError(replace(can, "[0.2073, 0.115]", "[0.2073, 0.13]"), "objects[0].label_size_m", "more than height_m");
  // Files.
  expectError(replace(can, "labels/soda_can_label.png", "labels/nope.png"), "objects[0].label", "texture file not found");
  expectError(replace(can, "labels/soda_can_label.png", "README.md"), "objects[0].label", "cannot read image");
  expectError(replace(can, "    label: ", "    # "), "objects[0].label", "missing");
  expectError(replace(can, "boxes/box_side_a.png", "boxes/nope.png"), "objects[0].side_texture", "not found");
  expectError(replace(can, "boxes/box_top.png", "boxes/nope.png"), "objects[0].cap_texture", "not found");
  // Fields of other shapes, and a cylinder's fields on a box.
  expectError(replace(can, "    shape: cylinder\n", "    shape: cylinder\n    size_m: [0.1, 0.1, 0.1]\n"),
              "objects[0].size_m", "not a field of shape 'cylinder'");
  expectError(replace(can, "    shape: cylinder\n", "    shape: cylinder\n    faces: {front: x.png}\n"),
              "objects[0].faces", "not a field of shape 'cylinder'");
  expectError(replace(good(), "    shape: box\n", "    shape: box\n    radius_m: 0.05\n"), "objects[0].radius_m",
              "not a field of shape 'box'");
  expectError(replace(good(), "    shape: box\n", "    shape: box\n    label: x.png\n"), "objects[0].label",
              "not a field of shape 'box'");
  expectError(replace(can, "    shape: cylinder\n", "    shape: cylinder\n    radius: 0.05\n"), "objects[0].radius",
              "did you mean");
}

TEST_F(BadScenario, DuplicateNames) {
  std::string text = good();
  const size_t start = text.find("  - name: box");
  const size_t end = text.find("camera:");
  text.insert(end, text.substr(start, end - start));
  expectError(text, "objects[1].name", "duplicate");
}

}  // namespace
}  // namespace refgrasp::sim
