// Object definition files: geometry of a valid definition, and one clear error per bad input.
#include <gtest/gtest.h>

#include "common/noise_image.h"
#include "common/temp_dir.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "core/error.h"
#include "detector/object.h"

using namespace refgrasp;
using namespace refgrasp::detector;
namespace fs = std::filesystem;

namespace {

fs::path testDir() {
  return refgrasp::testing::tempDir("refgrasp_test_object");
}

std::string write(const std::string& name, const std::string& text) {
  const fs::path p = testDir() / name;
  std::ofstream(p) << text;
  return p.string();
}

// 400x300 texture and a matching camera: a 0.2 m wide texture seen at 0.5 m (f = 1000).
void writeFixtures() {
  std::mt19937_64 rng(31);
  cv::imwrite((testDir() / "tex.png").string(), refgrasp::testing::noiseImage(rng, 400, 300));
  write("cam.yaml", R"(image_width: 400
image_height: 300
camera_matrix: {rows: 3, cols: 3, data: [1000, 0, 199.5, 0, 1000, 149.5, 0, 0, 1]}
distortion_model: plumb_bob
distortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}
)");
  write("cam_small.yaml", R"(image_width: 320
image_height: 240
camera_matrix: {rows: 3, cols: 3, data: [500, 0, 159.5, 0, 500, 119.5, 0, 0, 1]}
)");
  std::ofstream(testDir() / "corrupt.png") << "\x89PNG\r\n\x1a\n this is not really a png";
}

const char* kPose = "reference_pose: {translation: [0, 0, 0.5], rotation_vector: [0, 0, 0]}\n";

// Loads `yaml` and returns the ConfigError message ("" when it loaded).
std::string loadError(const std::string& name, const std::string& yaml) {
  const std::string path = write(name, yaml);
  try {
    loadObjectDefinition(path);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

class ObjectFile : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { writeFixtures(); }
};

}  // namespace

TEST_F(ObjectFile, FullDefinitionGivesTextureCorners) {
  const ObjectModel m = loadObjectDefinition(
      write("full.yaml", std::string("reference_image: tex.png\ncamera: cam.yaml\n") + kPose));
  EXPECT_EQ(m.name, "full");
  EXPECT_EQ(m.reference.cols, 400);
  EXPECT_EQ(m.reference.type(), CV_8UC1);
  ASSERT_TRUE(m.has3d());
  // DEVELOPERS.md texture convention: pixel-edge corners at (+-0.1, +-0.075, 0).
  const Eigen::Vector3d expect[4] = {{-0.1, -0.075, 0}, {0.1, -0.075, 0}, {0.1, 0.075, 0}, {-0.1, 0.075, 0}};
  for (int i = 0; i < 4; ++i) EXPECT_NEAR((m.target->corners_o[i] - expect[i]).norm(), 0, 1e-12) << i;
  EXPECT_NEAR((m.corners_px[2] - Eigen::Vector2d(399.5, 299.5)).norm(), 0, 1e-12);
  // textureObject() builds the same model in code.
  const ObjectModel t = textureObject("t", m.reference, 0.2, 0.5);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR((t.target->corners_o[i] - expect[i]).norm(), 0, 1e-12);
}

