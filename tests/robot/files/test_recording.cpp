// Recordings: round trip bit for bit, a recorder killed mid-write, a disk that fills (RLIMIT_FSIZE
// in a forked child, no root needed), damaged recordings read up to their last good frame.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <functional>
#include <thread>

#include "files_test_util.h"
#include "core/error.h"
#include "robot/files/recording.h"

namespace fs = std::filesystem;
using namespace refgrasp;
using namespace refgrasp::testing_util;
using files::Recording;
using files::RecordingOptions;
using files::RecordingWriter;

namespace {

RecordingOptions options(bool fsync = false) {
  RecordingOptions o;
  o.source = "test";
  o.created_by = "test_recording";
  o.fsync = fsync;
  return o;
}

robot::StereoFrame stereoFrame(std::mt19937_64& rng, int i, const StereoRig& rig) {
  robot::StereoFrame f;
  f.left = noiseImage(rng, rig.left.width, rig.left.height);
  f.right = noiseImage(rng, rig.right.width, rig.right.height);
  f.stamp = 0.1 + i / 48.0 + 1e-7 * i * i;  // not round in decimal
  f.index = 100 + 2 * i;
  f.capture.head = robot::HeadJoints{0.01 * i, -0.3 + 1.0 / 3.0};
  f.capture.bMc = Pose::fromRotationVector({0.1, 0.2 * i, -0.3}, {1.0 / 7.0, 0.2, 1.3});
  if (i % 2 == 0) f.capture.wMb_odom = Pose::fromRotationVector({0, 0, 0.5 * i}, {i / 3.0, 0, 0});
  f.truth.push_back({"tea_box", Pose::fromRotationVector({0.3, -0.1, 0.05 * i}, {0.1, -0.05, 0.9}),
                     Pose::fromRotationVector({0.3, -0.1, 0.05 * i}, {-0.02, -0.05, 0.9})});
  return f;
}

robot::RobotState robotState(int i) {
  robot::RobotState s;
  s.stamp = i / 48.0;
  s.wMb_odom = Pose::fromRotationVector({0, 0, 0.1 * i}, {0.5, 1.0 / 3.0, 0});
  s.base_v_mps = 0.2;
  s.pan_rad = 0.123456789;
  s.arm_q_rad = Eigen::VectorXd::LinSpaced(6, -1.0 / 3.0, 1.0);
  s.arm_qdot_radps = Eigen::VectorXd::Zero(6);
  s.gripper = robot::GripperPhase::kHolding;
  s.held_object = "tea_box";
  return s;
}

void expectSamePose(const Pose& a, const Pose& b) {
  EXPECT_EQ(a.R, b.R);
  EXPECT_EQ(a.t, b.t);
}

// Counts lines of a file.
size_t lineCount(const fs::path& p) {
  const std::string s = readText(p);
  return static_cast<size_t>(std::count(s.begin(), s.end(), '\n'));
}

}  // namespace

