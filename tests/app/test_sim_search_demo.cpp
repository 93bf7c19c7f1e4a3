// End to end: the simulated enon searches for the scenario's target with its stereo camera and the
// detector; the fused pose is checked against the simulator's ground truth.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "common/app_run.h"
#include "common/temp_dir.h"

namespace fs = std::filesystem;
using nlohmann::json;
using refgrasp::testing::AppRun;
using refgrasp::testing::readFile;
using refgrasp::testing::runApp;

namespace {

const std::string kSource = REFGRASP_SOURCE_DIR;

json lastLook(const fs::path& out) {
  std::ifstream in(out / "looks.jsonl");
  std::string line, last;
  while (std::getline(in, line))
    if (!line.empty()) last = line;
  return last.empty() ? json() : json::parse(last);
}

// The target's object definition in each shipped scenario.
std::string targetObject(const std::string& scenario) {
  return scenario == "table_clutter" ? "tea_box" : "cereal_box";
}

void expectFoundAccurately(const std::string& scenario, int max_looks) {
  const fs::path out = refgrasp::testing::tempDir("refgrasp_search_" + scenario);
  const AppRun r = runApp("sim_search_demo", "--enon " + kSource + "/config/enon.yaml --scenario " +
                                              kSource + "/config/scenarios/" + scenario +
                                              ".yaml --max-time 30 --out " + out.string());
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  const json look = lastLook(out);
  ASSERT_TRUE(look.contains("translation_error_m")) << look.dump();
  const double dist = std::hypot(look["lMo_true"]["t"][0].get<double>(),
                                 look["lMo_true"]["t"][1].get<double>(),
                                 look["lMo_true"]["t"][2].get<double>());
  // looks.jsonl has one line per look.
  const std::string looks = readFile(out / "looks.jsonl");
  const long n_looks = std::count(looks.begin(), looks.end(), '\n');
  std::printf("%s: found after %ld looks at %.2f m: %.1f mm, %.2f deg\n", scenario.c_str(), n_looks,
              dist, look["translation_error_m"].get<double>() * 1000,
              look["rotation_error_deg"].get<double>());
  EXPECT_LT(look["translation_error_m"].get<double>(), 0.01 * dist);
  EXPECT_LT(look["rotation_error_deg"].get<double>(), 2.0);
  EXPECT_LE(n_looks, max_looks);
  const cv::Mat pic = cv::imread((out / "found_left.png").string());
  EXPECT_EQ(pic.cols, 640);
  EXPECT_EQ(pic.rows, 480);
  // README's detect_object example runs on the frame as captured.
  const AppRun d = runApp("detect_object", "--object " + kSource + "/config/objects/" +
                                               targetObject(scenario) + ".yaml --camera " + kSource +
                                               "/config/cameras/bb2_left.yaml " +
                                               (out / "frame_left.png").string());
  ASSERT_EQ(d.status, 0) << d.err;
  const json line = json::parse(d.out);
  EXPECT_EQ(line["found"], look["left_found"]) << d.out;
}

}  // namespace

TEST(SimSearchDemo, FindsTheTargetOutsideTheInitialView) { expectFoundAccurately("table_single", 3); }

TEST(SimSearchDemo, FindsTheTargetAmongDistractors) { expectFoundAccurately("table_clutter", 1); }

TEST(SimSearchDemo, FindsTheTargetWithFrameDropsLatencyAndOdometryNoise) {
  expectFoundAccurately("faults", 3);
}

TEST(SimSearchDemo, BadFilesGiveOneLineErrorsAndExitCode4) {
  const fs::path d = refgrasp::testing::tempDir("refgrasp_search_bad");
  const std::string bad = (d / "bad.yaml").string();
  std::ofstream(bad) << "seed: [1\n";
  AppRun r = runApp("sim_search_demo", "--enon " + kSource + "/config/enon.yaml --scenario " + bad +
                                        " --out " + (d / "o").string());
  EXPECT_EQ(r.status, 4);
  EXPECT_NE(r.err.find(bad), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  r = runApp("sim_search_demo", "--enon /nonexistent/enon.yaml --out " + (d / "o").string());
  EXPECT_EQ(r.status, 4);
  EXPECT_NE(r.err.find("/nonexistent/enon.yaml"), std::string::npos) << r.err;
}

TEST(SimSearchDemo, HelpExplainsTheOutputs) {
  const AppRun r = runApp("sim_search_demo", "--help");
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(r.out.find("found_left.png"), std::string::npos);
  EXPECT_NE(r.out.find("--scenario"), std::string::npos);
}
