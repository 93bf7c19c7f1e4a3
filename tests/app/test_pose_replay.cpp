// pose_replay end to end: a recorded rendered sequence with ground truth replayed twice (identical
// poses.jsonl), the output files, and bad input (unknown path, undecodable video, frames of the
// wrong size, stereo pairs with mismatched stamps): one-line errors, every other frame kept.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/app_run.h"
#include "common/replay_sequence.h"
#include "common/temp_dir.h"
#include "robot/files/recording.h"

namespace fs = std::filesystem;
using nlohmann::json;
using namespace refgrasp;
using refgrasp::testing::AppRun;
using refgrasp::testing::readFile;
using refgrasp::testing::runApp;

namespace {

const std::string kSource = REFGRASP_SOURCE_DIR;
const std::string kObject = " --object " + kSource + "/config/objects/tea_box.yaml";

fs::path scratch(const std::string& name) {
  const fs::path d = refgrasp::testing::tempDir("refgrasp_test_pose_replay") / name;
  fs::remove_all(d);
  return d;
}

std::vector<json> jsonLines(const std::string& text) {
  std::vector<json> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) out.push_back(json::parse(l));
  return out;
}

// The first n frames of the rendered sequence (tea box visible) as sceneCamera images.
std::vector<cv::Mat> visibleFrames(int n) {
  std::vector<cv::Mat> out;
  for (const auto& f : refgrasp::testing::renderOcclusionSequence())
    if (static_cast<int>(out.size()) < n) out.push_back(f.frame.image);
  return out;
}

std::string sceneCameraFile() {
  const fs::path p = refgrasp::testing::tempDir("refgrasp_test_pose_replay") / "scene_camera.yaml";
  saveCameraFile(p.string(), refgrasp::testing::sceneCamera(), "scene");
  return p.string();
}

size_t lineCount(const std::string& s) { return static_cast<size_t>(std::count(s.begin(), s.end(), '\n')); }

// Every other frame of the rendered sequence: still in view, out of view, behind the occluder
// and out again.
std::vector<refgrasp::testing::SequenceFrame> everyOtherFrame() {
  std::vector<refgrasp::testing::SequenceFrame> seq;
  const auto all = refgrasp::testing::renderOcclusionSequence();
  for (size_t k = 0; k < all.size(); k += 2) seq.push_back(all[k]);
  return seq;
}

// seq as a mono recording in scratch(name).
fs::path writeRecording(const std::string& name, const std::vector<refgrasp::testing::SequenceFrame>& seq) {
  const fs::path rec = scratch(name);
  files::RecordingOptions o;
  o.fsync = false;
  auto w = files::RecordingWriter::createMono(rec.string(), refgrasp::testing::sceneCamera(), o);
  for (const auto& f : seq) EXPECT_TRUE(w->write(f.frame).ok);
  return rec;
}

}  // namespace

TEST(PoseReplayApp, ARecordedSequenceReplaysTwiceWithIdenticalPoses) {
  // Every other frame of the sequence (the full one is replayed in-process in test_replay.cpp).
  const std::vector<refgrasp::testing::SequenceFrame> seq = everyOtherFrame();
  const fs::path rec = writeRecording("recording", seq);
  EXPECT_LE(seq[5].visible, 0.05);   // out of view
  EXPECT_LE(seq[11].visible, 0.05);  // behind the occluder
  const fs::path a = scratch("out_a"), a2 = scratch("out_a2"), b = scratch("out_b");
  const AppRun ra = runApp("pose_replay", kObject + " --input " + rec.string() + " --output " + a.string());
  ASSERT_EQ(ra.status, 0) << ra.err;
  EXPECT_NE(ra.err.find("frames"), std::string::npos);  // progress bar
  const AppRun ra2 = runApp("pose_replay", kObject + " --input " + rec.string() + " --output " + a2.string());
  ASSERT_EQ(ra2.status, 0) << ra2.err;
  const AppRun rb = runApp("pose_replay", kObject + " --input " + rec.string() + " --output " +
                                              b.string() + " --frames --no-track");
  ASSERT_EQ(rb.status, 0) << rb.err;
  const std::string pa = readFile(a / "poses.jsonl");
  EXPECT_EQ(pa, readFile(a2 / "poses.jsonl"));  // byte for byte
  const std::vector<json> lines = jsonLines(pa);
  const std::vector<json> lines_b = jsonLines(readFile(b / "poses.jsonl"));
  ASSERT_EQ(lines.size(), seq.size());
  ASSERT_EQ(lines_b.size(), seq.size());
  int detect = 0, track = 0, posed = 0, posed_b = 0;
  for (size_t k = 0; k < seq.size(); ++k) {
    EXPECT_EQ(lines[k]["frame"], k);
    EXPECT_DOUBLE_EQ(lines[k]["stamp"].get<double>(), seq[k].frame.stamp);
    const std::string mode = lines[k]["mode"], mode_b = lines_b[k]["mode"];
    EXPECT_NE(mode_b, "track") << k;  // --no-track detects every frame
    detect += mode == "detect";
    track += mode == "track";
    posed += mode != "lost";
    posed_b += mode_b != "lost";
    if (mode != "lost") {
      ASSERT_TRUE(lines[k].contains("error")) << lines[k].dump();
      EXPECT_TRUE(lines[k].contains("confirmed")) << lines[k].dump();
    }
    if (mode == "track") EXPECT_TRUE(lines[k]["track"].contains("features")) << lines[k].dump();
    if (seq[k].visible >= 0.95) {
      EXPECT_NE(mode, "lost") << k;
      EXPECT_EQ(mode_b, "detect") << k;
      EXPECT_LT(lines[k]["error"]["translation_m"].get<double>(), 0.009) << k;
      EXPECT_LT(lines[k]["error"]["rotation_deg"].get<double>(), 1.0) << k;
    }
    if (seq[k].visible <= 0.05) {
      EXPECT_EQ(mode, "lost") << k;
      EXPECT_EQ(mode_b, "lost") << k;
    }
  }
  EXPECT_GT(track, 0);
  EXPECT_GE(posed, posed_b);
  EXPECT_EQ(lineCount(readFile(a / "trajectory.tum")), 1u + detect + track);
  EXPECT_EQ(lineCount(readFile(a / "poses.csv")), 1u + seq.size());
  EXPECT_TRUE(fs::exists(a / "overlay.mp4"));
  EXPECT_TRUE(fs::exists(b / "frames/000000.png"));
  EXPECT_TRUE(fs::exists(b / "frames/000015.png"));
  const json s = json::parse(readFile(a / "summary.json"));
  EXPECT_EQ(s["frames"], seq.size());
  EXPECT_EQ(s["frames_failed"], 0);
  EXPECT_EQ(s["objects"][0]["modes"]["detect"], detect);
  EXPECT_EQ(s["objects"][0]["modes"]["track"], track);
  EXPECT_TRUE(s["objects"][0].contains("ground_truth"));
  EXPECT_EQ(cv::imread((a / "plot.png").string()).cols, 1280);
}

