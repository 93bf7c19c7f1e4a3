#pragma once
// The IEEE-1394 (IIDC) camera calls the Bumblebee2 source needs, behind a small interface so that
// everything around them is tested without a camera (tests use a scripted double); the real
// implementation is libdc1394 2.x (makeLibDc1394Device). No call here throws: false / kError plus
// a one-line error.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace refgrasp::dc1394 {

struct CameraInfo {
  uint64_t guid = 0;
  int unit = 0;
  std::string vendor, model;  ///< e.g. "Point Grey Research", "Bumblebee2 BB2-08S2C"
};

/// What setup() programs: Format7 mode 3 with 16-bit pixels (one byte of each sensor), the ROI
/// of one sensor, the iso packet size (which sets the frame rate in Format7), exposure and gain.
struct CaptureConfig {
  int width = 640, height = 480;      ///< pixels per sensor
  bool raw16 = true;                  ///< RAW16 (colour sensors, Bayer mosaic) or MONO16
  uint32_t packet_bytes = 0;          ///< iso packet size, a multiple of the mode's unit
  std::optional<double> shutter_s;    ///< manual absolute shutter; empty = auto exposure
  std::optional<double> gain_db;      ///< manual absolute gain; empty = auto gain
  int dma_buffers = 4;                ///< driver ring buffer
};

/// A frame as the driver delivers it; the data stays valid until enqueue().
struct RawFrame {
  const uint8_t* data = nullptr;  ///< width * height 16-bit pixels, 2 bytes each
  size_t bytes = 0;
  int width = 0, height = 0;
  uint64_t timestamp_us = 0;       ///< libdc1394: host time (Unix, µs) the frame's DMA completed
  uint32_t packets_per_frame = 0;  ///< iso packets (125 µs each) the frame took on the bus
  uint32_t frames_behind = 0;      ///< frames still waiting in the ring buffer
};

enum class DequeueStatus { kFrame, kNone, kError };

class Dc1394Device {
 public:
  virtual ~Dc1394Device() = default;
  /// Cameras on the bus (none is not an error).
  virtual bool enumerate(std::vector<CameraInfo>* cameras, std::string* error) = 0;
  virtual bool open(const CameraInfo& camera, std::string* error) = 0;
  /// Vendor (Point Grey) control registers, offsets from the camera's command register base.
  virtual bool readRegister(uint64_t offset, uint32_t* value, std::string* error) = 0;
  virtual bool writeRegister(uint64_t offset, uint32_t value, std::string* error) = 0;
  /// Format7 mode 3 packet size limits (bytes) for config's ROI and coding.
  virtual bool packetLimits(const CaptureConfig& config, uint32_t* unit_bytes,
                            uint32_t* max_bytes, std::string* error) = 0;
  /// Programs the mode, ROI, packet size, shutter and gain, sets up capture and starts
  /// transmission.
  virtual bool setup(const CaptureConfig& config, std::string* error) = 0;
  /// Non-blocking: the oldest frame in the ring buffer (kFrame), none yet (kNone), or kError.
  /// Every kFrame must be given back with enqueue() before the next dequeue().
  virtual DequeueStatus dequeue(RawFrame* frame, std::string* error) = 0;
  virtual bool enqueue(std::string* error) = 0;
  /// Stops transmission and capture, releases the camera (idempotent).
  virtual void stop() = 0;
};

/// libdc1394 2.x. Its own log messages are collected into the returned errors instead of being
/// printed.
std::unique_ptr<Dc1394Device> makeLibDc1394Device();

}  // namespace refgrasp::dc1394
