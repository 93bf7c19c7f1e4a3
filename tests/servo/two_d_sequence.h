#pragma once
// A rendered sequence of a planar texture for the 2D-only tracker's tests: a slow camera motion
// (sway, distance change, tilt and roll) and a slow change of light (gain and a gradient across
// the image, applied per frame), the object registered 2D-only (no camera, no reference pose)
// and, for the ground truth, the same texture with its metric geometry.
#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "detector/object.h"
#include "robot/sim/realistic_scene.h"
#include "robot/sim/synthetic_scene.h"
#include "robot/sim/synthetic_sequence.h"

namespace refgrasp::testing {

inline constexpr const char* kTwoDTexture = "targets/cereal_box.png";
inline constexpr double kTwoDWidth = 0.25;

/// The texture with its metric geometry (ground truth corners only).
inline const detector::ObjectModel& twoDTruthModel() {
  static const detector::ObjectModel m = detector::textureObject("target", loadMedia(kTwoDTexture), kTwoDWidth);
  return m;
}

/// The texture registered 2D-only: H and corners, no pose.
inline const detector::ObjectModel& twoDModel() {
  static const detector::ObjectModel m =
      detector::makeObjectModel("target", loadMedia(kTwoDTexture), std::nullopt, std::nullopt);
  return m;
}

/// `frames` frames; one period of the motion every `period` frames, two of the light (so that
/// frames a whole period apart look alike). Deterministic given the seed.
inline TrackingSequence twoDSequence(int frames, int period, uint64_t seed) {
  TrackingSequenceSpec spec;
  spec.texture = kTwoDTexture;
  spec.width_m = kTwoDWidth;
  spec.frames = frames;
  spec.seed = seed;
  const double cycles = static_cast<double>(frames) / period;
  spec.path = [cycles](double t) { return swayPath(t, cycles); };
  TrackingSequence s = renderTrackingSequence(spec);
  std::mt19937_64 rng(seed);
  for (size_t k = 0; k < s.mono.size(); ++k) {
    const double b = 2 * M_PI * static_cast<double>(k) / (0.5 * period);
    CameraLook look;
    look.gain = 1 + 0.3 * std::sin(b);
    look.gradient = 0.2 * std::sin(0.5 * b);
    look.gradient_angle_rad = 0.5 * b;
    cv::Mat& img = s.mono[k].image;
    if (img.channels() == 1) applyCameraLook(img, look, rng);
  }
  return s;
}

/// The true pattern corners (TL, TR, BR, BL, image px) in frame k.
inline std::array<Eigen::Vector2d, 4> twoDTruthCorners(const TrackingSequence& s, size_t k) {
  std::array<Eigen::Vector2d, 4> c;
  for (size_t i = 0; i < 4; ++i) c[i] = s.camera.project(s.truth[k] * twoDTruthModel().target->corners_o[i]);
  return c;
}

/// Largest corner distance (px).
inline double cornerError(const std::array<Eigen::Vector2d, 4>& a, const std::array<Eigen::Vector2d, 4>& b) {
  double e = 0;
  for (size_t i = 0; i < 4; ++i) e = std::max(e, (a[i] - b[i]).norm());
  return e;
}

/// The q-quantile (0..1) of v (nearest rank); NaN when empty.
inline double quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())))];
}

}  // namespace refgrasp::testing