TEST(PoseReplayApp, UnknownInputAndUndecodableVideoAreOneLineErrors) {
  const fs::path out = scratch("out");
  AppRun r = runApp("pose_replay", kObject + " --camera " + sceneCameraFile() +
                                       " --input /nonexistent/input.mp4 --output " + out.string());
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "pose_replay: /nonexistent/input.mp4: no such file or folder\n");
  const fs::path bad = refgrasp::testing::tempDir("refgrasp_test_pose_replay") / "garbage.mp4";
  std::ofstream(bad) << std::string(4096, '\x17');
  r = runApp("pose_replay", kObject + " --camera " + sceneCameraFile() + " --input " + bad.string() +
                                " --output " + out.string());
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(lineCount(r.err), 1u) << r.err;
  EXPECT_EQ(r.err.rfind("pose_replay: " + bad.string() + ": cannot decode as a video", 0), 0u) << r.err;
  r = runApp("pose_replay", kObject + " --input " + bad.string() + " --output " + out.string());
  EXPECT_EQ(r.status, 2);  // a video needs --camera
  EXPECT_NE(r.err.find("needs a camera calibration (--camera)"), std::string::npos) << r.err;
}

TEST(PoseReplayApp, FramesOfTheWrongSizeAreOneLineErrorsAndTheOthersAreKept) {
  const fs::path in = scratch("folder");
  fs::create_directories(in);
  const std::vector<cv::Mat> imgs = visibleFrames(3);
  cv::imwrite((in / "f0.png").string(), imgs[0]);
  cv::Mat small;
  cv::resize(imgs[1], small, {320, 240});
  cv::imwrite((in / "f1.png").string(), small);
  cv::imwrite((in / "f2.png").string(), imgs[2]);
  const fs::path out = scratch("out");
  const AppRun r = runApp("pose_replay", kObject + " --camera " + sceneCameraFile() + " --input " +
                                             in.string() + " --output " + out.string());
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_NE(r.err.find((in / "f1.png").string() + ": image is 320x240, the calibration is 640x480\n"),
            std::string::npos)
      << r.err;
  const std::vector<json> lines = jsonLines(readFile(out / "poses.jsonl"));
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0]["mode"], "detect");
  EXPECT_EQ(lines[1]["mode"], "lost");
  EXPECT_NE(lines[1]["error_text"].get<std::string>().find("320x240"), std::string::npos);
  EXPECT_EQ(lines[2]["mode"], "detect");
  EXPECT_EQ(json::parse(readFile(out / "summary.json"))["frames_failed"], 1);
}

