// robot/sources.h: opening frame sources from text specs, with one-line errors.
#include <gtest/gtest.h>

#include <chrono>
#include <opencv2/imgcodecs.hpp>

#include "core/error.h"
#include "files_test_util.h"
#include "robot/files/recording.h"
#include "robot/sources.h"

namespace fs = std::filesystem;
using namespace refgrasp;
using namespace refgrasp::testing_util;
using robot::ReturnType;

namespace {

std::string openError(const robot::SourceRequest& r) {
  try {
    robot::openSource(r);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(no error)";
}

fs::path stereoRecording(int frames) {
  const fs::path d = testDir("_rec");
  files::RecordingOptions o;
  o.fsync = false;
  auto w = files::RecordingWriter::createStereo(d.string(), smallRig(), o);
  std::mt19937_64 rng(11);
  for (int i = 0; i < frames; ++i) {
    robot::StereoFrame f;
    f.left = noiseImage(rng, 64, 48);
    f.right = noiseImage(rng, 64, 48);
    f.stamp = i;
    f.index = i;
    f.truth.push_back({"poster", Pose(), Pose()});
    EXPECT_TRUE(w->write(f).ok);
  }
  return d;
}

}  // namespace

TEST(Sources, ARecordingIsRecognisedAndAMonoRequestGetsTheLeftEye) {
  const fs::path d = stereoRecording(3);
  robot::SourceRequest r;
  r.spec = d.string();
  robot::OpenedSource s = robot::openSource(r);
  EXPECT_EQ(s.kind, "recording");
  EXPECT_EQ(s.frames, 3);
  EXPECT_TRUE(s.has_truth);
  ASSERT_TRUE(s.mono);
  std::optional<robot::MonoFrame> f;
  ASSERT_EQ(s.mono->grab(0, &f), ReturnType::kOk);
  EXPECT_EQ(f->image.cols, 64);
  r.eyes = robot::Eyes::kStereo;
  r.spec = "recording:" + d.string();
  s = robot::openSource(r);
  ASSERT_TRUE(s.stereo);
  EXPECT_NEAR(s.stereo->rig().baseline(), 0.12, 1e-12);
}

TEST(Sources, FoldersAndVideosNeedACalibrationAndSettingsAreChecked) {
  const fs::path d = testDir();
  fs::create_directories(d / "left");
  fs::create_directories(d / "right");
  for (const char* eye : {"left", "right"})
    cv::imwrite((d / eye / "a.png").string(), cv::Mat(48, 64, CV_8UC1, cv::Scalar(1)));
  robot::SourceRequest r;
  r.spec = d.string();  // left/ and right/: a stereo folder pair
  r.eyes = robot::Eyes::kStereo;
  EXPECT_EQ(openError(r), r.spec + ": a folders source needs a stereo rig calibration (--stereo)");
  r.rig = smallRig();
  robot::OpenedSource s = robot::openSource(r);
  EXPECT_EQ(s.kind, "folders");
  EXPECT_EQ(s.frames, 1);
  r.settings["fps"] = "30";
  EXPECT_EQ(openError(r), r.spec + ": fps: not a setting of a folders source");
  r.settings = {{"fps_hz", "fast"}};
  EXPECT_EQ(openError(r), r.spec + ": fps_hz: 'fast' is not a number");
  robot::SourceRequest m;
  m.spec = "folder:" + (d / "left").string();
  EXPECT_EQ(openError(m), m.spec + ": a folder source needs a camera calibration (--camera)");
  m.camera = smallCamera();
  m.eyes = robot::Eyes::kStereo;
  EXPECT_EQ(openError(m), m.spec + ": is a mono source (folder); stereo needs a stereo one");
}

TEST(Sources, UnknownPathsAndKindsAreOneLineErrors) {
  robot::SourceRequest r;
  r.spec = "/nonexistent/refgrasp/input";
  EXPECT_EQ(openError(r), "/nonexistent/refgrasp/input: no such file or folder");
  r.spec = "";
  EXPECT_EQ(openError(r), "(empty): no input given");
  r.spec = "bb2:ffffffffffffffff";
  r.eyes = robot::Eyes::kStereo;
  r.rig = smallRig(640, 480);
  const std::string e = openError(r);
  EXPECT_EQ(e.rfind("bb2: no ", 0), 0u) << e;  // no camera here (or none with that GUID)
}

TEST(Sources, TheSimulatedCameraDeliversFramesWithGroundTruth) {
  robot::SourceRequest r;
  r.spec = std::string("sim:") + REFGRASP_SOURCE_DIR + "/config/scenarios/table_single.yaml";
  r.settings["enon"] = std::string(REFGRASP_SOURCE_DIR) + "/config/enon.yaml";
  r.eyes = robot::Eyes::kStereo;
  robot::OpenedSource s = robot::openSource(r);
  EXPECT_TRUE(s.has_truth);
  std::optional<robot::StereoFrame> f;
  ASSERT_EQ(s.stereo->grab(0, &f), ReturnType::kOk);
  ASSERT_TRUE(f.has_value());
  EXPECT_EQ(f->index, 0);
  EXPECT_EQ(f->left.size(), cv::Size(640, 480));
  ASSERT_FALSE(f->truth.empty());
  EXPECT_EQ(f->truth[0].object, "cereal_box");
  ASSERT_TRUE(f->truth[0].rMo.has_value());
  // Right-eye truth = lMr^-1 * lMo.
  const Pose rMo = s.stereo->rig().lMr.inverse() * f->truth[0].cMo;
  EXPECT_LT(translationError(rMo, *f->truth[0].rMo), 1e-9);
  ASSERT_EQ(s.stereo->grab(0, &f), ReturnType::kOk);
  EXPECT_EQ(f->index, 1);
  EXPECT_NEAR(f->stamp, 1.0 / 48, 1e-12);
}

namespace {

// A live stereo source stamping on the host's Unix clock, 40 ms before the grab.
struct UnixClockCamera : robot::StereoSource {
  StereoRig rig_ = smallRig();
  const StereoRig& rig() const override { return rig_; }
  ReturnType grab(Seconds, std::optional<robot::StereoFrame>* f) override {
    robot::StereoFrame s;
    s.left = cv::Mat(48, 64, CV_8UC1, cv::Scalar(1));
    s.right = s.left.clone();
    s.stamp = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count() - 0.040;
    *f = s;
    return ReturnType::kOk;
  }
};

}  // namespace

// onCallerClock (enon_grasp --camera): the Bumblebee2's Unix-clock stamps move onto the caller's
// clock keeping the capture delay; offline sources are stamped at the grab; mono is refused.
TEST(Sources, OnCallerClockPutsStampsOnTheLoopsClock) {
  robot::OpenedSource bb2;
  bb2.stereo = std::make_unique<UnixClockCamera>();
  bb2.kind = "bb2";
  bb2.live = true;
  auto cam = robot::onCallerClock(std::move(bb2));
  std::optional<robot::StereoFrame> f;
  ASSERT_EQ(cam->grab(12.5, &f), ReturnType::kOk);
  ASSERT_TRUE(f.has_value());
  EXPECT_NEAR(f->stamp, 12.5 - 0.040, 0.005);

  robot::SourceRequest r;
  r.spec = "recording:" + stereoRecording(2).string();
  r.eyes = robot::Eyes::kStereo;
  auto rec = robot::onCallerClock(robot::openSource(r));
  ASSERT_EQ(rec->grab(3.25, &f), ReturnType::kOk);
  ASSERT_TRUE(f.has_value());
  EXPECT_EQ(f->stamp, 3.25);
  ASSERT_EQ(rec->grab(3.5, &f), ReturnType::kOk);
  ASSERT_TRUE(f.has_value());
  EXPECT_EQ(f->stamp, 3.5);

  robot::OpenedSource mono;
  mono.description = "folder:x";
  try {
    robot::onCallerClock(std::move(mono));
    ADD_FAILURE() << "a mono source was accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), "folder:x: a stereo camera is needed, this source is mono");
  }
}
