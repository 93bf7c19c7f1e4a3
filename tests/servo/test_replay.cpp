// The pose replay in-process: modes and poses on a rendered sequence where the target leaves the
// view and passes behind an occluder; identical output twice; the report files; the tracker seam
// (a scripted tracker); frames the detector cannot use.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <sstream>

#include "common/replay_sequence.h"
#include "robot/sim/synthetic_sequence.h"
#include "common/temp_dir.h"
#include "detector/detector.h"
#include "servo/replay.h"
#include "servo/replay_report.h"

namespace fs = std::filesystem;
using namespace refgrasp;
using servo::TrackMode;

namespace {

const std::string kSource = REFGRASP_SOURCE_DIR;

detector::Detector& teaBoxDetector() {
  static detector::Detector det = [] {
    detector::Detector d;
    d.addObject(detector::loadObjectDefinition(kSource + "/config/objects/tea_box.yaml"));
    return d;
  }();
  return det;
}

const std::vector<refgrasp::testing::SequenceFrame>& sequence() {
  static const std::vector<refgrasp::testing::SequenceFrame> s = refgrasp::testing::renderOcclusionSequence();
  return s;
}

std::vector<servo::ReplayFrame> replayAll(servo::PoseReplay& replay) {
  std::vector<servo::ReplayFrame> out;
  const Intrinsics cam = refgrasp::testing::sceneCamera();
  for (size_t k = 0; k < sequence().size(); ++k)
    out.push_back(replay.process(static_cast<int64_t>(k), sequence()[k].frame, cam));
  return out;
}

std::string readText(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

size_t lines(const std::string& s) { return static_cast<size_t>(std::count(s.begin(), s.end(), '\n')); }

// A scripted tracker: follows the ground truth for `frames` frames after each start, then loses.
struct ScriptedTracker : servo::FrameTracker {
  const std::vector<Pose>* truth = nullptr;
  int frames = 0, left = 0;
  size_t now = 0;  ///< the frame being processed (set by the test)
  std::vector<size_t>* started_at = nullptr;
  servo::TrackStep start(const cv::Mat&, const Intrinsics&, const Pose& cMo) override {
    left = frames;
    started_at->push_back(now);
    return {true, cMo, {}, ""};
  }
  servo::TrackStep track(const cv::Mat&, const Intrinsics&, const std::optional<Pose>&) override {
    if (left-- <= 0) return {false, Pose(), {}, "scripted loss"};
    return {true, (*truth)[now], {}, ""};
  }
};

}  // namespace

TEST(PoseReplay, DetectOnlyModesAndPosesOnAnOcclusionSequence) {
  const auto& seq = sequence();
  servo::PoseReplay replay(teaBoxDetector());
  EXPECT_FALSE(replay.tracking());  // no tracker given: detection on every frame
  const std::vector<servo::ReplayFrame> a = replayAll(replay);
  ASSERT_EQ(a.size(), seq.size());
  int visible = 0, hidden = 0, detected = 0;
  std::string modes;
  for (size_t k = 0; k < seq.size(); ++k) {
    const servo::ObjectFrame& o = a[k].objects.at(0);
    ASSERT_TRUE(a[k].ok) << a[k].error;
    EXPECT_EQ(o.name, "tea_box");
    ASSERT_TRUE(o.truth_cMo.has_value());
    modes += o.mode == TrackMode::kDetect ? 'D' : o.mode == TrackMode::kTrack ? 'T' : '.';
    if (o.mode == TrackMode::kDetect) ++detected;
    if (seq[k].visible >= 0.95) {
      ++visible;
      ASSERT_EQ(o.mode, TrackMode::kDetect) << "frame " << k << " fully visible";
      ASSERT_TRUE(o.cMo && o.corners);
      const double dist = o.truth_cMo->t.norm();
      EXPECT_LT(translationError(*o.cMo, *o.truth_cMo), 0.01 * dist) << "frame " << k;
      EXPECT_LT(rotationError(*o.cMo, *o.truth_cMo) * 180 / M_PI, 1.0) << "frame " << k;
    } else if (seq[k].visible <= 0.05) {
      ++hidden;
      EXPECT_EQ(o.mode, TrackMode::kLost) << "frame " << k << " invisible ("
                                          << seq[k].visible << ")";
      EXPECT_FALSE(o.cMo.has_value());
    }
  }
  std::printf("modes (D detect, . lost): %s; %d fully visible, %d hidden, %d detected of %zu\n",
              modes.c_str(), visible, hidden, detected, seq.size());
  // The sequence does what it says: the target is fully visible, out of view and occluded.
  EXPECT_GE(visible, 12);
  EXPECT_GE(hidden, 6);
  EXPECT_LE(seq[10].visible, 0.05);  // out of view
  EXPECT_LE(seq[21].visible, 0.05);  // behind the occluder
  EXPECT_GE(seq.back().visible, 0.95);  // out again on its left

  // Deterministic: a second replay gives the same poses.jsonl lines (the first 12 frames, found
  // and lost ones; the app test compares whole files).
  servo::PoseReplay again(teaBoxDetector());
  for (size_t k = 0; k < 12; ++k) {
    const servo::ReplayFrame b = again.process(static_cast<int64_t>(k), seq[k].frame, refgrasp::testing::sceneCamera());
    EXPECT_EQ(servo::ReplayReport::jsonLines(a[k], false), servo::ReplayReport::jsonLines(b, false)) << k;
  }

  // The report files.
  const fs::path out = refgrasp::testing::tempDir("refgrasp_test_replay") / "report";
  fs::remove_all(out);
  {
    servo::ReplayReportOptions ro;
    ro.input = "rendered sequence";
    servo::ReplayReport report(out.string(), teaBoxDetector(), ro);
    std::string err;
    for (size_t k = 0; k < a.size(); ++k)
      ASSERT_TRUE(report.add(a[k], seq[k].frame.image, refgrasp::testing::sceneCamera(), &err)) << err;
    ASSERT_TRUE(report.finish(&err)) << err;
  }
  const std::string jsonl = readText(out / "poses.jsonl");
  EXPECT_EQ(lines(jsonl), seq.size());
  const nlohmann::json first = nlohmann::json::parse(jsonl.substr(0, jsonl.find('\n')));
  EXPECT_EQ(first["frame"], 0);
  EXPECT_EQ(first["mode"], "detect");
  EXPECT_TRUE(first["found"].get<bool>());
  EXPECT_EQ(first["R"].size(), 9u);
  EXPECT_EQ(first["corners"].size(), 4u);
  EXPECT_LT(first["error"]["translation_m"].get<double>(), 0.009);
  EXPECT_FALSE(first.contains("time_ms"));  // timings are not deterministic
  EXPECT_EQ(lines(readText(out / "trajectory.tum")), 1u + detected);  // header + one per pose
  EXPECT_EQ(lines(readText(out / "truth.tum")), 1u + seq.size());
  EXPECT_EQ(lines(readText(out / "poses.csv")), 1u + seq.size());
  const nlohmann::json summary = nlohmann::json::parse(readText(out / "summary.json"));
  EXPECT_EQ(summary["frames"], seq.size());
  EXPECT_EQ(summary["objects"][0]["modes"]["detect"], detected);
  EXPECT_EQ(summary["objects"][0]["modes"]["lost"], static_cast<int>(seq.size()) - detected);
  EXPECT_GE(summary["objects"][0]["lost_segments"].size(), 2u);  // out of view, occluded
  EXPECT_LT(summary["objects"][0]["ground_truth"]["translation_error_m"]["median"].get<double>(), 0.005);
  const cv::Mat plot = cv::imread((out / "plot.png").string());
  EXPECT_EQ(plot.cols, 1280);
  EXPECT_GT(plot.rows, 8 * 100);  // 6 pose panels + 2 error panels
  cv::VideoCapture video((out / "overlay.mp4").string());
  ASSERT_TRUE(video.isOpened());
  cv::Mat frame;
  int n = 0;
  for (; video.read(frame); ++n) EXPECT_EQ(frame.size(), cv::Size(640, 480));
  EXPECT_EQ(n, static_cast<int>(seq.size()));
}

// The tracker seam: detect -> track while the tracker follows -> detect again when it loses,
// lost when neither works; --no-track (options.track = false) never tracks.
TEST(PoseReplay, ATrackerRunsBetweenDetectionsAndDetectionResumesWhenItLoses) {
  const auto& seq = sequence();
  std::vector<Pose> truth;
  for (const auto& f : seq) truth.push_back(f.frame.truth[0].cMo);
  std::vector<size_t> started_at;
  ScriptedTracker* tracker = nullptr;
  servo::ReplayOptions options;
  options.pipeline.confirm_detections = 1;  // confirmation has its own test (test_target_tracker)
  servo::PoseReplay replay(teaBoxDetector(), options, [&](const detector::ObjectModel&) {
    auto t = std::make_unique<ScriptedTracker>();
    t->truth = &truth;
    t->frames = 2;
    t->started_at = &started_at;
    tracker = t.get();
    return t;
  });
  ASSERT_TRUE(replay.tracking());
  std::string modes;
  for (size_t k = 0; k < 12; ++k) {  // frames 0-5 visible, then leaving the view
    tracker->now = k;
    const servo::ReplayFrame r = replay.process(static_cast<int64_t>(k), seq[k].frame, refgrasp::testing::sceneCamera());
    const servo::ObjectFrame& o = r.objects[0];
    modes += o.mode == TrackMode::kDetect ? 'D' : o.mode == TrackMode::kTrack ? 'T' : '.';
    if (o.mode == TrackMode::kTrack) {
      ASSERT_TRUE(o.cMo && o.corners);
      EXPECT_EQ(o.cMo->t, truth[k].t);
      EXPECT_FALSE(o.detection.found);
    }
  }
  // Detect, track twice, the tracker loses and frame 3 is detected again, ...; once the target
  // has left the view (frames 9-11) nothing finds it.
  EXPECT_EQ(modes.substr(0, 7), "DTTDTTD") << modes;
  EXPECT_EQ(modes.substr(9), "...") << modes;
  ASSERT_GE(started_at.size(), 3u);
  EXPECT_EQ(started_at[0], 0u);
  EXPECT_EQ(started_at[1], 3u);
  EXPECT_EQ(started_at[2], 6u);

  servo::ReplayOptions no_track;
  no_track.track = false;
  servo::PoseReplay detect_only(teaBoxDetector(), no_track, [&](const detector::ObjectModel&) {
    return std::make_unique<ScriptedTracker>();
  });
  EXPECT_FALSE(detect_only.tracking());
}

TEST(PoseReplay, AFrameTheDetectorCannotUseIsAOneLineErrorAndResetsTheTrackers) {
  std::vector<size_t> started_at;
  std::vector<Pose> truth(4);
  ScriptedTracker* tracker = nullptr;
  servo::PoseReplay replay(teaBoxDetector(), {}, [&](const detector::ObjectModel&) {
    auto t = std::make_unique<ScriptedTracker>();
    t->truth = &truth;
    t->frames = 100;
    t->started_at = &started_at;
    tracker = t.get();
    return t;
  });
  tracker->now = 0;
  const servo::ReplayFrame a = replay.process(0, sequence()[0].frame, refgrasp::testing::sceneCamera());
  EXPECT_EQ(a.objects[0].mode, TrackMode::kDetect);
  robot::MonoFrame small;
  small.image = cv::Mat(240, 320, CV_8UC1, cv::Scalar(0));
  const servo::ReplayFrame b = replay.process(1, small, refgrasp::testing::sceneCamera());
  EXPECT_FALSE(b.ok);
  EXPECT_EQ(b.error, "image is 320x240, the camera calibration is 640x480");
  EXPECT_EQ(b.objects[0].mode, TrackMode::kLost);
  // The tracker was reset: the next good frame is detected, not tracked.
  tracker->now = 2;
  const servo::ReplayFrame c = replay.process(2, sequence()[1].frame, refgrasp::testing::sceneCamera());
  EXPECT_EQ(c.objects[0].mode, TrackMode::kDetect);
  const servo::ReplayFrame d = replay.failed(3, {0.2, -1}, "x.png: cannot decode as an image");
  EXPECT_FALSE(d.ok);
  const std::vector<std::string> line = servo::ReplayReport::jsonLines(d, false);
  EXPECT_EQ(line.at(0), R"({"frame":3,"index":-1,"stamp":0.2,"mode":"lost","found":false,"error_text":"x.png: cannot decode as an image"})");
}

// The robot's pipeline with the project's tracker (what pose_replay runs by default) against
// detection on every frame (--no-track), on the occlusion sequence: the tracked poses keep the
// detector's tolerances, the modes change where the target leaves, hides and comes back, the
// output is the same twice, and far fewer frames need the detector.
TEST(PoseReplay, TrackingFollowsTheSequenceWithinTheDetectorsTolerances) {
  const auto& seq = sequence();
  const auto trackers = servo::planarTrackerFactory({}, &teaBoxDetector());
  servo::PoseReplay tracked(teaBoxDetector(), {}, trackers);
  ASSERT_TRUE(tracked.tracking());
  const std::vector<servo::ReplayFrame> a = replayAll(tracked);
  servo::ReplayOptions no_track;
  no_track.track = false;
  servo::PoseReplay detect_only(teaBoxDetector(), no_track, trackers);
  ASSERT_FALSE(detect_only.tracking());
  const std::vector<servo::ReplayFrame> b = replayAll(detect_only);
  std::string modes, modes_b;
  int poses = 0, poses_b = 0, calls = 0, calls_b = 0, track_frames = 0;
  double worst_rot = 0, worst_trans = 0;
  for (size_t k = 0; k < seq.size(); ++k) {
    const servo::ObjectFrame& o = a[k].objects.at(0);
    const servo::ObjectFrame& ob = b[k].objects.at(0);
    ASSERT_TRUE(a[k].ok && b[k].ok);
    modes += o.mode == TrackMode::kDetect ? 'D' : o.mode == TrackMode::kTrack ? 'T' : '.';
    modes_b += ob.mode == TrackMode::kDetect ? 'D' : ob.mode == TrackMode::kTrack ? 'T' : '.';
    poses += o.cMo.has_value();
    poses_b += ob.cMo.has_value();
    calls += a[k].detector_calls;
    calls_b += b[k].detector_calls;
    track_frames += o.mode == TrackMode::kTrack;
    EXPECT_EQ(o.cMo.has_value(), o.corners.has_value()) << k;
    if (o.cMo) {
      const double dist = o.truth_cMo->t.norm();
      const double trans = translationError(*o.cMo, *o.truth_cMo) / dist;
      const double rot = rotationError(*o.cMo, *o.truth_cMo) * 180 / M_PI;
      worst_trans = std::max(worst_trans, trans);
      worst_rot = std::max(worst_rot, rot);
      EXPECT_LT(trans, 0.01) << "frame " << k;
      if (seq[k].visible >= 0.95) {
        EXPECT_LT(rot, 1.0) << "frame " << k;
      } else {
        EXPECT_LT(rot, 3.0) << "frame " << k << " partly visible (" << seq[k].visible << ")";
      }
    }
    if (seq[k].visible >= 0.95) {
      EXPECT_NE(o.mode, TrackMode::kLost) << "frame " << k << " fully visible";
    }
    if (seq[k].visible <= 0.05) {
      EXPECT_EQ(o.mode, TrackMode::kLost) << "frame " << k << " invisible";
    }
    if (o.mode == TrackMode::kTrack) {
      EXPECT_TRUE(o.confirmed) << k;
    }
  }
  std::printf("tracked:  %s (%d poses, %d detector calls; worst %.3f %% of distance, %.2f deg)\n"
              "no-track: %s (%d poses, %d detector calls)\n",
              modes.c_str(), poses, calls, 100 * worst_trans, worst_rot, modes_b.c_str(), poses_b, calls_b);
  // Detect, confirm, then track while it is in view; lost out of view and behind the panel; found
  // again by the detector; tracked at the end.
  EXPECT_EQ(modes.substr(0, 6), "DDTTTT") << modes;
  EXPECT_EQ(modes.substr(9, 5), ".....") << modes;
  EXPECT_EQ(modes[14], 'D') << modes;  // re-entering: whole-frame detection
  EXPECT_EQ(modes.substr(21, 3), "...") << modes;
  EXPECT_EQ(modes.substr(28), "TTTT") << modes;
  EXPECT_GE(track_frames, 12);
  EXPECT_GE(poses, poses_b);
  EXPECT_LE(3 * (poses - track_frames), 2 * poses_b) << "the tracker spares the detector";
  // Deterministic: the same poses.jsonl lines again.
  servo::PoseReplay again(teaBoxDetector(), {}, trackers);
  const std::vector<servo::ReplayFrame> c = replayAll(again);
  for (size_t k = 0; k < seq.size(); ++k)
    EXPECT_EQ(servo::ReplayReport::jsonLines(a[k], false), servo::ReplayReport::jsonLines(c[k], false)) << k;
}

// Tracking against detection alone on a rendered sequence of three passes: the camera swings
// to a 78 deg oblique view and back, slides until the target leaves the view and back, and
// slides until a panel hides it and back (motion blur, noise). Detection alone misses the
// oblique views; tracking gives a pose on more frames, within the detector's tolerances, with
// the modes following the scene, and the same output twice.
TEST(PoseReplay, TrackingGivesMorePosesThanDetectionAlone) {
  namespace rt = refgrasp::testing;
  rt::TrackingSequenceSpec spec;
  spec.texture = "targets/tea_box.png";
  spec.width_m = 0.20;
  spec.frames = 120;
  spec.exposure_fraction = 0.15;
  spec.path = [](double t) {
    const auto bump = [](double u) { return 0.5 * (1 - std::cos(2 * M_PI * u)); };  // 0 -> 1 -> 0
    if (t < 1.0 / 3) {
      rt::ViewPoint v;
      v.distance_m = 0.8;
      v.tilt_rad = 78 * M_PI / 180 * bump(3 * t);
      return v;
    }
    if (t < 2.0 / 3) return rt::sidewaysView(0.7 * bump(3 * t - 1), 0.0, 0.8);
    return rt::sidewaysView(-0.45 * bump(3 * t - 2), 0.0, 0.8);
  };
  spec.occluders.push_back({rt::loadMedia("clutter/clutter_03.png"), 0.16, 0.5,
                            Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(-0.22, 0, -0.4))});
  const rt::TrackingSequence seq = rt::renderTrackingSequence(spec);
  detector::Detector det;
  det.addObject(detector::textureObject("tea_box", rt::loadMedia(spec.texture), spec.width_m));
  servo::ReplayOptions no_track;
  no_track.track = false;
  const auto trackers = servo::planarTrackerFactory({}, &det);
  servo::PoseReplay tracked(det, {}, trackers), again(det, {}, trackers), detect_only(det, no_track);
  std::string modes, modes_b;
  int poses = 0, poses_b = 0, hidden = 0, missed_b = 0;
  double worst_rot = 0, worst_trans = 0;
  for (size_t k = 0; k < seq.mono.size(); ++k) {
    const servo::ReplayFrame ra = tracked.process(static_cast<int64_t>(k), seq.mono[k], seq.camera);
    const servo::ReplayFrame rb = detect_only.process(static_cast<int64_t>(k), seq.mono[k], seq.camera);
    if (k < 50) {  // the oblique views and the way out of the view
      const servo::ReplayFrame rc = again.process(static_cast<int64_t>(k), seq.mono[k], seq.camera);
      EXPECT_EQ(servo::ReplayReport::jsonLines(ra, false), servo::ReplayReport::jsonLines(rc, false)) << k;
    }
    const servo::ObjectFrame& a = ra.objects[0];
    const servo::ObjectFrame& b = rb.objects[0];
    modes += a.mode == TrackMode::kDetect ? 'D' : a.mode == TrackMode::kTrack ? 'T' : '.';
    modes_b += b.mode == TrackMode::kDetect ? 'D' : b.mode == TrackMode::kTrack ? 'T' : '.';
    poses += a.cMo.has_value();
    poses_b += b.cMo.has_value();
    // Tracking never loses a pose detection gives, and holds every full view detection misses.
    EXPECT_TRUE(a.cMo || !b.cMo) << k;
    if (!b.cMo && seq.visible[k] >= 0.95) {
      ++missed_b;
      EXPECT_TRUE(a.cMo.has_value()) << k;
    }
    if (seq.visible[k] <= 0.05) {
      ++hidden;
      EXPECT_EQ(a.mode, TrackMode::kLost) << k;
      EXPECT_EQ(b.mode, TrackMode::kLost) << k;
    }
    if (seq.visible[k] >= 0.95) { EXPECT_NE(a.mode, TrackMode::kLost) << k; }
    // What the robot may use: confirmed poses in full view keep the tolerances (a detection in
    // a blurred frame can be far off; confirmation is what keeps it from the robot).
    if (a.cMo && a.confirmed && seq.visible[k] >= 0.95) {
      const double rot = rotationError(*a.cMo, seq.truth[k]) * 180 / M_PI;
      const double trans = translationError(*a.cMo, seq.truth[k]) / seq.truth[k].t.norm();
      worst_rot = std::max(worst_rot, rot);
      worst_trans = std::max(worst_trans, trans);
      EXPECT_LT(rot, 1.0) << k;
      EXPECT_LT(trans, 0.01) << k;
    }
  }
  std::printf("tracked:  %s (%d poses; in full view worst %.2f deg, %.3f %% of the distance)\n"
              "no-track: %s (%d poses)\n",
              modes.c_str(), poses, worst_rot, 100 * worst_trans, modes_b.c_str(), poses_b);
  std::printf("full views detection alone misses: %d\n", missed_b);
  EXPECT_GE(hidden, 6);
  EXPECT_GE(missed_b, 8) << "the oblique views are beyond detection alone";
  EXPECT_GE(poses, poses_b + missed_b) << "tracking holds the oblique views detection misses";
  EXPECT_EQ(modes.substr(0, 3), "DDT");
  EXPECT_NE(modes.find(".D"), std::string::npos) << "found again after leaving the view";
  EXPECT_EQ(modes.back(), 'T');
}
