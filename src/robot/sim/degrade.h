#pragma once
// Camera image degradations applied after rendering: motion blur (optics), brightness (exposure,
// gain), additive Gaussian noise (sensor), in that order, then rounding to 8 bits.
#include <opencv2/core.hpp>
#include <random>

namespace refgrasp::sim {

/// Longest motion blur, pixels: a scenario may ask for at most this much, and a blur computed
/// from the camera's motion is clamped to it (beyond it the whole view is a smear anyway).
constexpr double kMaxMotionBlurPx = 256;

struct Degradation {
  double noise_sigma = 0;            ///< additive Gaussian noise, gray levels (standard deviation)
  double motion_blur_px = 0;         ///< length of a linear blur kernel, pixels (0: none)
  double motion_blur_angle_rad = 0;  ///< blur direction in the image: 0 along +u, pi/2 along +v
  double brightness_gain = 1;        ///< out = gain * in + offset
  double brightness_offset = 0;      ///< gray levels
  /// Throws std::invalid_argument on negative or non-finite values, a non-positive gain or a
  /// blur longer than kMaxMotionBlurPx.
  void check() const;
};

/// Degrades a CV_8UC1 image in place. Deterministic given the state of `rng` (draws one number
/// from it when noise_sigma > 0, which seeds a fast per-pixel generator; the noise is drawn by
/// inverse CDF from 2^12 quantiles of the normal distribution, tails cut at ~3.5 sigma).
void degrade(cv::Mat& img, const Degradation& d, std::mt19937_64& rng);

/// Normalised CV_32F kernel of a straight blur of `length_px` along `angle_rad`, centred (a
/// symmetric kernel: blurring does not shift the image). 1x1 identity for length < 0.5 px (or
/// NaN); lengths beyond kMaxMotionBlurPx are clamped to it.
cv::Mat motionBlurKernel(double length_px, double angle_rad);

}  // namespace refgrasp::sim
