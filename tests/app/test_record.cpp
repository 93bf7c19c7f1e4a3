// record end to end: the simulated camera to a recording with ground truth, an image folder to a
// mono recording, a disk that fills (prlimit --fsize: no root needed) and bad sources.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <random>

#include "common/app_run.h"
#include "common/temp_dir.h"
#include "robot/files/recording.h"

namespace fs = std::filesystem;
using namespace refgrasp;
using refgrasp::testing::AppRun;
using refgrasp::testing::runApp;

namespace {

const std::string kSource = REFGRASP_SOURCE_DIR;

fs::path scratch(const std::string& name) {
  const fs::path d = refgrasp::testing::tempDir("refgrasp_test_record") / name;
  fs::remove_all(d);
  return d;
}

std::string cameraFile(int w, int h) {
  const fs::path p = refgrasp::testing::tempDir("refgrasp_test_record") / "cam.yaml";
  saveCameraFile(p.string(), Intrinsics::pinhole(w, h, w, (w - 1) / 2.0, (h - 1) / 2.0), "cam");
  return p.string();
}

}  // namespace

TEST(RecordApp, TheSimulatedCameraIsRecordedWithGroundTruth) {
  const fs::path out = scratch("sim");
  const AppRun r = runApp("record", "--source sim:" + kSource + "/config/scenarios/table_clutter.yaml --set enon=" +
                                        kSource + "/config/enon.yaml --frames 3 --output " + out.string());
  ASSERT_EQ(r.status, 0) << r.err;
  const files::Recording rec = files::Recording::open(out.string());
  EXPECT_TRUE(rec.stereo());
  EXPECT_TRUE(rec.warning().empty());
  ASSERT_EQ(rec.entries().size(), 3u);
  EXPECT_NEAR(rec.entries()[2].stamp, 2.0 / 48, 1e-12);
  ASSERT_FALSE(rec.entries()[0].truth.empty());
  EXPECT_TRUE(rec.entries()[0].capture.head.has_value());
  EXPECT_NEAR(rec.rig().baseline(), 0.12, 1e-6);
  EXPECT_NE(r.err.find("record: 3 frames in"), std::string::npos) << r.err;
}

TEST(RecordApp, AnImageFolderBecomesAMonoRecording) {
  const fs::path in = scratch("images"), out = scratch("mono");
  fs::create_directories(in);
  for (int i = 0; i < 4; ++i)
    cv::imwrite((in / ("i" + std::to_string(i) + ".png")).string(), cv::Mat(24, 32, CV_8UC1, cv::Scalar(i)));
  cv::imwrite((in / "i9.png").string(), cv::Mat(12, 16, CV_8UC1, cv::Scalar(0)));  // wrong size
  const AppRun r = runApp("record", "--source " + in.string() + " --camera " + cameraFile(32, 24) +
                                        " --set fps_hz=10 --no-fsync --output " + out.string());
  EXPECT_EQ(r.status, 1) << r.err;  // one frame skipped
  EXPECT_NE(r.err.find((in / "i9.png").string() + ": image is 16x12, the calibration is 32x24"), std::string::npos)
      << r.err;
  const files::Recording rec = files::Recording::open(out.string());
  EXPECT_FALSE(rec.stereo());
  ASSERT_EQ(rec.entries().size(), 4u);
  EXPECT_DOUBLE_EQ(rec.entries()[3].stamp, 0.3);
}

TEST(RecordApp, ADiskThatFillsIsExitCode3AndTheRecordingReadsUpToTheLastGoodFrame) {
  // Image i has i noisy bands of 60 rows (incompressible): its PNG grows by ~38 kB per band, and
  // under a 100 kB file size limit image 3 cannot be written.
  const fs::path in = scratch("growing"), out = scratch("full");
  fs::create_directories(in);
  std::mt19937 rng(3);
  for (int i = 0; i < 8; ++i) {
    cv::Mat m(480, 640, CV_8UC1, cv::Scalar(90));
    for (int r = 0; r < 60 * i && r < 480; ++r)
      for (int c = 0; c < 640; ++c) m.at<uchar>(r, c) = static_cast<uchar>(rng());
    cv::imwrite((in / ("i" + std::to_string(i) + ".png")).string(), m);
  }
  const AppRun r = runApp("record", "--source folder:" + in.string() + " --camera " + cameraFile(640, 480) +
                                        " --output " + out.string(),
                          "prlimit --fsize=100000");
  EXPECT_EQ(r.status, 3) << r.err;
  EXPECT_NE(r.err.find("write failed: File too large\n"), std::string::npos) << r.err;
  // The problem is one line of ours; the progress lines (stderr is not a terminal) say "frames".
  EXPECT_NE(r.err.find("record: " + out.string() + "/"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("frames in"), std::string::npos) << r.err;
  const files::Recording rec = files::Recording::open(out.string());
  EXPECT_TRUE(rec.warning().empty()) << rec.warning();
  EXPECT_EQ(rec.entries().size(), 3u);
  for (size_t i = 0; i < rec.entries().size(); ++i) {
    robot::MonoFrame f;
    std::string e;
    EXPECT_TRUE(rec.read(i, &f, &e)) << e;
  }
}

TEST(RecordApp, BadSourcesAndOutputsAreOneLineErrors) {
  const fs::path out = scratch("bad");
  AppRun r = runApp("record", "--source /nonexistent/frames --output " + out.string());
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "record: /nonexistent/frames: no such file or folder\n");
  r = runApp("record", "--source bb2:ffffffffffffffff --stereo " + kSource +
                           "/config/cameras/bb2_rig.yaml --output " + out.string());
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err.rfind("record: bb2: no ", 0), 0u) << r.err;  // no FireWire camera here
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  r = runApp("record", "--source v4l2:/dev/video_refgrasp_none --camera " + cameraFile(64, 48) +
                           " --output " + out.string());
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "record: /dev/video_refgrasp_none: no such V4L2 device\n");
  fs::create_directories(out / "occupied");
  r = runApp("record", "--source sim:" + kSource + "/config/scenarios/table_single.yaml --set enon=" + kSource +
                           "/config/enon.yaml --frames 1 --output " + (out / "occupied").parent_path().string());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("exists and is not an empty folder"), std::string::npos) << r.err;
  r = runApp("record", "--source x --output y --set nokey");
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "record: --set nokey: expected KEY=VALUE\n");
}
