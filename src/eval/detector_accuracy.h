#pragma once
// The detector on rendered scenes with ground truth by construction (robot/sim/synthetic_scene.h):
// the figures of docs/results.md "Accuracy". tests/detector asserts on these runs;
// bench_accuracy prints their tables. Every run is seeded: the same call gives the same figures.
//   poseAccuracy     both pose methods on the same matches, and Detector::detect, on random poses
//   jitterDepths     the depth of one still pose over noisy renders
//   stereoJitter     the left, right and fused poses of one still stereo pose
//   hardCases        the paper matcher against the ratio baseline on Section III-B's hard cases
//   falsePositives   every target registered, over clutter frames that contain none of them
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/pose.h"

namespace refgrasp::eval {

/// The q-quantile of v by nearest rank (0.5: the median, 1: the maximum); NaN when v is empty.
double quantile(std::vector<double> v, double q);

/// Sample standard deviation (n - 1 in the denominator); NaN for fewer than 2 values.
double sampleStd(const std::vector<double>& v);

/// Position jitter of poses of one still target: the square root of the summed per-axis sample
/// variances of t, metres.
double positionJitter(const std::vector<Pose>& poses);

/// Errors of one pose method over frames; "ok" = rotation < 1 deg and translation < 1 % of the
/// distance.
struct PoseErrors {
  std::vector<double> rot_deg, rel_t;  ///< of the frames with a pose: degrees, fraction of the distance
  int n = 0;                           ///< frames
  int ok = 0;                          ///< frames with a pose within the bars
  void add(const std::optional<Pose>& estimate, const Pose& truth);
  double rate() const { return n ? static_cast<double>(ok) / n : 0; }
};

struct PoseAccuracyFrame {
  Pose truth;                          ///< cMo
  double tilt_deg = 0;                 ///< angle between the target's normal and the optical axis
  int inliers = 0;                     ///< of the matcher's first instance (0: no instance)
  std::optional<Pose> paper, refined;  ///< both methods on that instance
  std::optional<Pose> detected;        ///< Detector::detect (the default method, the sanity check)
  std::optional<double> detected_corner_px;  ///< detect()'s worst corner error when it found the target
};

struct PoseAccuracy {
  std::vector<PoseAccuracyFrame> frames;
  PoseErrors paper, refined, detected;
};

/// The default detector on `poses` random visible poses of the 20 cm poster
/// (targets/poster_concert.png) at 0.3-1.2 m, tilt 0-50 deg, noise 2, motion blur 0-1.5 px in a
/// random direction, over clutter; the poses drawn from `seed`, frame i rendered with seed 1000 + i.
PoseAccuracy poseAccuracy(int poses = 48, uint64_t seed = 2024);

/// Detector::detect's depth Z (metres) of the poster at 0.5 m (one pose, mildly tilted) in
/// `frames` renders, noise 2, frame i rendered with seed 77 + i; nullopt where it gave no pose.
std::vector<std::optional<double>> jitterDepths(int frames = 50);

struct StereoJitterFrame {
  bool ok = false;    ///< detectStereo's
  std::string error;  ///< its one line when not ok
  size_t objects = 0;
  bool fused = false;                           ///< a fused pose
  bool both = false;                            ///< fused from both eyes
  std::optional<Pose> left, right_in_left, lMo;  ///< when both: each eye's pose in the left camera, the fused pose
};

struct StereoJitter {
  Pose lMo_truth;
  std::vector<StereoJitterFrame> frames;
  /// Over the frames fused from both eyes: their count and the position jitter (metres) of the
  /// left eye's, the right eye's and the fused poses.
  struct Summary {
    int both = 0;
    double left_m = NAN, right_m = NAN, fused_m = NAN;
  };
  Summary summary() const;
};

/// detectStereo on `frames` noisy stereo renders of the poster at 0.8 m (a 12 cm baseline, ideal
/// cameras; frame i's eyes seeded 500 + 2i and 501 + 2i).
StereoJitter stereoJitter(int frames = 30);

/// Instances found by the paper matcher and by the ratio baseline (found = the four projected
/// texture corners within 3 px of distinct true targets).
struct HardCaseRow {
  std::string category;
  int paper = 0, ratio = 0, total = 0;
};

/// The hard cases of Section III-B, 10 seeded scenes each: small (20 cm at 1.4-1.8 m), motion
/// blur 8 px, repeated motif, symmetric (found up to the square's symmetries), 3 instances.
std::vector<HardCaseRow> hardCases();

struct FalsePositiveRun {
  int frames = 0;
  size_t objects = 0;       ///< registered
  int detections = 0;       ///< found instances: each a false detection
  int sanity_rejected = 0;  ///< matcher candidates the sanity check refused
  double total_ms = 0;      ///< Detector::detect's own time, summed
  std::vector<std::string> failed;           ///< "frame i: <error>" where detect() failed
  std::vector<std::string> false_detections;  ///< "frame i: false detection of <texture> (n inliers)"
};

/// The default detector with the five target textures registered (20 cm wide) over `frames`
/// clutter frames (clutterBackground(100000 + i)) that contain none of them, each with noise 2 as
/// in the rendered scenes (drawn from one generator seeded with `noise_seed`).
FalsePositiveRun falsePositivesOnClutter(int frames = 500, uint64_t noise_seed = 100000);

}  // namespace refgrasp::eval
