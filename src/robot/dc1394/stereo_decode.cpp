#include "robot/dc1394/stereo_decode.h"

#include <dc1394/conversions.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace refgrasp::dc1394 {

const char* toString(ColorFilter f) {
  switch (f) {
    case ColorFilter::kNone: return "none";
    case ColorFilter::kRGGB: return "RGGB";
    case ColorFilter::kGBRG: return "GBRG";
    case ColorFilter::kGRBG: return "GRBG";
    case ColorFilter::kBGGR: return "BGGR";
  }
  return "?";
}

ColorFilter colorFilterFromRegister(uint32_t value) {
  switch (value) {  // four ASCII letters, first one in the most significant byte
    case 0x52474742: return ColorFilter::kRGGB;
    case 0x47425247: return ColorFilter::kGBRG;
    case 0x47524247: return ColorFilter::kGRBG;
    case 0x42474752: return ColorFilter::kBGGR;
    default: return ColorFilter::kNone;  // "YYYY": monochrome
  }
}

std::optional<SensorInfo> sensorInfoFromRegister(uint32_t value) {
  switch (value & 0xF) {
    case 0xA: return SensorInfo{true, 640, 480};
    case 0xB: return SensorInfo{false, 640, 480};
    case 0xC: return SensorInfo{true, 1024, 768};
    case 0xD: return SensorInfo{false, 1024, 768};
    case 0xE: return SensorInfo{true, 1280, 960};
    case 0xF: return SensorInfo{false, 1280, 960};
    default: return std::nullopt;
  }
}

bool deinterlaceStereo(const uint8_t* raw, size_t bytes, int width, int height,
                       bool little_endian, cv::Mat* left, cv::Mat* right) {
  const size_t n = static_cast<size_t>(width) * static_cast<size_t>(height);
  if (width <= 0 || height <= 0 || bytes < 2 * n) return false;
  // dc1394_deinterlace_stereo takes the total size as width x (2 * height) bytes and does not
  // modify its source (the prototype is not const).
  std::vector<uint8_t> src(raw, raw + 2 * n);
  cv::Mat both(2 * height, width, CV_8UC1);
  if (dc1394_deinterlace_stereo(src.data(), both.data, static_cast<uint32_t>(width),
                                static_cast<uint32_t>(2 * height)) != DC1394_SUCCESS)
    return false;
  const cv::Mat even = both.rowRange(0, height), odd = both.rowRange(height, 2 * height);
  *right = (little_endian ? even : odd).clone();
  *left = (little_endian ? odd : even).clone();
  return true;
}

int bayerToBgrCode(ColorFilter f) {
  switch (f) {
    case ColorFilter::kRGGB: return cv::COLOR_BayerBG2BGR;
    case ColorFilter::kBGGR: return cv::COLOR_BayerRG2BGR;
    case ColorFilter::kGRBG: return cv::COLOR_BayerGB2BGR;
    case ColorFilter::kGBRG: return cv::COLOR_BayerGR2BGR;
    case ColorFilter::kNone: return -1;
  }
  return -1;
}

cv::Mat demosaic(const cv::Mat& mosaic, ColorFilter f) {
  if (f == ColorFilter::kNone) return mosaic.clone();
  cv::Mat bgr;
  cv::cvtColor(mosaic, bgr, bayerToBgrCode(f));
  return bgr;
}

uint32_t packetBytesForFrameRate(int width, int height, int bytes_per_pixel, double fps_hz,
                                 uint32_t unit_bytes, uint32_t max_bytes) {
  const double frame_bytes = static_cast<double>(width) * height * bytes_per_pixel;
  // At most this many 125 µs bus cycles per frame, so that a frame arrives every 1 / fps_hz.
  const double cycles = std::max(1.0, std::floor(8000.0 / fps_hz + 1e-9));
  const uint32_t unit = std::max<uint32_t>(unit_bytes, 1);
  const uint32_t packet =
      static_cast<uint32_t>(std::ceil(frame_bytes / cycles / unit - 1e-9)) * unit;
  const uint32_t top = std::max(unit, max_bytes - max_bytes % unit);
  return std::clamp(packet, unit, top);
}

double frameRateForPacketBytes(int width, int height, int bytes_per_pixel, uint32_t packet_bytes) {
  const double frame_bytes = static_cast<double>(width) * height * bytes_per_pixel;
  // A frame takes ceil(frame_bytes / packet) bus cycles of 125 µs.
  return 8000.0 / std::ceil(frame_bytes / packet_bytes);
}

Seconds exposureCentre(uint64_t dma_done_us, uint32_t packets_per_frame, double shutter_s) {
  return static_cast<double>(dma_done_us) * 1e-6 - packets_per_frame * 125e-6 - 0.5 * shutter_s;
}

}  // namespace refgrasp::dc1394