TEST(Recording, StereoRoundTripIsBitExact) {
  const fs::path dir = testDir();
  const StereoRig rig = smallRig();
  std::mt19937_64 rng(1);
  std::vector<robot::StereoFrame> frames;
  {
    auto w = RecordingWriter::createStereo(dir.string(), rig, options(true));
    for (int i = 0; i < 5; ++i) {
      frames.push_back(stereoFrame(rng, i, rig));
      const robot::RobotState s = robotState(i);
      const files::WriteStatus st = w->write(frames.back(), i == 3 ? nullptr : &s);
      ASSERT_TRUE(st.ok) << st.error;
    }
    EXPECT_EQ(w->frames(), 5);
  }
  const Recording rec = Recording::open(dir.string());
  EXPECT_TRUE(rec.warning().empty()) << rec.warning();
  ASSERT_TRUE(rec.stereo());
  ASSERT_EQ(rec.entries().size(), 5u);
  EXPECT_EQ(rec.source(), "test");
  EXPECT_EQ(rec.rig().left.width, 64);
  EXPECT_NEAR(rec.rig().right.cx, rig.right.cx, 1e-9);
  EXPECT_NEAR(translationError(rec.rig().lMr, rig.lMr), 0, 1e-12);
  EXPECT_NEAR(rotationError(rec.rig().lMr, rig.lMr), 0, 1e-12);
  for (size_t i = 0; i < 5; ++i) {
    robot::StereoFrame f;
    std::string err;
    ASSERT_TRUE(rec.read(i, &f, &err)) << err;
    EXPECT_TRUE(identical(f.left, frames[i].left)) << i;
    EXPECT_TRUE(identical(f.right, frames[i].right)) << i;
    EXPECT_EQ(f.stamp, frames[i].stamp);  // bit for bit, through JSON text
    EXPECT_EQ(f.index, frames[i].index);
    const files::IndexEntry& e = rec.entries()[i];
    EXPECT_EQ(e.frame, static_cast<int64_t>(i));
    EXPECT_EQ(e.files[0], "frames/" + std::string(i < 10 ? "00000" : "0000") + std::to_string(i) + "_left.png");
    ASSERT_TRUE(f.capture.head && f.capture.bMc);
    EXPECT_EQ(f.capture.head->pan_rad, frames[i].capture.head->pan_rad);
    EXPECT_EQ(f.capture.head->tilt_rad, frames[i].capture.head->tilt_rad);
    expectSamePose(*f.capture.bMc, *frames[i].capture.bMc);
    EXPECT_EQ(f.capture.wMb_odom.has_value(), i % 2 == 0);
    if (f.capture.wMb_odom) expectSamePose(*f.capture.wMb_odom, *frames[i].capture.wMb_odom);
    ASSERT_EQ(f.truth.size(), 1u);
    EXPECT_EQ(f.truth[0].object, "tea_box");
    expectSamePose(f.truth[0].cMo, frames[i].truth[0].cMo);
    ASSERT_TRUE(f.truth[0].rMo.has_value());
    expectSamePose(*f.truth[0].rMo, *frames[i].truth[0].rMo);
    EXPECT_EQ(e.robot.has_value(), i != 3);
    if (e.robot) {
      const robot::RobotState s = robotState(static_cast<int>(i));
      EXPECT_EQ(e.robot->stamp, s.stamp);
      expectSamePose(e.robot->wMb_odom, s.wMb_odom);
      EXPECT_EQ(e.robot->arm_q_rad, s.arm_q_rad);
      EXPECT_EQ(e.robot->gripper, s.gripper);
      EXPECT_EQ(e.robot->held_object, "tea_box");
    }
  }

  // Identical index: copying the recording through the reader and the writer gives the same bytes.
  const fs::path copy = testDir("_copy");
  {
    auto w = RecordingWriter::createStereo(copy.string(), rec.rig(), options());
    for (size_t i = 0; i < rec.entries().size(); ++i) {
      robot::StereoFrame f;
      std::string err;
      ASSERT_TRUE(rec.read(i, &f, &err)) << err;
      const auto& robot = rec.entries()[i].robot;
      ASSERT_TRUE(w->write(f, robot ? &*robot : nullptr).ok);
    }
  }
  EXPECT_EQ(readText(copy / "index.jsonl"), readText(dir / "index.jsonl"));
  for (size_t i = 0; i < 5; ++i)
    EXPECT_EQ(readText(copy / rec.entries()[i].files[1]), readText(dir / rec.entries()[i].files[1]));
}

TEST(Recording, MonoRoundTripKeepsColourAndWorksAsAFrameSource) {
  const fs::path dir = testDir();
  const Intrinsics cam = smallCamera(40, 30);
  std::mt19937_64 rng(2);
  std::vector<cv::Mat> images;
  {
    auto w = RecordingWriter::createMono(dir.string(), cam, options());
    for (int i = 0; i < 4; ++i) {
      robot::MonoFrame f;
      f.image = noiseImage(rng, 40, 30, i % 2 ? CV_8UC3 : CV_8UC1);
      f.stamp = i * 0.5;
      f.index = i;
      images.push_back(f.image);
      ASSERT_TRUE(w->write(f).ok);
    }
    robot::StereoFrame wrong;
    EXPECT_FALSE(w->write(wrong).ok);  // a stereo frame in a mono recording is refused
  }
  auto src = files::makeRecordingMonoSource(Recording::open(dir.string()));
  EXPECT_EQ(src->camera().width, 40);
  for (int i = 0; i < 4; ++i) {
    std::optional<robot::MonoFrame> f;
    ASSERT_EQ(src->grab(0, &f), robot::ReturnType::kOk);
    ASSERT_TRUE(f.has_value());
    EXPECT_TRUE(identical(f->image, images[static_cast<size_t>(i)])) << i;
    EXPECT_EQ(f->stamp, i * 0.5);
    EXPECT_TRUE(f->truth.empty());
  }
  std::optional<robot::MonoFrame> f;
  EXPECT_EQ(src->grab(0, &f), robot::ReturnType::kDeactivate);
  EXPECT_FALSE(f.has_value());
  EXPECT_THROW(files::makeRecordingStereoSource(Recording::open(dir.string())), ConfigError);
}

