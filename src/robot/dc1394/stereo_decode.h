#pragma once
// Pure decoding of Bumblebee2 frames (no device): Point Grey registers, de-interlacing of the
// Format7 mode 3 stereo stream, Bayer demosaicing, packet size <-> frame rate, capture stamps.
//
// Byte layout (Point Grey's own libdc1394 examples, pgrlibdcstereo): with IMAGE_DATA_FORMAT
// (0x1048) set to little endian (0x80000000, the Point Grey default), each 16-bit pixel of the
// mode-3 stream holds one byte of each sensor: the byte at even offset (low byte) is the RIGHT
// sensor, the byte at odd offset (high byte) the LEFT one. dc1394_deinterlace_stereo moves the even
// bytes to the first half of its output and the odd bytes to the second half, hence first half =
// right, second half = left. In big-endian mode (0x80000001) the bytes, and so the eyes, swap.
#include <cstdint>
#include <optional>
#include <opencv2/core.hpp>
#include <string>

#include "core/types.h"

namespace refgrasp::dc1394 {

// Point Grey control registers (offsets from the command register base).
inline constexpr uint64_t kPgrBayerTileMapping = 0x1040;  ///< ASCII "RGGB", "YYYY" (mono), ...
inline constexpr uint64_t kPgrImageDataFormat = 0x1048;   ///< 16-bit byte order
inline constexpr uint64_t kPgrSensorBoardInfo = 0x1F28;   ///< low nibble: sensor type
inline constexpr uint32_t kPgrLittleEndian = 0x80000000u;
inline constexpr uint32_t kPgrBigEndian = 0x80000001u;

/// The colour filter of the sensor, top-left 2x2 block read row by row.
enum class ColorFilter { kNone, kRGGB, kGBRG, kGRBG, kBGGR };
const char* toString(ColorFilter f);

/// BAYER_TILE_MAPPING value -> filter; "YYYY" (0x59595959) and unknown values are kNone.
ColorFilter colorFilterFromRegister(uint32_t value);

struct SensorInfo {
  bool colour = false;
  int width = 0, height = 0;
};
/// SENSOR_BOARD_INFO value (low nibble 0xA..0xF) -> sensor; empty for an unknown sensor.
std::optional<SensorInfo> sensorInfoFromRegister(uint32_t value);

/// Splits a Format7 mode 3 buffer of width x height 16-bit pixels into the two 8-bit images with
/// libdc1394's dc1394_deinterlace_stereo. little_endian: the byte order programmed in
/// IMAGE_DATA_FORMAT (see above). Returns false when `bytes` is too small.
bool deinterlaceStereo(const uint8_t* raw, size_t bytes, int width, int height,
                       bool little_endian, cv::Mat* left, cv::Mat* right);

/// OpenCV's cvtColor code for a mosaic with this filter. OpenCV names a Bayer pattern after the
/// second row's 2nd and 3rd pixels, so RGGB is COLOR_BayerBG2BGR, BGGR COLOR_BayerRG2BGR, GRBG
/// COLOR_BayerGB2BGR, GBRG COLOR_BayerGR2BGR. -1 for kNone.
int bayerToBgrCode(ColorFilter f);
/// Demosaics an 8-bit mosaic to BGR (OpenCV bilinear); a copy of the input for kNone.
cv::Mat demosaic(const cv::Mat& mosaic, ColorFilter f);

/// Format7: one iso packet per 125 µs bus cycle, a frame takes ceil(frame_bytes / packet_bytes)
/// cycles, so fps = 8000 / ceil(frame_bytes / packet_bytes). packetBytesForFrameRate: the smallest
/// multiple of unit_bytes giving at least fps_hz, clamped to [unit_bytes, max_bytes].
uint32_t packetBytesForFrameRate(int width, int height, int bytes_per_pixel, double fps_hz,
                                 uint32_t unit_bytes, uint32_t max_bytes);
double frameRateForPacketBytes(int width, int height, int bytes_per_pixel, uint32_t packet_bytes);

/// Exposure centre (seconds, host Unix clock) from libdc1394's stamp of the frame's DMA
/// completion: minus the transfer (packets_per_frame bus cycles of 125 µs) and half the shutter.
Seconds exposureCentre(uint64_t dma_done_us, uint32_t packets_per_frame, double shutter_s);

}  // namespace refgrasp::dc1394
