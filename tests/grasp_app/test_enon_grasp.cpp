// enon_grasp: its command line as docs/tools/enon_grasp.md documents it (summary line, exit codes,
// --log as a recording pose_replay reads back, --video), the session in process, and bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/videoio.hpp>
#include <regex>
#include <sstream>

#include "common/app_run.h"
#include "common/temp_dir.h"
#include "grasp/enon_grasp.h"
#include "grasp/grasp_log.h"

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;
using namespace refgrasp;
using refgrasp::testing::AppRun;
using refgrasp::testing::readFile;
using refgrasp::testing::runApp;

namespace {

const std::string kSource = REFGRASP_SOURCE_DIR;
const std::string kTableSingle = kSource + "/config/scenarios/table_single.yaml";
const std::string kEnon = " --enon " + kSource + "/config/enon.yaml";

fs::path scratch(const std::string& name) {
  const fs::path d = refgrasp::testing::tempDir("refgrasp_test_enon_grasp") / name;
  fs::remove_all(d);
  return d;
}

std::vector<json> jsonLines(const std::string& text) {
  std::vector<json> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);)
    if (!l.empty()) out.push_back(json::parse(l));
  return out;
}

std::vector<std::string> keys(const json& j) {
  std::vector<std::string> k;
  for (auto it = j.begin(); it != j.end(); ++it) k.push_back(it.key());
  return k;
}

size_t lines(const std::string& s) { return static_cast<size_t>(std::count(s.begin(), s.end(), '\n')); }

}  // namespace

// The documented summary line, exactly: its keys in order, the phases in the order they ran with
// their outcomes, the final error from the simulator's ground truth; exit 0 on a grasp.
TEST(EnonGraspApp, OracleRunPrintsTheSummaryLineAndExits0) {
  const AppRun r = runApp("enon_grasp", "--backend sim --scenario " + kTableSingle + kEnon + " --oracle");
  ASSERT_EQ(r.status, 0) << r.err << r.out;
  ASSERT_EQ(lines(r.out), 1u) << r.out;
  const json j = json::parse(r.out);
  EXPECT_EQ(keys(j), (std::vector<std::string>{"success", "sim_time_s", "phases", "final_error",
                                               "collisions"}));
  EXPECT_EQ(j["success"], true);
  EXPECT_EQ(j["collisions"], 0);
  EXPECT_GT(j["sim_time_s"].get<double>(), 5);
  EXPECT_LT(j["sim_time_s"].get<double>(), 40);
  EXPECT_EQ(keys(j["phases"]), (std::vector<std::string>{"search", "approach", "align", "grasp"}));
  EXPECT_EQ(j["phases"]["search"]["outcome"], "found");
  EXPECT_EQ(j["phases"]["approach"]["outcome"], "converged");
  EXPECT_EQ(j["phases"]["align"]["outcome"], "converged");
  EXPECT_EQ(j["phases"]["grasp"]["outcome"], "holding");
  double total = 0;
  for (const auto& [name, p] : j["phases"].items()) {
    EXPECT_EQ(keys(p), (std::vector<std::string>{"time_s", "outcome"})) << name;
    total += p["time_s"].get<double>();
  }
  EXPECT_NEAR(total, j["sim_time_s"].get<double>(), 0.05);
  EXPECT_EQ(keys(j["final_error"]), (std::vector<std::string>{"position_mm", "rotation_deg"}));
  EXPECT_LT(j["final_error"]["position_mm"].get<double>(), 5.0);
  EXPECT_LT(j["final_error"]["rotation_deg"].get<double>(), 2.0);
  EXPECT_TRUE(r.err.empty()) << r.err;  // no progress line when stderr is not a terminal
  // Numbers as documented: times to 1 ms, position to 0.01 mm, rotation to 0.001 deg (no
  // "15.540000000000001").
  EXPECT_FALSE(std::regex_search(r.out, std::regex("[0-9]\\.[0-9]{4,}"))) << r.out;
}

// --seed overrides the scenario's; a run that ends without a grasp (here: out of time) exits 1
// with success false, the phase that was running marked "timeout", and one line on stderr.
TEST(EnonGraspApp, ARunWithoutAGraspExits1) {
  const AppRun r = runApp("enon_grasp", "--scenario " + kTableSingle + kEnon +
                                            " --oracle --seed 7 --max-time 3");
  EXPECT_EQ(r.status, 1) << r.err;
  const json j = json::parse(r.out);
  EXPECT_EQ(j["success"], false);
  EXPECT_EQ(j["phases"]["approach"]["outcome"], "timeout");
  EXPECT_EQ(lines(r.err), 1u) << r.err;
  EXPECT_NE(r.err.find("enon_grasp: "), std::string::npos);
}

