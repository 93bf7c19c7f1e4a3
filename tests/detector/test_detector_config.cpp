// Detector options from YAML: the shipped config/detector.yaml is complete, documented and equal
// to the defaults; every bad file gives one line "<file>: <field>: <problem>"; a value in the file
// changes what the detector does.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <fstream>
#include <regex>
#include <sstream>

#include "robot/sim/synthetic_scene.h"
#include "common/temp_dir.h"
#include "core/error.h"
#include "detector/detector_config.h"

using namespace refgrasp;
using namespace refgrasp::detector;

namespace {

const std::string kShipped = std::string(REFGRASP_SOURCE_DIR) + "/config/detector.yaml";

std::string write(const std::string& name, const std::string& text) {
  const std::string p = (refgrasp::testing::tempDir("refgrasp_test_detector_config") / name).string();
  std::ofstream(p) << text;
  return p;
}

// The ConfigError message of loading `yaml` ("" when it loaded).
std::string loadError(const std::string& name, const std::string& yaml) {
  const std::string path = write(name, yaml);
  try {
    loadDetectorOptions(path);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(DetectorConfig, ShippedFileHoldsEveryFieldDocumentedWithTheDefaults) {
  const DetectorOptions loaded = loadDetectorOptions(kShipped);
  const auto values = detectorOptionValues(loaded);
  EXPECT_EQ(values, detectorOptionValues(DetectorOptions{}));
  ASSERT_GE(values.size(), 38u);
  // Every field is written in the file (not left to the default) ...
  const YAML::Node root = YAML::LoadFile(kShipped);
  for (const auto& [field, value] : values) {
    const size_t dot = field.find('.');
    const YAML::Node n = dot == std::string::npos ? root[field]
                                                  : root[field.substr(0, dot)][field.substr(dot + 1)];
    EXPECT_TRUE(n.IsDefined() && n.IsScalar()) << field;
  }
  // ... and every line that sets a field carries a comment.
  std::ifstream in(kShipped);
  const std::regex field_line(R"(^\s*[a-z_0-9]+:\s*[^\s#].*$)");
  int lines = 0;
  for (std::string line; std::getline(in, line);) {
    if (!std::regex_match(line, field_line)) continue;
    ++lines;
    EXPECT_NE(line.find('#'), std::string::npos) << line;
  }
  EXPECT_EQ(lines, static_cast<int>(values.size()));
}

TEST(DetectorConfig, ASubsetKeepsTheOtherDefaults) {
  const DetectorOptions o = loadDetectorOptions(
      write("subset.yaml", "match: {matcher: ratio, min_inliers: 20, seed: 7}\npose: paper\n"
                           "dense:\n  enabled: false\n"));
  EXPECT_EQ(o.match.matcher, MatcherType::kRatio);
  EXPECT_EQ(o.match.min_inliers, 20);
  EXPECT_EQ(o.match.seed, 7u);
  EXPECT_EQ(o.pose, PoseMethod::kPaper);
  EXPECT_FALSE(o.dense.enabled);
  EXPECT_EQ(o.match.global_ratio, MatchOptions{}.global_ratio);
  EXPECT_EQ(o.sift.octave_layers, SiftOptions{}.octave_layers);
}

TEST(DetectorConfig, BadFilesGiveOneLineErrorsNamingTheField) {
  struct Case {
    std::string name, yaml, expect;  // expect: "<field>: <problem>" after "<file>: "
  };
  const std::vector<Case> cases = {
      {"typo.yaml", "match: {min_inlirs: 5}\n", "match.min_inlirs: unknown field"},
      {"section.yaml", "matching: {min_inliers: 5}\n", "matching: unknown field"},
      {"not_map.yaml", "match: 5\n", "match: expected a mapping"},
      {"type.yaml", "match: {min_inliers: many}\n", "match.min_inliers: expected a number"},
      {"fraction.yaml", "match: {min_inliers: 12.5}\n", "match.min_inliers: expected an integer"},
      {"bool.yaml", "sift: {upsample: maybe}\n", "sift.upsample: expected true or false"},
      {"enum.yaml", "pose: fast\n", "pose: expected paper or refined, got 'fast'"},
      {"matcher.yaml", "match: {matcher: [paper]}\n", "match.matcher: expected a string"},
      {"nan.yaml", "match: {global_ratio: .nan}\n", "match.global_ratio: must be finite"},
      {"inf.yaml", "sanity: {max_distance_m: .inf}\n", "sanity.max_distance_m: must be finite"},
      {"range.yaml", "match: {global_ratio: 1.5}\n", "match.global_ratio: must be in (0, 1]"},
      {"range2.yaml", "sanity: {max_distance_m: 0.1}\n",
       "sanity.max_distance_m: must be finite and > min_distance_m"},
      {"range3.yaml", "dense: {gauss_filter_size: 4}\n", "dense.gauss_filter_size: must be odd and >= 1"},
      {"range3b.yaml", "dense: {normalize_sigma_px: 100}\n", "dense.normalize_sigma_px: must be in [0, 64] (0: off)"},
      {"range3c.yaml", "verify: {realign_trusted_correlation: 1.2}\n", "verify.realign_trusted_correlation: must be in [0, 1] (1: never)"},
      {"range3e.yaml", "verify: {realign_min_in_view: -0.1}\n", "verify.realign_min_in_view: must be in [0, 1] (0: always)"},
      {"range3i.yaml", "verify: {realign_verified_correlation: 1.5}\n",
       "verify.realign_verified_correlation: must be in [-1, 1.01] (1.01: never)"},
      {"range3j.yaml", "verify: {realign_verified_cells: 10}\n", "verify.realign_verified_cells: must be in [0, 9]"},
      {"range3k.yaml", "verify: {periodic_min_strong_cells: -1}\n", "verify.periodic_min_strong_cells: must be in [0, 9]"},
      {"bool2.yaml", "verify: {spare_candidate: 2}\n", "verify.spare_candidate: expected true or false"},
      {"bool3.yaml", "verify: {period_rematch: maybe}\n", "verify.period_rematch: expected true or false"},
      {"weak_regions.yaml", "match: {weak_regions: 9}\n", "match.weak_regions: must be in [0, 4]"},
      {"weak_contrast.yaml", "match: {weak_contrast_threshold: 0}\n", "match.weak_contrast_threshold: must be in (0, 1)"},
      {"range2b.yaml", "sanity: {max_pose_gap_px: 0}\n", "sanity.max_pose_gap_px: must be in (0, 1e9] (1e9: never)"},
      {"range3d.yaml", "verify: {period_ambiguity_cells: 11}\n", "verify.period_ambiguity_cells: must be in [1, 10] (10: never)"},
      {"fraction2.yaml", "verify: {period_ambiguity_cells: 2.5}\n", "verify.period_ambiguity_cells: expected an integer"},
      {"nan2.yaml", "verify: {period_ambiguity_margin: .nan}\n", "verify.period_ambiguity_margin: must be finite"},
      {"range3e.yaml", "verify: {period_switch_correlation: 2}\n", "verify.period_switch_correlation: must be in [-1, 1.01] (1.01: never)"},
      {"range3h.yaml", "verify: {max_feature_pose_rms_px: 0}\n", "verify.max_feature_pose_rms_px: must be in (0, 1000] (1000: never)"},
      {"range4.yaml", "pose_options: {huber_px: -1}\n", "pose_options.huber_px: must be finite and >= 0"},
      {"range6.yaml", "multiview: {max_gap_fraction: 2}\n", "multiview.max_gap_fraction: must be in [0, 1]"},
      {"range6b.yaml", "multiview: {max_rotation_gap_rad: -0.1}\n", "multiview.max_rotation_gap_rad: must be in [0, pi]"},
      {"range6c.yaml", "multiview: {max_gap_m: .inf}\n", "multiview.max_gap_m: must be"},
      {"range5.yaml", "sift: {octave_layers: 0}\n", "sift.octave_layers: must be in [1, 10]"},
      {"seed.yaml", "match: {seed: -1}\n", "match.seed: expected an integer in [0, 2^53]"},
      {"empty_value.yaml", "match:\n  min_inliers:\n", "match.min_inliers: no value"},
      {"invalid.yaml", "match: {min_inliers: [12\n", "invalid YAML"},
  };
  for (const Case& c : cases) {
    const std::string msg = loadError(c.name, c.yaml);
    const std::string path = (refgrasp::testing::tempDir("refgrasp_test_detector_config") / c.name).string();
    EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << c.name << ": " << msg;
    EXPECT_NE(msg.find(c.expect), std::string::npos) << c.name << ": " << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
  try {
    loadDetectorOptions("/nonexistent/detector.yaml");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_STREQ(e.what(), "/nonexistent/detector.yaml: file not found");
  }
}

TEST(DetectorConfig, AValueInTheFileChangesTheDetector) {
  const cv::Mat tex = refgrasp::testing::loadMedia("targets/poster_concert.png");
  refgrasp::testing::SceneSpec spec;
  spec.cMo = Pose::fromRotationVector({0.2, -0.1, 0.1}, {0.0, 0.02, 0.6});
  spec.seed = 31;
  const cv::Mat img = refgrasp::testing::renderTarget(refgrasp::testing::sceneCamera(), tex, 0.2, 0.2 * tex.rows / tex.cols, spec).image;
  Detector shipped(loadDetectorOptions(kShipped)), capped(loadDetectorOptions(write(
      "capped.yaml", "sift:\n  max_features: 150  # the strongest 150 scene keypoints\n")));
  shipped.addObject(textureObject("poster", tex, 0.2));
  capped.addObject(textureObject("poster", tex, 0.2));
  const DetectionResult a = shipped.detect(img, refgrasp::testing::sceneCamera());
  const DetectionResult b = capped.detect(img, refgrasp::testing::sceneCamera());
  EXPECT_GT(a.scene_features, 1000);
  EXPECT_EQ(b.scene_features, 150);
  EXPECT_TRUE(a.find(0));
}
