#include <gtest/gtest.h>

#include "common/temp_dir.h"

#include <cmath>
#include <filesystem>
#include <fstream>

#include "core/camera.h"
#include "core/error.h"
#include "core/pose.h"
#include "core/yaml.h"

using namespace refgrasp;
namespace fs = std::filesystem;

namespace {
std::string writeTemp(const std::string& name, const std::string& text) {
  const fs::path dir = refgrasp::testing::tempDir("refgrasp_test_core");
  const fs::path p = dir / name;
  std::ofstream(p) << text;
  return p.string();
}
}  // namespace

TEST(Pose, ComposeInverseAndRotationVector) {
  const Pose aMb = Pose::fromRotationVector({0.1, -0.2, 0.3}, {1, 2, 3});
  const Pose bMc = Pose::fromRotationVector({-0.4, 0.0, 0.2}, {0.5, 0, -1});
  const Eigen::Vector3d x(0.3, -0.7, 2.0);
  EXPECT_NEAR(((aMb * bMc) * x - aMb * (bMc * x)).norm(), 0, 1e-12);
  EXPECT_NEAR(((aMb * aMb.inverse()).t).norm(), 0, 1e-12);
  EXPECT_NEAR((aMb.rotationVector() - Eigen::Vector3d(0.1, -0.2, 0.3)).norm(), 0, 1e-12);
  EXPECT_NEAR(rotationError(aMb, Pose::fromRotationVector({0.1, -0.2, 0.3 + 1e-3}, {1, 2, 3})),
              1e-3 * 0.3 / std::sqrt(0.14), 2e-4);
}

TEST(Intrinsics, DistortionRoundTrip) {
  Intrinsics c = Intrinsics::pinhole(640, 480, 550, 319.5, 239.5);
  c.dist = {-0.28, 0.09, 0.001, -0.0005, -0.01};
  for (double u = 0; u < 640; u += 97)
    for (double v = 0; v < 480; v += 71) {
      const Eigen::Vector2d xn = c.undistortToNormalized({u, v});
      EXPECT_NEAR((c.distortNormalized(xn) - Eigen::Vector2d(u, v)).norm(), 0, 1e-6);
    }
}

TEST(CameraFile, RosYamlAndVispXmlAgree) {
  const std::string ros = writeTemp("cam.yaml", R"(image_width: 640
image_height: 480
camera_name: left
camera_matrix: {rows: 3, cols: 3, data: [550, 0, 320.5, 0, 551, 240.25, 0, 0, 1]}
distortion_model: plumb_bob
distortion_coefficients: {rows: 1, cols: 5, data: [-0.1, 0, 0, 0, 0]}
)");
  const std::string xml = writeTemp("cam.xml", R"(<?xml version="1.0"?>
<root><camera><name>left</name><image_width>640</image_width><image_height>480</image_height>
<model><type>perspectiveProjWithoutDistortion</type><px>549</px><py>550</py><u0>320</u0><v0>240</v0></model>
<model><type>perspectiveProjWithDistortion</type><px>550</px><py>551</py><u0>320.5</u0><v0>240.25</v0>
<kud>-0.1</kud><kdu>0.1</kdu></model></camera></root>
)");
  const Intrinsics a = loadCameraFile(ros), b = loadCameraFile(xml);
  EXPECT_EQ(a.width, b.width);
  EXPECT_DOUBLE_EQ(a.fx, b.fx);
  EXPECT_DOUBLE_EQ(a.fy, b.fy);
  EXPECT_DOUBLE_EQ(a.cx, b.cx);
  EXPECT_DOUBLE_EQ(a.cy, b.cy);
  EXPECT_DOUBLE_EQ(a.dist[0], b.dist[0]);
  // Saving and re-reading is lossless.
  const std::string again = writeTemp("again.yaml", "");
  saveCameraFile(again, a, "left");
  const Intrinsics c = loadCameraFile(again);
  EXPECT_DOUBLE_EQ(c.cy, a.cy);
  EXPECT_DOUBLE_EQ(c.dist[0], a.dist[0]);
}

TEST(CameraFile, BadInputsGiveOneLineErrorsNamingFileAndField) {
  const auto expectError = [](const std::string& path, const std::string& needle) {
    try {
      loadCameraFile(path);
      FAIL() << "no error for " << path;
    } catch (const ConfigError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(path), std::string::npos) << msg;
      EXPECT_NE(msg.find(needle), std::string::npos) << msg;
      EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    }
  };
  expectError("/nonexistent/cam.yaml", "file not found");
  expectError(writeTemp("bad1.yaml", "image_width: [\n"), "invalid YAML");
  expectError(writeTemp("bad2.yaml", "image_width: 640\nimage_height: 480\n"), "camera_matrix.data");
  expectError(writeTemp("bad3.yaml",
                        "image_width: 640\nimage_height: 480\ncamera_matrix: {data: [1,0,0,0,1]}\n"),
              "expected 9 numbers");
  expectError(writeTemp("bad4.yaml", "image_width: -3\nimage_height: 480\n"), "image_width");
  expectError(writeTemp("bad5.yaml",
                        "image_width: 640\nimage_height: 480\ncamera_matrix: {data: [.nan,0,0,0,1,0,0,0,1]}\n"),
              "not finite");
  expectError(writeTemp("bad.xml", "<root></root>"), "no <camera>");
  expectError(writeTemp("kb.xml", "<root><camera><image_width>640</image_width><image_height>480"
                                  "</image_height><model><type>ProjWithKannalaBrandtDistortion"
                                  "</type></model></camera></root>"),
              "unsupported projection model");
  expectError(writeTemp("bad2.xml", "<root><camera><image_width>640</image_width><image_height>480"
                                    "</image_height><model><type>perspectiveProjWithoutDistortion</type><px>abc"
                                    "</px></model></camera></root>"),
              "px");
}

TEST(StereoRig, LoadsEyesRelativeToRigFile) {
  writeTemp("l.yaml", "image_width: 640\nimage_height: 480\ncamera_matrix: {data: [550,0,320,0,550,240,0,0,1]}\n");
  writeTemp("r.yaml", "image_width: 640\nimage_height: 480\ncamera_matrix: {data: [552,0,321,0,552,241,0,0,1]}\n");
  const std::string rig = writeTemp("rig.yaml", R"(left: l.yaml
right: r.yaml
right_in_left: {translation: [0.12, 0, 0], rotation_vector: [0, 0, 0]}
)");
  const StereoRig r = loadStereoRig(rig);
  EXPECT_DOUBLE_EQ(r.baseline(), 0.12);
  EXPECT_DOUBLE_EQ(r.right.fx, 552);
  const std::string bad = writeTemp("rig_bad.yaml", "left: l.yaml\nright: missing.yaml\nright_in_left: {translation: [0.12,0,0], rotation_vector: [0,0,0]}\n");
  try {
    loadStereoRig(bad);
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("right"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("missing.yaml"), std::string::npos);
  }
}