TEST(PoseReplayApp, StereoPairsWithMismatchedStampsAreOneLineErrorsAndTheOthersAreKept) {
  const fs::path in = scratch("stereo");
  const std::vector<cv::Mat> imgs = visibleFrames(3);
  for (const char* eye : {"left", "right"}) {
    fs::create_directories(in / eye);
    for (int i = 0; i < 3; ++i)
      cv::imwrite((in / eye / ("f" + std::to_string(i) + ".png")).string(), imgs[static_cast<size_t>(i)]);
  }
  std::ofstream(in / "left/stamps.txt") << "0.0\n0.1\n0.2\n";
  std::ofstream(in / "right/stamps.txt") << "0.0\n0.125\n0.2\n";
  const fs::path cams = refgrasp::testing::tempDir("refgrasp_test_pose_replay");
  std::ofstream(cams / "rig.yaml") << "left: scene_camera.yaml\nright: scene_camera.yaml\n"
                                      "right_in_left: {translation: [0.12, 0, 0], rotation_vector: [0, 0, 0]}\n";
  sceneCameraFile();
  const fs::path out = scratch("out");
  const AppRun r = runApp("pose_replay", kObject + " --stereo " + (cams / "rig.yaml").string() +
                                             " --input " + in.string() + " --output " + out.string());
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_NE(r.err.find((in / "right/f1.png").string() +
                       ": pair 1: stamps differ by 25.000 ms (left 0.100000 s, right 0.125000 s; max 1.000 ms)\n"),
            std::string::npos)
      << r.err;
  const std::vector<json> lines = jsonLines(readFile(out / "poses.jsonl"));
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0]["mode"], "detect");
  EXPECT_EQ(lines[0]["eyes"], "both");
  EXPECT_EQ(lines[1]["mode"], "lost");
  EXPECT_EQ(lines[2]["mode"], "detect");
}

TEST(PoseReplayApp, TheDetectorConfigFileIsUsedAndABadOneIsAOneLineError) {
  const fs::path in = scratch("config_folder");
  fs::create_directories(in);
  const std::vector<cv::Mat> imgs = visibleFrames(2);
  for (int i = 0; i < 2; ++i) cv::imwrite((in / ("f" + std::to_string(i) + ".png")).string(), imgs[static_cast<size_t>(i)]);
  const fs::path cfg = refgrasp::testing::tempDir("refgrasp_test_pose_replay") / "strict.yaml";
  std::ofstream(cfg) << "match:\n  min_inliers: 100000\n";  // nothing can be found
  const fs::path out = scratch("out");
  AppRun r = runApp("pose_replay", kObject + " --camera " + sceneCameraFile() + " --input " + in.string() +
                                       " --output " + out.string() + " --detector-config " + cfg.string());
  ASSERT_EQ(r.status, 0) << r.err;
  for (const json& l : jsonLines(readFile(out / "poses.jsonl"))) EXPECT_EQ(l["mode"], "lost");
  std::ofstream(cfg) << "match:\n  min_inlier: 12\n";
  r = runApp("pose_replay", kObject + " --camera " + sceneCameraFile() + " --input " + in.string() +
                                " --output " + out.string() + " --detector-config " + cfg.string());
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(lineCount(r.err), 1u) << r.err;
  EXPECT_EQ(r.err.rfind("pose_replay: " + cfg.string() + ": match.min_inlier", 0), 0u) << r.err;
}

// --prior-max-scale: the tracker's re-detections after the target left the view and came back
// from behind the occluder search their predicted region downsampled, as precise on the frames in
// full view; options in any order; a bad value is a one-line error.
TEST(PoseReplayApp, PriorMaxScaleKeepsThePosesAndABadValueIsAOneLineError) {
  const std::vector<refgrasp::testing::SequenceFrame> seq = everyOtherFrame();
  const fs::path rec = writeRecording("recording_prior", seq);
  const fs::path out = scratch("out_prior");
  const AppRun r = runApp("pose_replay", "--prior-max-scale 0.4 --output " + out.string() + " --input " +
                                             rec.string() + kObject);
  ASSERT_EQ(r.status, 0) << r.err;
  const std::vector<json> lines = jsonLines(readFile(out / "poses.jsonl"));
  ASSERT_EQ(lines.size(), seq.size());
  int full_view = 0;
  for (size_t k = 0; k < seq.size(); ++k) {
    if (seq[k].visible < 0.95) continue;
    ++full_view;
    ASSERT_NE(lines[k]["mode"], "lost") << k;
    EXPECT_LT(lines[k]["error"]["translation_m"].get<double>(), 0.009) << k;
    EXPECT_LT(lines[k]["error"]["rotation_deg"].get<double>(), 1.0) << k;
  }
  EXPECT_GE(full_view, 5);
  for (const char* bad : {"-1", "nan", "x"}) {
    const AppRun b = runApp("pose_replay", kObject + " --input " + rec.string() + " --output " + out.string() +
                                               " --prior-max-scale " + bad);
    EXPECT_EQ(b.status, 2) << bad;
    EXPECT_EQ(lineCount(b.err), 1u) << b.err;
    EXPECT_NE(b.err.find("--prior-max-scale"), std::string::npos) << b.err;
  }
}

TEST(PoseReplayApp, HelpNamesTheOutputsAndExitCodes) {
  const AppRun r = runApp("pose_replay", "--help");
  EXPECT_EQ(r.status, 0);
  for (const char* s : {"poses.jsonl", "trajectory.tum", "overlay.mp4", "summary.json", "plot.png",
                        "--no-track", "--stereo", "--detector-config", "--prior-max-scale", "Exit status"})
    EXPECT_NE(r.out.find(s), std::string::npos) << s;
}