// control.jsonl's "detector" (formats.md): on every frame the detector ran on, what it saw of the
// target and what it reported, so that a look can be explained from the log alone; null on the
// frames it did not run on (tracked ones) and between frames.
TEST(EnonGraspApp, TheLogSaysWhatTheDetectorSawOnEveryFrameItRan) {
  const fs::path dir = scratch("log_detector");
  const AppRun r =
      runApp("enon_grasp", "--scenario " + kTableSingle + kEnon + " --log " + dir.string() + " --max-time 3");
  ASSERT_TRUE(r.status == 0 || r.status == 1) << r.err;
  const std::vector<json> control = jsonLines(readFile(dir / "control.jsonl"));
  int ran = 0, found = 0;
  for (const json& l : control) {
    ASSERT_TRUE(l.contains("detector")) << l.dump();
    const json& d = l["detector"];
    if (l["frame"].is_null()) {
      EXPECT_TRUE(d.is_null()) << l.dump();
      continue;
    }
    if (l["source"] == "detect") EXPECT_FALSE(d.is_null()) << "a detection without the detector's record: " << l.dump();
    if (d.is_null()) continue;
    ++ran;
    for (const char* k : {"scene_features", "global_matches", "hypotheses", "candidates", "views", "weak_regions",
                          "rejected", "miss", "sanity", "found"})
      ASSERT_TRUE(d.contains(k)) << k << " in " << d.dump();
    EXPECT_TRUE(d["views"].is_boolean()) << d.dump();
    EXPECT_TRUE(d["weak_regions"].is_number_integer()) << d.dump();
    EXPECT_GE(d["weak_regions"].get<int>(), 0);
    EXPECT_LE(d["weak_regions"].get<int>(), 2) << "match.weak_regions' default";
    EXPECT_GT(d["scene_features"].get<int>(), 0);
    if (!d["found"].is_null()) {
      ++found;
      EXPECT_EQ(d["miss"], "none") << d.dump();
      EXPECT_GE(d["found"]["inliers"].get<int>(), 8) << d.dump();
      EXPECT_GT(d["found"]["correlation"].get<double>(), 0.5) << d.dump();
    } else {
      EXPECT_NE(d["miss"], "none") << "not found, so it says why: " << d.dump();
    }
  }
  EXPECT_GE(ran, 2) << "the search's look and the confirmation at least";
  EXPECT_GE(found, 2);
}

// --log DIR: a refgrasp recording of the frames the controller used plus control.jsonl, one
// line per control iteration; every line obeys the safety rule (no motion on an unconfirmed or
// lost target); pose_replay reads the recording back, one pose line per frame, with the truth.
TEST(EnonGraspApp, TheLogIsARecordingThatPoseReplayReadsBack) {
  const fs::path dir = scratch("log");
  const AppRun r = runApp("enon_grasp", "--scenario " + kTableSingle + kEnon + " --oracle --log " +
                                            dir.string() + " --max-time 4");
  ASSERT_TRUE(r.status == 0 || r.status == 1) << r.err;
  ASSERT_TRUE(fs::exists(dir / "recording.json"));
  const std::vector<json> control = jsonLines(readFile(dir / "control.jsonl"));
  const std::vector<json> index = jsonLines(readFile(dir / "index.jsonl"));
  ASSERT_GT(control.size(), 190u);  // 4 s at 50 Hz
  ASSERT_GT(index.size(), 10u);
  size_t with_frame = 0;
  for (const json& l : control) {
    for (const char* k : {"t", "phase", "detail", "observed", "confirmed", "cMo", "truth_cMo",
                          "error", "command", "state"})
      ASSERT_TRUE(l.contains(k)) << k << " in " << l.dump();
    const json& c = l["command"];
    const bool moves = c["base_v_mps"] != 0 || c["base_w_radps"] != 0 ||
                       (c["head_mode"] == "velocity" && (c["pan"] != 0 || c["tilt"] != 0)) ||
                       std::any_of(c["arm_qdot_radps"].begin(), c["arm_qdot_radps"].end(),
                                   [](const json& q) { return q != 0; });
    if ((l["observed"] == "lost" || l["observed"] == "unconfirmed") && l["phase"] != "search") {
      EXPECT_FALSE(moves) << l.dump();
    }
    if (l["target_driven"] == true && l["confirmed"] == false) {
      EXPECT_FALSE(moves) << l.dump();
    }
    if (!l["frame"].is_null()) {
      ++with_frame;
      EXPECT_EQ(index.at(l["frame"].get<size_t>())["index"], l["frame_index"]);
      EXPECT_FALSE(l["truth_cMo"].is_null());
    }
  }
  EXPECT_EQ(with_frame, index.size());
  const fs::path out = scratch("replay");
  const AppRun pr = runApp("pose_replay", "--object " + kSource + "/config/objects/cereal_box.yaml" +
                                              " --input " + dir.string() + " --output " + out.string());
  ASSERT_EQ(pr.status, 0) << pr.err;
  const std::vector<json> poses = jsonLines(readFile(out / "poses.jsonl"));
  EXPECT_EQ(poses.size(), index.size());
  EXPECT_TRUE(poses.back().contains("truth"));
}