TEST(Recording, AWrongFrameIsRefusedWithoutSpoilingTheRecording) {
  const fs::path dir = testDir();
  const StereoRig rig = smallRig();
  std::mt19937_64 rng(3);
  auto w = RecordingWriter::createStereo(dir.string(), rig, options());
  robot::StereoFrame bad = stereoFrame(rng, 0, rig);
  bad.right = noiseImage(rng, 32, 24);
  const files::WriteStatus st = w->write(bad);
  EXPECT_FALSE(st.ok);
  EXPECT_FALSE(st.fatal);
  EXPECT_NE(st.error.find("right image is 32x24, the calibration is 64x48"), std::string::npos) << st.error;
  EXPECT_EQ(st.error.find('\n'), std::string::npos);
  EXPECT_TRUE(w->write(stereoFrame(rng, 1, rig)).ok);  // the next good frame is frame 0
  EXPECT_EQ(Recording::open(dir.string()).entries().size(), 1u);
  // Creating over an existing recording is refused.
  EXPECT_THROW(RecordingWriter::createStereo(dir.string(), rig, options()), ConfigError);
}

TEST(Recording, NotARecordingIsAOneLineError) {
  const fs::path dir = testDir();
  fs::create_directories(dir);
  try {
    Recording::open(dir.string());
    FAIL() << "no exception";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), (dir / "recording.json").string() + ": missing: not a refgrasp recording");
  }
  std::ofstream(dir / "recording.json") << R"({"format": "refgrasp-recording", "version": 7, "kind": "mono"})";
  try {
    Recording::open(dir.string());
    FAIL() << "no exception";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("version: 7 is not supported"), std::string::npos) << e.what();
  }
  EXPECT_THROW(Recording::open((dir / "nope").string()), ConfigError);
}

// Damage at the end of a recording: each case reads the frames before it, with one warning.
TEST(Recording, DamagedRecordingsAreReadUpToTheLastGoodFrame) {
  const StereoRig rig = smallRig();
  const auto make = [&](const std::string& name) {
    const fs::path d = testDir(name);
    std::mt19937_64 rng(4);
    auto w = RecordingWriter::createStereo(d.string(), rig, options());
    for (int i = 0; i < 4; ++i) EXPECT_TRUE(w->write(stereoFrame(rng, i, rig)).ok);
    return d;
  };
  struct Case {
    std::string name, expect;
    std::function<void(const fs::path&)> damage;
  };
  const std::vector<Case> cases = {
      {"_truncated_line", "line 4: truncated (no end of line)",
       [](const fs::path& d) {
         std::string s = readText(d / "index.jsonl");
         s.resize(s.size() - 20);
         std::ofstream(d / "index.jsonl", std::ios::binary) << s;
       }},
      {"_garbage_line", "line 5: not valid JSON",
       [](const fs::path& d) { std::ofstream(d / "index.jsonl", std::ios::app) << "{\"frame\": 4, \"ind\n"; }},
      {"_missing_image", "000003_right.png is missing or truncated",
       [](const fs::path& d) { fs::remove(d / "frames/000003_right.png"); }},
      {"_truncated_image", "000003_left.png is missing or truncated",
       [](const fs::path& d) {
         const fs::path p = d / "frames/000003_left.png";
         fs::resize_file(p, fs::file_size(p) / 2);
       }},
  };
  for (const Case& c : cases) {
    const fs::path d = make(c.name);
    c.damage(d);
    const Recording rec = Recording::open(d.string());
    const size_t expected = c.name == "_garbage_line" ? 4u : 3u;
    EXPECT_EQ(rec.entries().size(), expected) << c.name;
    EXPECT_NE(rec.warning().find(c.expect), std::string::npos) << c.name << ": " << rec.warning();
    EXPECT_NE(rec.warning().find("read the " + std::to_string(expected) + " frames before it"),
              std::string::npos)
        << rec.warning();
    EXPECT_EQ(rec.warning().find('\n'), std::string::npos);
    for (size_t i = 0; i < rec.entries().size(); ++i) {
      robot::StereoFrame f;
      std::string err;
      EXPECT_TRUE(rec.read(i, &f, &err)) << c.name << " " << i << ": " << err;
    }
  }
}