TEST_F(ObjectFile, RegionAndPlaneOptions) {
  // 4-point region: its vertices are the corners; 5 points: the bounding box.
  const ObjectModel four = loadObjectDefinition(write("four.yaml", std::string(
      "name: box\nreference_image: tex.png\ncamera: cam.yaml\n") + kPose +
      "pattern_region: [[100, 50], [300, 50], [300, 250], [100, 250]]\n"));
  EXPECT_EQ(four.name, "box");
  EXPECT_NEAR((four.target->corners_o[0] - Eigen::Vector3d(-0.04975, -0.04975, 0)).norm(), 0, 1e-12);
  const ObjectModel five = loadObjectDefinition(write("five.yaml",
      "reference_image: tex.png\npattern_region: [[100, 50], [300, 60], [320, 200], [200, 250], [90, 150]]\n"));
  EXPECT_FALSE(five.has3d());  // no reference_pose: 2D-only
  EXPECT_NEAR((five.corners_px[0] - Eigen::Vector2d(90, 50)).norm(), 0, 1e-12);
  EXPECT_NEAR((five.corners_px[2] - Eigen::Vector2d(320, 250)).norm(), 0, 1e-12);
  // A plane 2 cm in front of the object origin (n.X = offset with n = -z, offset 0.02 => z = -0.02).
  const ObjectModel off = loadObjectDefinition(write("plane.yaml", std::string(
      "reference_image: tex.png\ncamera: cam.yaml\n") + kPose +
      "pattern_plane: {normal: [0, 0, -1], offset: 0.02}\n"));
  for (const auto& X : off.target->corners_o) EXPECT_NEAR(X.z(), -0.02, 1e-12);
  EXPECT_NEAR(off.target->corners_o[2].x(), 0.1 * 0.48 / 0.5, 1e-12);
}

TEST_F(ObjectFile, RegionMayRunPastTheImage) {
  // The outline on the pixel edges and 10 px beyond the 400x300 image on every side (a cropped
  // reference): accepted, corners and 3D corners from the outline as given.
  const ObjectModel m = loadObjectDefinition(write("past.yaml", std::string(
      "reference_image: tex.png\ncamera: cam.yaml\n") + kPose +
      "pattern_region: [[-10.5, -10.5], [409.5, -10.5], [409.5, 309.5], [-10.5, 309.5]]\n"));
  ASSERT_TRUE(m.has3d());
  EXPECT_NEAR((m.corners_px[0] - Eigen::Vector2d(-10.5, -10.5)).norm(), 0, 1e-12);
  // f = 1000 px at 0.5 m: 0.5 mm per px; the corner 210 px left of the principal point 199.5.
  EXPECT_NEAR((m.target->corners_o[0] - Eigen::Vector3d(-0.105, -0.08, 0)).norm(), 0, 1e-12);
  EXPECT_NEAR((m.target->corners_o[2] - Eigen::Vector3d(0.105, 0.08, 0)).norm(), 0, 1e-12);
  // Mostly outside, a corner inside: accepted too.
  EXPECT_EQ(loadError("corner.yaml", "reference_image: tex.png\n"
                                     "pattern_region: [[300, 200], [700, 200], [700, 600], [300, 600]]\n"), "");
  // Touching the image along a pixel edge only: nothing inside, a one-line error.
  const std::string msg = loadError("beside.yaml", "reference_image: tex.png\n"
                                    "pattern_region: [[399.5, 0], [500, 0], [500, 100], [399.5, 100]]\n");
  EXPECT_NE(msg.find("beside.yaml: pattern_region: polygon lies outside the 400x300 image"), std::string::npos) << msg;
}