// --video FILE: the frames used, one per frame the controller looked at; on the simulator three
// 640x480 panels side by side (head camera, external view, map).
TEST(EnonGraspApp, TheVideoHasTheFramesUsed) {
  const fs::path dir = scratch("video");
  fs::create_directories(dir);
  const fs::path file = dir / "grasp.mp4";
  const AppRun r = runApp("enon_grasp", "--scenario " + kTableSingle + kEnon + " --oracle --video " +
                                            file.string() + " --max-time 3");
  ASSERT_TRUE(r.status == 0 || r.status == 1) << r.err;
  cv::VideoCapture v(file.string());
  ASSERT_TRUE(v.isOpened());
  int frames = 0;
  for (cv::Mat f; v.read(f); ++frames) {
    EXPECT_EQ(f.cols, 3 * 640);
    EXPECT_EQ(f.rows, 480);
  }
  EXPECT_GT(frames, 10);
}

// Bad options and files: exit 2 and one line naming the file and the field.
TEST(EnonGraspApp, BadOptionsAndFilesExit2WithOneLine) {
  const fs::path dir = scratch("bad");
  fs::create_directories(dir / "occupied");
  std::ofstream(dir / "occupied" / "x") << "x";
  {  // table_single without a target (paths made absolute: the copy lives elsewhere)
    std::string y = readFile(kTableSingle);
    y.replace(y.find("target: true"), 12, "target: false");
    for (const auto& [from, to] : {std::pair<std::string, std::string>{"../../media", kSource + "/media"},
                                   {"../objects", kSource + "/config/objects"}})
      for (size_t p = y.find(from); p != std::string::npos; p = y.find(from, p + to.size()))
        y.replace(p, from.size(), to);
    std::ofstream(dir / "no_target.yaml") << y;
  }
  std::ofstream(dir / "bad.yaml") << "seed: [\n";
  struct Case {
    std::string args, expect;
  };
  const std::vector<Case> cases = {
      {"--oracle" + kEnon, "--scenario"},
      {"--scenario " + (dir / "missing.yaml").string() + kEnon, "missing.yaml"},
      {"--scenario " + (dir / "bad.yaml").string() + kEnon, "bad.yaml"},
      {"--scenario " + (dir / "no_target.yaml").string() + kEnon, "no_target.yaml: objects"},
      {"--scenario " + kTableSingle + " --enon " + (dir / "missing_enon.yaml").string(), "missing_enon.yaml"},
      {"--scenario " + kTableSingle + kEnon + " --backend warp", "backend"},
      {"--scenario " + kTableSingle + kEnon + " --backend dds --oracle", "--oracle"},
      {"--scenario " + kTableSingle + kEnon + " --max-time -1", "--max-time"},
      {"--scenario " + kTableSingle + kEnon + " --seed abc", "--seed"},
      {"--scenario " + kTableSingle + kEnon + " --oracle --log " + (dir / "occupied").string(), "occupied"},
      {"--scenario " + kTableSingle + kEnon + " --detector-config " + (dir / "bad.yaml").string(), "bad.yaml"},
      {"--scenario " + kTableSingle + kEnon + " --camera bb2", "--camera: needs a robot backend other than sim"},
      {"--scenario " + kTableSingle + kEnon + " --camera-config x.yaml", "--camera-config: only with --camera"},
      // No FireWire camera here: found missing before the robot is started.
      {"--camera bb2:ffffffffffffffff --backend dds --scenario " + kTableSingle + kEnon, "bb2: no "},
      {"--scenario " + kTableSingle + kEnon + " --backend dds --camera " + (dir / "missing_rec").string(), "missing_rec"},
  };
  for (const Case& c : cases) {
    const AppRun r = runApp("enon_grasp", c.args);
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.err;
    EXPECT_EQ(lines(r.err), 1u) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_TRUE(r.out.empty()) << c.args;
  }
}