// A recorder SIGKILLed while writing 640x480 frames as fast as it can: what is left reads
// cleanly up to the last frame whose index line was complete.
TEST(Recording, ARecorderKilledMidWriteLeavesAReadableRecording) {
  const fs::path dir = testDir();
  const StereoRig rig = smallRig(640, 480);
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    std::mt19937_64 rng(5);
    auto w = RecordingWriter::createStereo(dir.string(), rig, options(false));
    for (int i = 0;; ++i)
      if (!w->write(stereoFrame(rng, i, rig)).ok) _exit(3);
  }
  // Kill it once it has written a few frames, at whatever instant that is.
  const auto start = std::chrono::steady_clock::now();
  while (lineCount(dir / "index.jsonl") < 3 &&
         std::chrono::steady_clock::now() - start < std::chrono::seconds(30))
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  std::this_thread::sleep_for(std::chrono::milliseconds(7));
  kill(child, SIGKILL);
  int status = 0;
  waitpid(child, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "the recorder was not killed";
  const Recording rec = Recording::open(dir.string());
  EXPECT_GE(rec.entries().size(), 3u) << rec.warning();
  std::printf("killed after %zu complete frames; warning: '%s'\n", rec.entries().size(),
              rec.warning().c_str());
  auto src = files::makeRecordingStereoSource(Recording::open(dir.string()));
  size_t n = 0;
  for (;;) {
    std::optional<robot::StereoFrame> f;
    const robot::ReturnType r = src->grab(0, &f);
    if (r == robot::ReturnType::kDeactivate) break;
    ASSERT_EQ(r, robot::ReturnType::kOk) << src->lastError();
    EXPECT_EQ(f->index, 100 + 2 * static_cast<int64_t>(n));
    ++n;
  }
  EXPECT_EQ(n, rec.entries().size());
}

namespace {

// Runs `record` in a forked child whose files may not grow beyond `limit_bytes`
// (RLIMIT_FSIZE, SIGXFSZ ignored: writes fail with EFBIG as on a full disk). `record` calls
// `failed(error, frame, exit_code)` when a write reports the failure; the parent gets it back.
struct LimitedRun {
  int exit_code = -1;
  std::string error;
  int failed_at = -1;
};

using FailReport = std::function<void(const std::string& error, int frame, int exit_code)>;

LimitedRun recordWithFileSizeLimit(rlim_t limit_bytes, const std::function<void(const FailReport&)>& record) {
  const fs::path report = testDir("_report.txt");
  const pid_t child = fork();
  if (child == 0) {
    signal(SIGXFSZ, SIG_IGN);
    rlimit lim{limit_bytes, limit_bytes};
    if (setrlimit(RLIMIT_FSIZE, &lim) != 0) _exit(9);
    record([&](const std::string& error, int frame, int code) {
      rlimit none{RLIM_INFINITY, RLIM_INFINITY};
      setrlimit(RLIMIT_FSIZE, &none);  // the report itself must be written
      std::ofstream(report) << error << "\n" << frame << "\n";
      _exit(code);
    });
    _exit(4);  // no write failed: the test set-up is wrong
  }
  LimitedRun run;
  int status = 0;
  waitpid(child, &status, 0);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::istringstream lines(readText(report));
  std::getline(lines, run.error);
  lines >> run.failed_at;
  return run;
}

}  // namespace

