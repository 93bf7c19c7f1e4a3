#include "robot/degrade.h"

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "core/error.h"

namespace refgrasp::sim {

void Degradation::check() const {
  refgrasp::check(std::isfinite(noise_sigma) && noise_sigma >= 0, "Degradation.noise_sigma",
                  "must be finite and >= 0");
  refgrasp::check(std::isfinite(motion_blur_px) && motion_blur_px >= 0,
                  "Degradation.motion_blur_px", "must be finite and >= 0");
  refgrasp::check(std::isfinite(motion_blur_angle_rad), "Degradation.motion_blur_angle_rad",
                  "must be finite");
  refgrasp::check(std::isfinite(brightness_gain) && brightness_gain > 0,
                  "Degradation.brightness_gain", "must be finite and > 0");
  refgrasp::check(std::isfinite(brightness_offset), "Degradation.brightness_offset",
                  "must be finite");
}

cv::Mat motionBlurKernel(double length_px, double angle_rad) {
  if (!(length_px >= 0.5)) return cv::Mat::ones(1, 1, CV_32F);
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
  return k / cv::sum(k)[0];
}

void degrade(cv::Mat& img, const Degradation& d, std::mt19937_64& rng) {
  d.check();
  CV_Assert(img.type() == CV_8UC1);
  const bool blur = d.motion_blur_px >= 0.5;
  const bool affine = d.brightness_gain != 1 || d.brightness_offset != 0;
  if (!blur && !affine && d.noise_sigma <= 0) return;
  cv::Mat f;
  if (blur)
    cv::filter2D(img, f, CV_32F, motionBlurKernel(d.motion_blur_px, d.motion_blur_angle_rad),
                 cv::Point(-1, -1), 0, cv::BORDER_REFLECT);
  else
    img.convertTo(f, CV_32F);
  if (affine) f.convertTo(f, CV_32F, d.brightness_gain, d.brightness_offset);
  if (d.noise_sigma > 0) {
    cv::RNG cvrng(rng());
    cv::Mat noise(img.size(), CV_32F);
    cvrng.fill(noise, cv::RNG::NORMAL, 0.0, d.noise_sigma);
    f += noise;
  }
  f.convertTo(img, CV_8U);  // rounds and saturates
}

}  // namespace refgrasp::sim
