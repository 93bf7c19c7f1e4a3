// Tracking on realistic data: a pose on (nearly) every frame of a sequence where
// single-frame detection finds about half. The object is a real photograph (media/photos/)
// defined by a *photograph* of it (taken at 30 deg under other light, its region traced as a
// polygon: what make_reference is given); the sequence comes through another camera with its own
// look (gain, gamma, gradient, vignetting, noise per frame, JPEG) while the camera backs away to
// 3.8 m at up to 60 deg and comes back. Ground truth from the renderer.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "detector/detector.h"
#include "detector/object.h"
#include "robot/sim/realistic_scene.h"
#include "robot/sim/synthetic_scene.h"
#include "robot/sim/synthetic_sequence.h"
#include "servo/replay.h"
#include "servo/tracker.h"

using namespace refgrasp;
namespace rt = refgrasp::testing;
using servo::TrackMode;

TEST(RealisticTracking, APoseOnNearlyEveryFrameWhereDetectionFindsAboutHalf) {
  const std::string texture = "photos/butterfly_on_leaf.jpg";
  const cv::Mat tex = rt::loadMedia(texture);
  const double w = 0.20, h = w * tex.rows / tex.cols;
  rt::ReferencePhotoSpec ps;
  ps.tilt_rad = 30 * M_PI / 180;
  ps.width_px = 240;
  ps.look_strength = 0.5;
  ps.seed = 9;
  const rt::ReferencePhoto photo = rt::photographReference(tex, w, h, ps);
  detector::Detector det;
  det.addObject(detector::makeObjectModel("butterfly", photo.image, photo.camera, photo.cMo, photo.polygon_px));

  rt::TrackingSequenceSpec spec;
  spec.texture = texture;
  spec.width_m = w;
  spec.frames = 120;
  spec.noise_sigma = 0;  // the look adds it
  spec.seed = 21;
  spec.path = [](double t) {
    const double u = 0.5 * (1 - std::cos(2 * M_PI * t));  // 0 -> 1 -> 0
    rt::ViewPoint v;
    v.distance_m = 1.0 + 2.8 * u;
    v.tilt_rad = 60 * M_PI / 180 * std::sin(M_PI * t);
    v.tilt_dir_rad = 0.6;
    v.roll_rad = 0.2 * std::sin(3 * M_PI * t);
    return v;
  };
  rt::TrackingSequence seq = rt::renderTrackingSequence(spec);
  rt::CameraLook look;
  look.gain = 0.8;
  look.gamma = 1.25;
  look.gradient = 0.25;
  look.gradient_angle_rad = 0.4;
  look.vignetting = 0.25;
  look.defocus_sigma_px = 0.6;
  look.noise_sigma = 3;
  look.jpeg_quality = 80;
  std::mt19937_64 rng(5);
  for (auto& f : seq.mono) rt::applyCameraLook(f.image, look, rng);

  servo::ReplayOptions no_track;
  no_track.track = false;
  servo::PoseReplay tracked(det, {}, servo::planarTrackerFactory({}, &det)), detect_only(det, no_track);
  std::string modes, modes_b;
  int poses = 0, poses_b = 0, in_view = 0, good = 0, good_b = 0;
  double worst_rot = 0, worst_trans = 0, worst_rot_b = 0, worst_trans_b = 0;
  for (size_t k = 0; k < seq.mono.size(); ++k) {
    const servo::ObjectFrame a = tracked.process(static_cast<int64_t>(k), seq.mono[k], seq.camera).objects[0];
    const servo::ObjectFrame b = detect_only.process(static_cast<int64_t>(k), seq.mono[k], seq.camera).objects[0];
    modes += a.mode == TrackMode::kDetect ? 'D' : a.mode == TrackMode::kTrack ? 'T' : '.';
    modes_b += b.mode == TrackMode::kDetect ? 'D' : '.';
    in_view += seq.visible[k] >= 0.95;
    const auto ok = [&](const std::optional<Pose>& p, double* rot, double* trans) {
      if (!p) return false;
      *rot = rotationError(*p, seq.truth[k]) * 180 / M_PI;
      *trans = translationError(*p, seq.truth[k]) / seq.truth[k].t.norm();
      return *rot < 2.0 && *trans < 0.02;  // the realistic sets' "pose ok"
    };
    double rot = 0, trans = 0;
    if (a.cMo && a.confirmed) {
      ++poses;
      good += ok(a.cMo, &rot, &trans);
      EXPECT_LT(rot, 3.0) << k;
      EXPECT_LT(trans, 0.03) << k;
      worst_rot = std::max(worst_rot, rot);
      worst_trans = std::max(worst_trans, trans);
    }
    if (b.cMo) {
      ++poses_b;
      good_b += ok(b.cMo, &rot, &trans);
      worst_rot_b = std::max(worst_rot_b, rot);
      worst_trans_b = std::max(worst_trans_b, trans);
    }
  }
  std::printf("tracked:  %s\n  %d confirmed poses, %d within 2 deg and 2 %% (worst %.2f deg, %.2f %%)\n"
              "no-track: %s\n  %d poses, %d within 2 deg and 2 %% (worst %.2f deg, %.2f %%); %d frames in full view\n",
              modes.c_str(), poses, good, worst_rot, 100 * worst_trans, modes_b.c_str(), poses_b, good_b,
              worst_rot_b, 100 * worst_trans_b, in_view);
  EXPECT_EQ(in_view, 120);
  // The data: single-frame detection gives a correct pose on 40-70 % of the frames; a few wrong
  // ones are allowed (the far views' mirror pose, 90 deg off with the right position: the planar
  // ambiguity a single frame cannot resolve, which is why the robot's pipeline confirms and then
  // tracks). The far half of the path (beyond ~2.5 m, up to 60 deg) stays out of single-frame
  // reach. The figures: docs/results.md "Tracking on realistic data".
  // The upper bound is no regression check: it keeps the sequence beyond single-frame detection,
  // without which the tracking figures below would show nothing. A detector that passes it
  // calls for a harder path, not a looser bound.
  EXPECT_LE(good_b, 84);
  EXPECT_GE(good_b, 48);
  EXPECT_GE(good_b, poses_b - 8);
  // Tracking: a confirmed pose on nearly every frame (never the first: confirmation needs a
  // second agreeing detection), nearly all within the realistic sets' 2 deg and 2 % and, as
  // asserted per frame above, every one within 3 deg and 3 %.
  EXPECT_GE(poses, 115);
  EXPECT_GE(good, poses - 3);
}