TEST(Recording, ADiskThatFillsIsAnErrorAndTheRecordingReadsUpToTheLastGoodFrame) {
  // Frames 0-3 compress to a few kB (flat images); frame 4 is noise (~300 kB) and cannot be
  // written under a 100 kB file size limit.
  const fs::path dir = testDir();
  const StereoRig rig = smallRig(640, 480);
  const LimitedRun run = recordWithFileSizeLimit(100 * 1000, [&](const FailReport& failed) {
    std::mt19937_64 rng(6);
    auto w = RecordingWriter::createStereo(dir.string(), rig, options(true));
    for (int i = 0; i < 8; ++i) {
      robot::StereoFrame f = stereoFrame(rng, i, rig);
      if (i < 4) f.left = f.right = cv::Mat(480, 640, CV_8UC1, cv::Scalar(10 * i));
      const files::WriteStatus st = w->write(f);
      // Every later write fails too (the recording is not silently continued).
      if (!st.ok) failed(st.error, i, !st.fatal ? 6 : w->write(stereoFrame(rng, i + 1, rig)).ok ? 5 : 0);
    }
  });
  ASSERT_EQ(run.exit_code, 0);
  EXPECT_EQ(run.failed_at, 4);
  EXPECT_NE(run.error.find("000004_left.png: write failed: File too large"), std::string::npos)
      << run.error;
  const Recording rec = Recording::open(dir.string());
  EXPECT_EQ(rec.entries().size(), 4u);
  EXPECT_TRUE(rec.warning().empty()) << rec.warning();
  for (size_t i = 0; i < 4; ++i) {
    robot::StereoFrame f;
    std::string e;
    ASSERT_TRUE(rec.read(i, &f, &e)) << e;
    EXPECT_EQ(f.left.at<uchar>(0, 0), 10 * i);
  }
  // The failed frame left no file behind (not even a temporary).
  for (const auto& e : fs::directory_iterator(dir / "frames"))
    EXPECT_EQ(e.path().filename().string().rfind("000004", 0), std::string::npos) << e.path();
}

TEST(Recording, AnIndexThatCannotGrowIsAnErrorAndLeavesNoPartialLine) {
  // Tiny frames: the index is the largest file and hits the limit mid-line.
  const fs::path dir = testDir();
  const StereoRig rig = smallRig(8, 6);
  const LimitedRun run = recordWithFileSizeLimit(4000, [&](const FailReport& failed) {
    std::mt19937_64 rng(7);
    auto w = RecordingWriter::createStereo(dir.string(), rig, options(false));
    for (int i = 0; i < 100; ++i) {
      const files::WriteStatus st = w->write(stereoFrame(rng, i, rig));
      if (!st.ok) failed(st.error, i, 0);
    }
  });
  ASSERT_EQ(run.exit_code, 0);
  const int failed_at = run.failed_at;
  EXPECT_NE(run.error.find("index.jsonl: write failed: File too large"), std::string::npos) << run.error;
  const Recording rec = Recording::open(dir.string());
  EXPECT_EQ(rec.entries().size(), static_cast<size_t>(failed_at));
  EXPECT_GT(failed_at, 2);
  EXPECT_TRUE(rec.warning().empty()) << rec.warning();  // the partial line was cut off
  const std::string index = readText(dir / "index.jsonl");
  EXPECT_EQ(index.back(), '\n');
  // The frame whose line could not be written left no images.
  EXPECT_FALSE(fs::exists(dir / "frames" / (std::string(failed_at < 10 ? "00000" : "0000") +
                                            std::to_string(failed_at) + "_left.png")));
}

namespace {

// A mono recording of `frames` small frames in a fresh folder named after the test.
fs::path monoRecording(const std::string& name, int frames) {
  const fs::path d = testDir(name);
  std::mt19937_64 rng(8);
  auto w = RecordingWriter::createMono(d.string(), smallCamera(16, 12), options());
  for (int i = 0; i < frames; ++i) {
    robot::MonoFrame f;
    f.image = noiseImage(rng, 16, 12);
    f.stamp = i * 0.1;
    f.index = i;
    EXPECT_TRUE(w->write(f).ok);
  }
  return d;
}

// The one-line ConfigError of Recording::open and the seconds it took.
std::pair<std::string, double> openError(const fs::path& d) {
  const auto t0 = std::chrono::steady_clock::now();
  std::string e = "(no error)";
  try {
    Recording::open(d.string());
  } catch (const ConfigError& x) {
    e = x.what();
  }
  return {e, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()};
}

}  // namespace

