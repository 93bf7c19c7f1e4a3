#include "robot/sim/degrade.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <opencv2/imgproc.hpp>

#include "core/error.h"

namespace refgrasp::sim {

void Degradation::check() const {
  refgrasp::check(std::isfinite(noise_sigma) && noise_sigma >= 0, "Degradation.noise_sigma",
                  "must be finite and >= 0");
  refgrasp::check(std::isfinite(motion_blur_px) && motion_blur_px >= 0 &&
                      motion_blur_px <= kMaxMotionBlurPx,
                  "Degradation.motion_blur_px", "must be in [0, 256]");
  refgrasp::check(std::isfinite(motion_blur_angle_rad), "Degradation.motion_blur_angle_rad",
                  "must be finite");
  refgrasp::check(std::isfinite(brightness_gain) && brightness_gain > 0,
                  "Degradation.brightness_gain", "must be finite and > 0");
  refgrasp::check(std::isfinite(brightness_offset), "Degradation.brightness_offset",
                  "must be finite");
}

cv::Mat motionBlurKernel(double length_px, double angle_rad) {
  if (!(length_px >= 0.5)) return cv::Mat::ones(1, 1, CV_32F);
  length_px = std::min(length_px, kMaxMotionBlurPx);  // the casts below stay far inside int
  // Snap near-axis directions so that angle and angle + pi give the identical kernel.
  const auto snap = [](double v) { return std::abs(v) < 1e-9 ? 0.0 : v; };
  const double c = snap(std::cos(angle_rad)), s = snap(std::sin(angle_rad));
  const int rx = static_cast<int>(std::ceil(std::abs(c) * length_px / 2)) + 1;
  const int ry = static_cast<int>(std::ceil(std::abs(s) * length_px / 2)) + 1;
  cv::Mat k = cv::Mat::zeros(2 * ry + 1, 2 * rx + 1, CV_32F);
  // Box-filtered segment: samples every 1/8 px, splatted bilinearly, mirrored for symmetry.
  const int n = static_cast<int>(std::ceil(length_px * 8)) + 1;
  for (int i = 0; i < n; ++i) {
    const double t = (n == 1 ? 0.0 : (i / (n - 1.0) - 0.5)) * length_px;
    const double x = rx + t * c, y = ry + t * s;
    const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
    const double fx = x - x0, fy = y - y0;
    k.at<float>(y0, x0) += static_cast<float>((1 - fx) * (1 - fy));
    k.at<float>(y0, x0 + 1) += static_cast<float>(fx * (1 - fy));
    k.at<float>(y0 + 1, x0) += static_cast<float>((1 - fx) * fy);
    k.at<float>(y0 + 1, x0 + 1) += static_cast<float>(fx * fy);
  }
  cv::Mat flipped;
  cv::flip(k, flipped, -1);
  k += flipped;
  // Crop to the non-zero support, symmetrically so the kernel stays centred (a horizontal blur
  // becomes a 1 x n kernel, much cheaper to apply).
  int cx = rx, cy = ry;
  for (int y = 0; y <= 2 * ry; ++y)
    for (int x = 0; x <= 2 * rx; ++x)
      if (k.at<float>(y, x) > 1e-7f * static_cast<float>(n)) {
        cx = std::min(cx, x);
        cy = std::min(cy, y);
      }
  k = k(cv::Rect(cx, cy, 2 * (rx - cx) + 1, 2 * (ry - cy) + 1)).clone();
  return k / cv::sum(k)[0];
}

namespace {

// Standard normal quantiles at the midpoints of 4096 equal-probability bins (16 KB, stays in L1):
// indexing it with a uniform 12-bit number draws from the normal distribution, tails cut at
// ~3.5 sigma (standard deviation 0.3 % low).
constexpr int kQuantileBits = 12;
using QuantileTable = std::array<float, 1 << kQuantileBits>;

const QuantileTable& normalQuantiles() {
  static const QuantileTable table = [] {
    QuantileTable t{};
    for (size_t i = 0; i < t.size(); ++i) {
      const double p = (static_cast<double>(i) + 0.5) / static_cast<double>(t.size());
      double x = 0;  // Newton on Phi(x) = p, Phi(x) = erfc(-x / sqrt 2) / 2
      for (int it = 0; it < 60; ++it) {
        const double err = 0.5 * std::erfc(-x / std::sqrt(2.0)) - p;
        const double pdf = std::exp(-0.5 * x * x) / std::sqrt(2 * M_PI);
        const double step = err / std::max(pdf, 1e-300);
        x -= std::clamp(step, -1.0, 1.0);
        if (std::abs(step) < 1e-12) break;
      }
      t[i] = static_cast<float>(x);
    }
    return t;
  }();
  return table;
}

uint64_t splitmix64(uint64_t* state) {
  uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

}  // namespace

void degrade(cv::Mat& img, const Degradation& d, std::mt19937_64& rng) {
  d.check();
  CV_Assert(img.type() == CV_8UC1);
  const bool blur = d.motion_blur_px >= 0.5;
  const bool affine = d.brightness_gain != 1 || d.brightness_offset != 0;
  if (!blur && !affine && d.noise_sigma <= 0) return;
  cv::Mat blurred;  // CV_32F when blurring
  if (blur)
    cv::filter2D(img, blurred, CV_32F, motionBlurKernel(d.motion_blur_px, d.motion_blur_angle_rad),
                 cv::Point(-1, -1), 0, cv::BORDER_REFLECT);
  const auto& q = normalQuantiles();
  uint64_t state = d.noise_sigma > 0 ? rng() : 0;
  const float gain = static_cast<float>(d.brightness_gain), offset = static_cast<float>(d.brightness_offset);
  const float sigma = static_cast<float>(d.noise_sigma);
  for (int y = 0; y < img.rows; ++y) {
    uchar* p = img.ptr<uchar>(y);
    const float* b = blur ? blurred.ptr<float>(y) : nullptr;
    uint64_t bits = 0;
    int left = 0;  // unused 12-bit draws in `bits`
    for (int x = 0; x < img.cols; ++x) {
      float v = gain * (b ? b[x] : static_cast<float>(p[x])) + offset;
      if (sigma > 0) {
        if (left == 0) {
          bits = splitmix64(&state);
          left = 64 / kQuantileBits;
        }
        v += sigma * q[bits & ((1u << kQuantileBits) - 1)];
        bits >>= kQuantileBits;
        --left;
      }
      p[x] = cv::saturate_cast<uchar>(v);  // rounds to nearest
    }
  }
}

}  // namespace refgrasp::sim
