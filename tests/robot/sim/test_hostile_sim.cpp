// Hostile values in the simulator's inputs: a scenario or robot model asking for a
// blur, a duration, a period or a count that would overflow, hang or exhaust memory is refused at
// start-up with one line naming the file and field; a blur computed at run time is clamped.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "common/hostile.h"
#include "common/temp_dir.h"
#include "core/error.h"
#include "robot/enon_model.h"
#include "robot/sim/degrade.h"
#include "robot/sim/scenario.h"

namespace refgrasp::sim {
namespace {

namespace fs = std::filesystem;
const std::string kSource = REFGRASP_SOURCE_DIR;

fs::path scratch() { return refgrasp::testing::tempDir("refgrasp_test_hostile_sim"); }

std::string scenarioError(const std::string& from, const std::string& to) {
  const std::string p = testing::shippedVariant("config/scenarios/table_single.yaml", scratch() / "s.yaml", from, to);
  return testing::configErrorOf([&] { loadScenario(p); }).substr(p.size() + 2);
}

std::string enonError(const std::string& from, const std::string& to) {
  const std::string p = testing::shippedVariant("config/enon.yaml", scratch() / "enon.yaml", from, to);
  return testing::configErrorOf([&] { robot::loadEnonModel(p); }).substr(p.size() + 2);
}

}  // namespace

TEST(HostileSim, AHugeMotionBlurIsClampedNotASignedOverflow) {
  // 5e9 px: cast to int, that length would overflow (undefined behaviour) and ask for a
  // (2^31 x 2^31) kernel; clamped to kMaxMotionBlurPx it is the longest kernel.
  const cv::Mat k = motionBlurKernel(5e9, 0.3);
  const cv::Mat k_max = motionBlurKernel(kMaxMotionBlurPx, 0.3);
  ASSERT_EQ(k.size(), k_max.size());
  EXPECT_LE(k.cols, 2 * 130 + 1);
  EXPECT_NEAR(cv::sum(k)[0], 1.0, 1e-5);
  EXPECT_EQ(cv::norm(k, k_max, cv::NORM_INF), 0.0);
  EXPECT_EQ(motionBlurKernel(std::numeric_limits<double>::quiet_NaN(), 0).size(), cv::Size(1, 1));
  Degradation d;
  d.motion_blur_px = 257;
  EXPECT_THROW(d.check(), std::invalid_argument);
}

TEST(HostileSim, ScenarioValuesThatWouldHangOrExhaustAreRefusedAtLoad) {
  EXPECT_EQ(scenarioError("noise_sigma: 2.0", "noise_sigma: 2.0\n  motion_blur_px: 1e10"),
            "camera.motion_blur_px: must be at most 256");
  EXPECT_EQ(scenarioError("max_duration_s: 120", "max_duration_s: 1e12"), "max_duration_s: must be in (0, 3600] s");
  EXPECT_EQ(scenarioError("noise_sigma: 2.0", "noise_sigma: 1e6"), "camera.noise_sigma: must be at most 255");
  EXPECT_EQ(scenarioError("exposure_s: 0.01", "exposure_s: 50"), "camera.exposure_s: must be at most 1");
  EXPECT_EQ(scenarioError("camera:", "faults: {command_latency_s: 1e9}\ncamera:"),
            "faults.command_latency_s: must be at most 10");
  std::string many = "objects:\n";
  for (int i = 0; i < 300; ++i)
    many += "  - {name: o" + std::to_string(i) + ", shape: plane, size_m: [0.1, 0.1], texture: " + kSource +
            "/media/targets/tea_box.png, pose: {translation: [2, 0, 1], rotation_vector: [0, 0, 0]}}\n";
  EXPECT_EQ(scenarioError("objects:\n", many), "objects: 301 objects, at most 256");
  // Strict at every level: typos inside a nested pose, keys given twice, wrong types.
  EXPECT_EQ(scenarioError("grasp_frame: {translation: [0.0, 0.0, 0.035], rotation_vector",
                          "grasp_frame: {translation: [0.0, 0.0, 0.035], rotaton_vector"),
            "objects[0].grasp_frame.rotaton_vector: unknown field (did you mean rotation_vector?)");
  EXPECT_EQ(scenarioError("robot_start: {x: 0.0,", "robot_start: {x: 0.0, x: 1.0,"),
            "robot_start.x: given twice (lines 7 and 7)");
  EXPECT_EQ(scenarioError("target: true", "taget: true"), "objects[0].taget: unknown field (did you mean target?)");
  EXPECT_EQ(scenarioError("seed: 1", "seed: {a: 1}"), "seed: expected a number");
}

TEST(HostileSim, RobotModelValuesThatWouldHangAreRefusedAtLoad) {
  EXPECT_EQ(enonError("control_period_s: 0.02", "control_period_s: 1e-9"), "control_period_s: must be in [0.001, 1] s");
  EXPECT_EQ(enonError("watchdog_period_s: 0.2", "watchdog_period_s: 0.001"),
            "watchdog_period_s: must be in [0.02, 60] s (from control_period_s)");
  EXPECT_EQ(enonError("frame_rate_hz: 48", "frame_rate_hz: 1e9"), "head.frame_rate_hz: must be in [0.1, 1000] Hz");
  std::string joints;
  for (int i = 0; i < 33; ++i)
    joints += "    - {name: j" + std::to_string(i) + ", a_m: 0, alpha_rad: 0, d_m: 0.1, theta_offset_rad: 0, "
              "limits: {min_rad: -1, max_rad: 1, max_speed_radps: 1}}\n";
  EXPECT_EQ(enonError("  joints:\n", "  joints:\n" + joints), "arm.joints: 38 joints, at most 32");
  // Unknown keys anywhere (the loader reads the sections by dotted names, so rejectUnknownFields()
  // is what catches them), with the nearest real key.
  EXPECT_EQ(enonError("watchdog_period_s: 0.2", "watchdog_period_s: 0.2\nwatchdog_periode_s: 0.5"),
            "watchdog_periode_s: unknown field (did you mean watchdog_period_s?)");
  EXPECT_EQ(enonError("tilt_height_m: 0.07", "tilt_height_m: 0.07\n  tilt_hieght_m: 0.08"),
            "head.tilt_hieght_m: unknown field (did you mean tilt_height_m?)");
  EXPECT_EQ(enonError("max_speed_radps: 1.5}", "max_speed_radps: 1.5, max_speed: 2}"),
            "head.pan.max_speed: unknown field (did you mean max_speed_radps?)");
  const std::string enon = refgrasp::testing::readFile(kSource + "/config/enon.yaml");
  const auto line = std::count(enon.begin(), enon.begin() + static_cast<long>(enon.find("close_time_s")), '\n') + 1;
  EXPECT_EQ(enonError("close_time_s: 0.5", "close_time_s: 0.5\n  close_time_s: 0.6"),
            "gripper.close_time_s: given twice (lines " + std::to_string(line) + " and " + std::to_string(line + 1) + ")");
}

}  // namespace refgrasp::sim