// Memory bombs: the index and recording.json are bounded before anything is read into memory
// (core/file.h forEachLine / readRegularFile). Sparse files make them cheap.
TEST(Recording, IndexAndMetadataBombsAreOneLineErrorsInBoundedTime) {
  const fs::path d = monoRecording("", 3);
  const std::string index = (d / "index.jsonl").string(), meta = (d / "recording.json").string();
  const uintmax_t good_size = fs::file_size(index);
  // Three good lines, then 6 GiB of NUL bytes (no '\n'): over the size limit, refused from its size.
  fs::resize_file(index, good_size + (uintmax_t{6} << 30));
  auto [e, s] = openError(d);
  EXPECT_EQ(e, index + ": is " + std::to_string(good_size + (uintmax_t{6} << 30)) +
                   " bytes, more than the limit of 4294967296");
  EXPECT_LT(s, 0.5);
  // Under the size limit (3 GiB of NUL bytes): the line limit stops the read at line 4.
  fs::resize_file(index, good_size + (uintmax_t{3} << 30));
  std::tie(e, s) = openError(d);
  EXPECT_EQ(e, index + ": line 4: longer than the limit of 1048576 bytes");
  EXPECT_LT(s, 2.0);
  fs::resize_file(index, files::kMaxIndexBytes + 1);
  std::tie(e, s) = openError(d);
  EXPECT_EQ(e, index + ": is 4294967297 bytes, more than the limit of 4294967296");
  // A long line of text with no NUL: the same limit.
  fs::resize_file(index, good_size);
  std::ofstream(index, std::ios::app) << "{\"frame\": 3, \"index\": \"" << std::string(3 << 20, '9');
  std::tie(e, s) = openError(d);
  EXPECT_EQ(e, index + ": line 4: longer than the limit of 1048576 bytes");
  // recording.json is a configuration file: 4 MiB at most.
  fs::resize_file(index, good_size);
  fs::resize_file(meta, uintmax_t{1} << 30);
  std::tie(e, s) = openError(d);
  EXPECT_EQ(e, meta + ": is 1073741824 bytes, more than the limit of 4194304");
  EXPECT_LT(s, 0.5);
}

TEST(Recording, FifosInARecordingAreOneLineErrorsNotHangs) {
  const fs::path d = monoRecording("", 2);
  // A frame the index names is a FIFO: the recording ends before it (PNG check without blocking).
  fs::remove(d / "frames/000001.png");
  ASSERT_EQ(::mkfifo((d / "frames/000001.png").c_str(), 0600), 0);
  const Recording rec = Recording::open(d.string());
  EXPECT_EQ(rec.entries().size(), 1u);
  EXPECT_NE(rec.warning().find("000001.png is missing or truncated; read the 1 frames before it"),
            std::string::npos)
      << rec.warning();
  for (const char* name : {"index.jsonl", "recording.json"}) {
    const fs::path p = d / name, saved = d / (std::string(name) + ".saved");
    fs::rename(p, saved);
    ASSERT_EQ(::mkfifo(p.c_str(), 0600), 0);
    EXPECT_EQ(openError(d).first, p.string() + ": is a FIFO, not a regular file");
    fs::remove(p);
    fs::rename(saved, p);
  }
}

// "Nothing to do" is said: a recording without a frame to read is an error, not an empty success.
TEST(Recording, ARecordingWithoutFramesSaysNothingToDo) {
  const fs::path d = monoRecording("", 0);
  const std::string index = (d / "index.jsonl").string();
  EXPECT_EQ(openError(d).first, index + ": no frames (an empty recording): nothing to do");
  std::ofstream(index) << "{\"frame\": 0, \"ind\n";
  EXPECT_EQ(openError(d).first,
            index + ": line 1: not valid JSON; no frame before it: nothing to do");
  std::ofstream(index) << std::string(100, '\0');  // a crash's NUL tail and nothing before it
  EXPECT_EQ(openError(d).first,
            index + ": line 1: truncated (no end of line); no frame before it: nothing to do");
  fs::remove(index);
  EXPECT_EQ(openError(d).first, index + ": missing");
}
