// The tracker and the per-frame pipeline (servo/tracker.h, servo/target_tracker.h) on rendered
// sequences with ground truth: a camera orbiting a fixed target (0.4-1.8 m, tilts to 50 deg,
// roll, motion blur, noise), the target leaving the view and hidden, re-detection through the
// prior then the whole frame, confirmation, stereo against mono, determinism, bad options.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "detector/detector.h"
#include "robot/sim/synthetic_scene.h"
#include "robot/sim/synthetic_sequence.h"
#include "servo/target_tracker.h"
#include "servo/tracker.h"

using namespace refgrasp;
namespace rt = refgrasp::testing;
using servo::TrackMode;

namespace {

constexpr double kDeg = 180.0 / M_PI;
const char* kTexture = "targets/cereal_box.png";
constexpr double kWidth = 0.25;

const detector::ObjectModel& targetModel() {
  static const detector::ObjectModel m =
      detector::textureObject("target", rt::loadMedia(kTexture), kWidth);
  return m;
}

const detector::Detector& targetDetector() {
  static const detector::Detector d = [] {
    detector::Detector det;
    det.addObject(targetModel());
    return det;
  }();
  return d;
}

const rt::TrackingSequence& orbit() {
  static const rt::TrackingSequence s = [] {
    rt::TrackingSequenceSpec spec;
    spec.texture = kTexture;
    spec.width_m = kWidth;
    return rt::renderTrackingSequence(spec);
  }();
  return s;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

struct Errors {
  std::vector<double> rot_deg, trans_frac;
  int frames = 0, with_pose = 0;
  void add(const Pose& est, const Pose& truth) {
    rot_deg.push_back(rotationError(est, truth) * kDeg);
    trans_frac.push_back(translationError(est, truth) / truth.t.norm());
  }
  double maxRot() const { return rot_deg.empty() ? 0 : *std::max_element(rot_deg.begin(), rot_deg.end()); }
  double maxTrans() const {
    return trans_frac.empty() ? 0 : *std::max_element(trans_frac.begin(), trans_frac.end());
  }
};

}  // namespace

// The FrameTracker alone, started at the first frame's ground truth and never restarted, the
// camera's motion predicted by the last frame-to-frame motion.
TEST(PlanarTracker, FollowsAnOrbitingCameraWithinTheDetectorsTolerances) {
  const auto& seq = orbit();
  auto tracker = servo::planarTrackerFactory({}, &targetDetector())(targetDetector().object(0));
  const servo::TrackStep s0 = tracker->start(seq.mono[0].image, seq.camera, seq.truth[0]);
  ASSERT_TRUE(s0.ok) << s0.lost_reason;
  EXPECT_GE(s0.quality.features, 20);  // 1.8 m away: the pattern is 76 px wide
  Errors e;
  std::optional<Pose> last = seq.truth[0], before;
  int aligned = 0;
  for (size_t k = 1; k < seq.mono.size(); ++k) {
    const Pose predicted = before ? *last * before->inverse() * *last : *last;
    const servo::TrackStep s = tracker->track(seq.mono[k].image, seq.camera, predicted);
    ASSERT_TRUE(s.ok) << "frame " << k << ": " << s.lost_reason;
    before = last;
    last = s.cMo;
    aligned += s.quality.aligned;
    e.add(s.cMo, seq.truth[k]);
    EXPECT_GE(s.quality.features, 12) << k;
    EXPECT_LT(s.quality.projection_error_px, 1.0) << k;
  }
  std::printf("tracked %zu frames (%d aligned): rotation median %.3f max %.3f deg, translation median "
              "%.3f%% max %.3f%% of the distance\n",
              seq.mono.size(), aligned, median(e.rot_deg), e.maxRot(), 100 * median(e.trans_frac),
              100 * e.maxTrans());
  EXPECT_LT(median(e.rot_deg), 1.0);
  EXPECT_LT(median(e.trans_frac), 0.01);
  EXPECT_LT(e.maxRot(), 2.0);
  EXPECT_LT(e.maxTrans(), 0.01);
  EXPECT_GE(aligned, static_cast<int>(seq.mono.size()) * 9 / 10);
}

// The pipeline: detected, confirmed by the next detection, then tracked to the end with the
// detector's accuracy.
TEST(TargetTracker, TracksTheOrbitWithTwoDetections) {
  const auto& seq = orbit();
  servo::TargetTracker pipeline(targetDetector());
  ASSERT_TRUE(pipeline.tracking());
  Errors e;
  std::string modes;
  int calls = 0;
  for (size_t k = 0; k < seq.mono.size(); ++k) {
    const servo::TargetFrame f = pipeline.process(seq.mono[k], seq.camera);
    ASSERT_TRUE(f.ok) << f.error;
    const servo::TargetState& s = f.objects.at(0);
    modes += s.mode == TrackMode::kDetect ? 'D' : s.mode == TrackMode::kTrack ? 'T' : '.';
    calls += f.detector_calls;
    ASSERT_TRUE(s.cMo) << k;
    e.add(*s.cMo, seq.truth[k]);
    EXPECT_EQ(s.confirmed, k > 0) << k;
  }
  std::printf("modes %s\ndetector calls %d; rotation median %.3f max %.3f deg, translation median %.3f%% max %.3f%%\n",
              modes.c_str(), calls, median(e.rot_deg), e.maxRot(), 100 * median(e.trans_frac), 100 * e.maxTrans());
  EXPECT_EQ(modes, "DD" + std::string(seq.mono.size() - 2, 'T'));
  EXPECT_EQ(calls, 2);
  EXPECT_LT(median(e.rot_deg), 1.0);
  EXPECT_LT(median(e.trans_frac), 0.01);
  EXPECT_LT(e.maxRot(), 2.0);
  EXPECT_LT(e.maxTrans(), 0.01);
}
