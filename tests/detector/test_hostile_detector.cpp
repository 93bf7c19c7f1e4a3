// Hostile detector inputs: option files asking for counts that would hang a frame, keys
// given twice or mistyped; object files whose pattern region would make the simplicity test
// quadratic in a huge polygon; reference images that are bombs. One line, at start-up.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "common/hostile.h"
#include "common/temp_dir.h"
#include "core/error.h"
#include "detector/detector_config.h"
#include "detector/object.h"

using namespace refgrasp;
using namespace refgrasp::detector;

namespace {

std::string write(const std::string& name, const std::string& text) {
  const auto p = refgrasp::testing::tempDir("refgrasp_test_hostile_detector") / name;
  std::ofstream(p, std::ios::binary) << text;
  return p.string();
}

std::string optionsError(const std::string& yaml) {
  const std::string p = write("options.yaml", yaml);
  return refgrasp::testing::configErrorOf([&] { loadDetectorOptions(p); }).substr(p.size() + 2);
}

const std::string kSource = REFGRASP_SOURCE_DIR;
const std::string kHead = "reference_image: " + kSource + "/media/targets/cereal_box.png\ncamera: " + kSource +
                          "/config/objects/cereal_box_camera.yaml\n"
                          "reference_pose: {translation: [0, 0, 0.5], rotation_vector: [0, 0, 0]}\n";

std::string objectError(const std::string& extra) {
  const std::string p = write("object.yaml", kHead + extra);
  return refgrasp::testing::configErrorOf([&] { loadObjectDefinition(p); }).substr(p.size() + 2);
}

}  // namespace

TEST(HostileDetectorOptions, CountsThatWouldHangAFrameAreBounded) {
  EXPECT_EQ(optionsError("dense: {max_iterations: 2000000000}\n"), "dense.max_iterations: must be at most 10000");
  EXPECT_EQ(optionsError("pose_options: {refined_lm_iterations: 1e9}\n"),
            "pose_options.refined_lm_iterations: must be at most 10000");
  EXPECT_EQ(optionsError("match: {max_instances: 100000}\n"), "match.max_instances: must be at most 100");
  EXPECT_EQ(optionsError("match: {max_hypotheses: 1e9}\n"), "match.max_hypotheses: must be at most 100000");
  EXPECT_EQ(optionsError("dense: {pose_grid: 100000}\n"), "dense.pose_grid: must be at most 64");
  EXPECT_EQ(optionsError("sift: {threads: 100000}\n"), "sift.threads: must be at most 256");
  EXPECT_EQ(optionsError("match: {min_inlirs: 5}\n"), "match.min_inlirs: unknown field (did you mean min_inliers?)");
  EXPECT_EQ(optionsError("matching: {min_inliers: 5}\n"), "matching: unknown field (did you mean match?)");
  EXPECT_EQ(optionsError("pose: paper\npose: refined\n"), "pose: given twice (lines 1 and 2)");
}

TEST(HostileObjectFile, EveryFieldIsCheckedStrictly) {
  EXPECT_EQ(objectError("referance_pose: {}\n"), "referance_pose: unknown field (did you mean reference_pose?)");
  EXPECT_EQ(objectError("pattern_plane: {normal: [0, 0, 1], ofset: 0}\n"),
            "pattern_plane.ofset: unknown field (did you mean offset?)");
  EXPECT_EQ(objectError("pattern_plane: 3\n"), "pattern_plane: expected a mapping");
  EXPECT_EQ(objectError("name: a\nname: b\n"), "name: given twice (lines 4 and 5)");
  std::string region = "pattern_region: [";
  for (int i = 0; i < 5000; ++i) region += (i ? ", [" : "[") + std::to_string(i % 400) + ", 1]";
  EXPECT_EQ(objectError(region + "]\n"), "pattern_region: 5000 points, more than the limit of 1000");
  EXPECT_EQ(objectError("pattern_region: [[0, 0], [10, 0], [[1], 2]]\n"), "pattern_region[2]: expected two numbers");
  // makeObjectModel (objects built in code) holds the same bound.
  std::vector<Eigen::Vector2d> big(2000, Eigen::Vector2d(1, 1));
  EXPECT_NE(refgrasp::testing::configErrorOf([&] {
              makeObjectModel("x", cv::Mat(10, 10, CV_8UC1, cv::Scalar(0)), std::nullopt, std::nullopt, big);
            }).find("pattern_region: 2000 points"),
            std::string::npos);
}