TEST_F(ObjectFile, BadInputsGiveOneLineErrorsNamingFileAndField) {
  struct Case {
    std::string name, yaml, field;
  };
  const std::string base = "reference_image: tex.png\ncamera: cam.yaml\n";
  const std::vector<Case> cases = {
      {"invalid.yaml", "reference_image: [tex.png\n", "invalid YAML"},
      {"no_image.yaml", "camera: cam.yaml\n", "reference_image"},
      {"missing_image.yaml", "reference_image: nothere.png\n", "reference_image"},
      {"corrupt_image.yaml", "reference_image: corrupt.png\n", "reference_image"},
      {"pose_no_camera.yaml", std::string("reference_image: tex.png\n") + kPose, "camera"},
      {"camera_missing.yaml", "reference_image: tex.png\ncamera: nocam.yaml\n", "camera"},
      {"camera_size.yaml", "reference_image: tex.png\ncamera: cam_small.yaml\n", "camera"},
      {"pose_nan.yaml", base + "reference_pose: {translation: [0, .nan, 0.5], rotation_vector: [0, 0, 0]}\n",
       "reference_pose.translation"},
      {"pose_short.yaml", base + "reference_pose: {translation: [0, 0.5], rotation_vector: [0, 0, 0]}\n",
       "reference_pose.translation"},
      {"region_two.yaml", base + "pattern_region: [[0, 0], [10, 10]]\n", "pattern_region"},
      {"region_cross.yaml", base + "pattern_region: [[0, 0], [100, 100], [100, 0], [0, 100]]\n",
       "pattern_region"},
      {"region_outside.yaml", base + "pattern_region: [[450, 0], [600, 0], [500, 100]]\n", "pattern_region"},
      {"region_nan.yaml", base + "pattern_region: [[0, 0], [.nan, 0], [100, 100]]\n", "pattern_region[1]"},
      {"region_shape.yaml", base + "pattern_region: [[0, 0, 1], [10, 0], [10, 10]]\n", "pattern_region[0]"},
      {"region_text.yaml", base + "pattern_region: [[0, 0], [a, 0], [10, 10]]\n", "pattern_region[1]"},
      {"normal_zero.yaml", base + kPose + "pattern_plane: {normal: [0, 0, 0], offset: 0}\n",
       "pattern_plane.normal"},
      {"plane_behind.yaml", base + kPose + "pattern_plane: {normal: [0, 0, 1], offset: -1.0}\n",
       "pattern_plane"},
      {"plane_nan.yaml", base + kPose + "pattern_plane: {normal: [0, 0, 1], offset: .nan}\n",
       "pattern_plane.offset"},
  };
  for (const Case& c : cases) {
    const std::string msg = loadError(c.name, c.yaml);
    ASSERT_FALSE(msg.empty()) << c.name << " loaded";
    EXPECT_NE(msg.find(c.name), std::string::npos) << msg;
    EXPECT_NE(msg.find(c.field), std::string::npos) << c.name << ": " << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
  try {
    loadObjectDefinition((testDir() / "does_not_exist.yaml").string());
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("does_not_exist.yaml: file not found"), std::string::npos);
  }
}

TEST(ShippedObjects, EveryDefinitionLoadsWith3dCorners) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(fs::path(REFGRASP_SOURCE_DIR) / "config/objects")) {
    if (e.path().extension() != ".yaml" || e.path().stem().string().find("_camera") != std::string::npos)
      continue;
    const ObjectModel m = loadObjectDefinition(e.path().string());
    ++n;
    EXPECT_EQ(m.name, e.path().stem().string());
    // *_2d.yaml: a 2D-only definition by design (a photo and its pattern region, no measured
    // pose: how a user starts on their own footage); it loads, without 3D geometry.
    if (e.path().stem().string().size() > 3 &&
        e.path().stem().string().compare(e.path().stem().string().size() - 3, 3, "_2d") == 0) {
      EXPECT_FALSE(m.hasPose()) << e.path();
      continue;
    }
    ASSERT_TRUE(m.hasPose()) << e.path();
    const std::string stem = e.path().stem().string();
    // A several-view box of scripts/make_shape_scenarios.py (five faces) or the clip's box of
    // scripts/make_box_video.sh (box_video: front and top), each face a shipped definition of
    // its own (checked by this loop).
    if (m.isMultiView()) {
      EXPECT_EQ(m.views.size(), stem == "box_video" ? 2u : 5u) << e.path();
      continue;
    }
    ASSERT_TRUE(m.has3d()) << e.path();
    // Shipped objects are 0.2 m wide textures: corners 0.2 m apart in x. The photo_* targets of
    // scripts/make_grasp_scenarios.py have faces 16-22 cm wide, the box faces of
    // scripts/make_shape_scenarios.py 12-18 cm; a cylinder's flat label is its label's width, at
    // most the circumference; the clip's box (box_video_*) is 0.25 m wide.
    const double width = (m.target->corners_o[1] - m.target->corners_o[0]).norm();
    if (m.isCylinder()) {
      EXPECT_NEAR(width, m.cylinder->width_m, 1e-9) << e.path();
      EXPECT_LE(width, 2 * M_PI * m.cylinder->radius_m * 1.01) << e.path();
    } else if (stem.rfind("photo_", 0) == 0) {
      EXPECT_GE(width, 0.16 - 1e-6) << e.path();
      EXPECT_LE(width, 0.22 + 1e-6) << e.path();
    } else if (stem.rfind("box_video_", 0) == 0) {
      EXPECT_NEAR(width, 0.25, 1e-4) << e.path();  // corners clicked, posed by PnP: 0.01 px RMS
    } else if (stem.rfind("box_", 0) == 0) {
      EXPECT_GE(width, 0.12 - 1e-6) << e.path();
      EXPECT_LE(width, 0.18 + 1e-6) << e.path();
    } else {
      EXPECT_NEAR(width, 0.2, 1e-9) << e.path();
    }
  }
  EXPECT_GE(n, 5);
}

