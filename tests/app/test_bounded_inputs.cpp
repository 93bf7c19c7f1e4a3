// The tools that read recordings and image folders, fed inputs with nothing in them or built to
// exhaust memory: an empty recording is "nothing to do" (exit 2, one line), never a success with
// 0 frames; a recording index or a stamps file of three good lines followed by gigabytes of NUL
// bytes (sparse: no disk used) is one line within seconds and a bounded peak memory.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "common/app_run.h"
#include "common/noise_image.h"
#include "common/temp_dir.h"
#include "bounded_run.h"
#include "core/camera.h"
#include "robot/files/recording.h"

namespace fs = std::filesystem;
using namespace refgrasp;
using refgrasp::testing::AppRun;
using refgrasp::testing::BoundedRun;
using refgrasp::testing::runApp;
using refgrasp::testing::runBounded;

namespace {

const std::string kObject = std::string(REFGRASP_SOURCE_DIR) + "/config/objects/tea_box.yaml";
// Peak resident memory allowed to a tool answering a bomb: its libraries and the object's
// reference take ~115 MB (more under AddressSanitizer); the bombs below are 3 GiB and 1 GiB.
constexpr long kMaxRssMb = 768;
constexpr double kMaxSeconds = 5;

fs::path scratch(const std::string& name) {
  const fs::path d = refgrasp::testing::tempDir("refgrasp_test_bounded_inputs") / name;
  fs::remove_all(d);
  return d;
}

Intrinsics smallCamera() { return Intrinsics::pinhole(32, 24, 40, 15.5, 11.5); }

fs::path monoRecording(const std::string& name, int frames) {
  const fs::path d = scratch(name);
  files::RecordingOptions o;
  o.fsync = false;
  auto w = files::RecordingWriter::createMono(d.string(), smallCamera(), o);
  std::mt19937_64 rng(38);
  for (int i = 0; i < frames; ++i) {
    robot::MonoFrame f;
    f.image = refgrasp::testing::noiseImage(rng, 32, 24);
    f.stamp = 0.1 * i;
    f.index = i;
    EXPECT_TRUE(w->write(f).ok);
  }
  return d;
}

std::vector<std::string> replayArgs(const fs::path& input, const fs::path& out) {
  return {"--object", kObject, "--input", input.string(), "--output", out.string()};
}

}  // namespace

TEST(BoundedInputs, AnEmptyRecordingIsNothingToDoForPoseReplayAndRecord) {
  const fs::path rec = monoRecording("empty", 0), out = scratch("out");
  const std::string index = (rec / "index.jsonl").string();
  ASSERT_EQ(fs::file_size(index), 0u);
  AppRun r = runApp("pose_replay", "--object " + kObject + " --input " + rec.string() + " --output " +
                                       out.string());
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "pose_replay: " + index + ": no frames (an empty recording): nothing to do\n");
  EXPECT_FALSE(fs::exists(out));  // refused before any output
  r = runApp("record", "--source " + rec.string() + " --output " + out.string());
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "record: " + index + ": no frames (an empty recording): nothing to do\n");
}

TEST(BoundedInputs, PoseReplayAnswersARecordingIndexBombInOneLineAndBoundedMemory) {
  const fs::path rec = monoRecording("bomb", 3), out = scratch("out");
  const std::string index = (rec / "index.jsonl").string();
  const uintmax_t good = fs::file_size(index);
  // Three good lines then 6 GiB of NUL bytes: refused from the file's size.
  fs::resize_file(index, good + (uintmax_t{6} << 30));
  BoundedRun r = runBounded("pose_replay", replayArgs(rec, out));
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "pose_replay: " + index + ": is " + std::to_string(good + (uintmax_t{6} << 30)) +
                       " bytes, more than the limit of 4294967296\n");
  EXPECT_LT(r.seconds, kMaxSeconds);
  EXPECT_LT(r.max_rss_mb, kMaxRssMb);
  // 3 GiB of NUL bytes, under the size limit: the line limit stops the read at line 4.
  fs::resize_file(index, good + (uintmax_t{3} << 30));
  r = runBounded("pose_replay", replayArgs(rec, out));
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "pose_replay: " + index + ": line 4: longer than the limit of 1048576 bytes\n");
  EXPECT_LT(r.seconds, kMaxSeconds);
  EXPECT_LT(r.max_rss_mb, kMaxRssMb);
}

TEST(BoundedInputs, PoseReplayAnswersAStampsFileBombInOneLineAndBoundedMemory) {
  const fs::path dir = scratch("folder"), out = scratch("out");
  fs::create_directories(dir);
  std::mt19937_64 rng(38);
  for (int i = 0; i < 3; ++i)
    cv::imwrite((dir / ("f" + std::to_string(i) + ".png")).string(),
                refgrasp::testing::noiseImage(rng, 32, 24));
  const std::string camera = (scratch("camera.yaml")).string();
  saveCameraFile(camera, smallCamera(), "small");
  const std::string stamps = (dir / "stamps.txt").string();
  std::vector<std::string> args = replayArgs(dir, out);
  args.insert(args.end(), {"--camera", camera});
  // Three stamps then NUL bytes up to just under the 1 GiB size limit.
  std::ofstream(stamps) << "0.1\n0.2\n0.3\n";
  fs::resize_file(stamps, (uintmax_t{1} << 30) - 1);
  BoundedRun r = runBounded("pose_replay", args);
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "pose_replay: " + stamps + ": line 4: longer than the limit of 65536 bytes\n");
  EXPECT_LT(r.seconds, kMaxSeconds);
  EXPECT_LT(r.max_rss_mb, kMaxRssMb);
  // An over-long line of digits (one stamp of 64 MiB).
  std::ofstream(stamps) << "0.1\n" << std::string(64 << 20, '7') << "\n";
  r = runBounded("pose_replay", args);
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "pose_replay: " + stamps + ": line 2: longer than the limit of 65536 bytes\n");
  EXPECT_LT(r.seconds, kMaxSeconds);
  EXPECT_LT(r.max_rss_mb, kMaxRssMb);
}