TEST_F(ObjectFile, CylinderDefinitionAsDocumented) {
  // The documented example, with the test's 400x300 texture as the label.
  const ObjectModel m = loadObjectDefinition(write("soda_can.yaml", R"(name: soda_can
reference_image: tex.png   # the label unrolled flat
cylinder:
  radius_m: 0.033
  label_size_m: [0.2073, 0.115]
)"));
  ASSERT_TRUE(m.isCylinder());
  EXPECT_FALSE(m.isMultiView());
  EXPECT_EQ(m.name, "soda_can");
  EXPECT_DOUBLE_EQ(m.cylinder->radius_m, 0.033);
  EXPECT_DOUBLE_EQ(m.cylinder->width_m, 0.2073);
  EXPECT_DOUBLE_EQ(m.cylinder->height_m, 0.115);
  EXPECT_EQ(m.cylinder->image_width, 400);
  EXPECT_EQ(m.cylinder->image_height, 300);
  EXPECT_TRUE(m.cylinder->fullWrap());  // 0.2073 m is 2 pi 0.033 m
  // The planar approximation: the flat label on the tangent plane z = 0, corners at (+-w/2, +-h/2).
  ASSERT_TRUE(m.has3d());
  const std::array<Eigen::Vector3d, 4> want = {Eigen::Vector3d(-0.10365, -0.0575, 0), Eigen::Vector3d(0.10365, -0.0575, 0),
                                               Eigen::Vector3d(0.10365, 0.0575, 0), Eigen::Vector3d(-0.10365, 0.0575, 0)};
  for (int i = 0; i < 4; ++i) EXPECT_NEAR((m.target->corners_o[i] - want[i]).norm(), 0, 1e-9) << i;
}

TEST_F(ObjectFile, SeveralViewDefinitionAsDocumented) {
  write("front.yaml", std::string("name: tea_box_front\nreference_image: tex.png\ncamera: cam.yaml\n") + kPose);
  write("left.yaml", std::string("name: tea_box_left\nreference_image: tex.png\ncamera: cam.yaml\n") + kPose);
  write("can.yaml", "name: can\nreference_image: tex.png\ncylinder: {radius_m: 0.05, label_size_m: [0.2, 0.15]}\n");
  const ObjectModel m = loadObjectDefinition(write("tea_box.yaml", R"(name: tea_box
views:
  - definition: front.yaml
    oMv: {translation: [0, 0, 0], rotation_vector: [0, 0, 0]}
  - definition: left.yaml
    oMv: {translation: [-0.1, 0, 0.035], rotation_vector: [0, 1.5708, 0]}
  - definition: can.yaml
    oMv: {translation: [0, 0.2, 0], rotation_vector: [0, 0, 0]}
)"));
  ASSERT_TRUE(m.isMultiView());
  ASSERT_EQ(m.views.size(), 3u);
  EXPECT_EQ(m.views[0].name, "tea_box_front");
  EXPECT_EQ(m.views[1].name, "tea_box_left");
  EXPECT_TRUE(m.views[2].model->isCylinder());
  EXPECT_NEAR((m.views[1].oMv.t - Eigen::Vector3d(-0.1, 0, 0.035)).norm(), 0, 1e-12);
  EXPECT_NEAR(m.views[1].oMv.rotationVector().y(), 1.5708, 1e-12);
  EXPECT_TRUE(m.views[0].model->has3d());
}

TEST_F(ObjectFile, BadCylindersAndViewsGiveOneLineErrorsNamingFileAndField) {
  write("flat.yaml", "name: flat\nreference_image: tex.png\n");  // 2D-only: no metric geometry
  write("good.yaml", std::string("name: good\nreference_image: tex.png\ncamera: cam.yaml\n") + kPose);
  write("cycle_b.yaml", "views:\n  - {definition: cycle_a.yaml, oMv: {translation: [0, 0, 0], rotation_vector: [0, 0, 0]}}\n");
  const std::string id = ", oMv: {translation: [0, 0, 0], rotation_vector: [0, 0, 0]}}\n";
  struct Case {
    std::string name, yaml, field;
  };
  const std::vector<Case> cases = {
      {"r_zero.yaml", "reference_image: tex.png\ncylinder: {radius_m: 0, label_size_m: [0.1, 0.1]}\n",
       "cylinder.radius_m"},
      {"r_negative.yaml", "reference_image: tex.png\ncylinder: {radius_m: -0.03, label_size_m: [0.1, 0.1]}\n",
       "cylinder.radius_m"},
      {"too_wide.yaml", "reference_image: tex.png\ncylinder: {radius_m: 0.03, label_size_m: [0.2, 0.1]}\n",
       "cylinder.label_size_m"},
      {"size_one.yaml", "reference_image: tex.png\ncylinder: {radius_m: 0.03, label_size_m: [0.1]}\n",
       "cylinder.label_size_m"},
      {"no_radius.yaml", "reference_image: tex.png\ncylinder: {label_size_m: [0.1, 0.1]}\n", "cylinder.radius_m"},
      {"cyl_typo.yaml", "reference_image: tex.png\ncylinder: {radius_m: 0.03, label_size: [0.1, 0.1]}\n",
       "cylinder.label_size"},
      {"cyl_pose.yaml", std::string("reference_image: tex.png\ncamera: cam.yaml\n") + kPose +
                            "cylinder: {radius_m: 0.03, label_size_m: [0.1, 0.1]}\n",
       "camera"},
      {"views_empty.yaml", "views: []\n", "views"},
      {"views_missing.yaml", "views:\n  - {definition: nothere.yaml" + id, "views[0].definition"},
      {"views_2d.yaml", "views:\n  - {definition: good.yaml" + id + "  - {definition: flat.yaml" + id,
       "views[1].definition"},
      {"views_self.yaml", "views:\n  - {definition: views_self.yaml" + id, "views[0].definition"},
      {"cycle_a.yaml", "views:\n  - {definition: cycle_b.yaml" + id, "views[0].definition"},
      {"views_twice.yaml", "views:\n  - {definition: good.yaml" + id + "  - {definition: good.yaml" + id,
       "views[1].definition"},
      {"views_no_pose.yaml", "views:\n  - {definition: good.yaml}\n", "views[0].oMv"},
      {"views_bad_pose.yaml",
       "views:\n  - {definition: good.yaml, oMv: {translation: [0, .nan, 0], rotation_vector: [0, 0, 0]}}\n",
       "views[0].oMv.translation"},
      {"views_extra.yaml", "reference_image: tex.png\nviews:\n  - {definition: good.yaml" + id, "reference_image"},
  };
  for (const Case& c : cases) {
    const std::string msg = loadError(c.name, c.yaml);
    ASSERT_FALSE(msg.empty()) << c.name << " loaded";
    EXPECT_EQ(msg.rfind(testDir().string(), 0), 0u) << msg;  // the file comes first
    EXPECT_NE(msg.find(c.name), std::string::npos) << msg;
    EXPECT_NE(msg.find(c.field), std::string::npos) << c.name << ": " << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
}
