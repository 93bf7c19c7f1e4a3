#pragma once
// The Point Grey Bumblebee2 stereo camera over IEEE-1394 (libdc1394), as a robot::StereoSource.
//
// Start-up (constructor): enumerate the bus, pick the camera (by GUID, else the first whose model
// starts with "Bumblebee2"), read SENSOR_BOARD_INFO (sensor size, colour) and BAYER_TILE_MAPPING
// (the Bayer pattern), set little-endian 16-bit transfers, program Format7 mode 3 (RAW16 for
// colour sensors, MONO16 otherwise) with the iso packet size giving frame_rate_hz, shutter and
// gain (manual when set, else auto), and start transmission. Any failure, "no camera found"
// included, throws ConfigError with one line.
//
// grab(): non-blocking; drains the driver's ring buffer and returns the newest frame not returned
// before (older ones are dropped, they are stale), de-interlaced (robot/dc1394/stereo_decode.h:
// even bytes = right eye) and, for colour sensors, demosaiced with the camera's Bayer pattern
// and converted to gray (or kept BGR with output_bgr). stamp = exposure centre on the host Unix
// clock (libdc1394's DMA-completion stamp minus the transfer and half the shutter; with auto
// exposure the shutter is not known and taken as 0). index = frames dequeued so far (dropped
// ones included). A device error returns kError with lastError().
#include <memory>
#include <string>

#include "core/camera.h"
#include "robot/camera.h"
#include "robot/dc1394/device.h"
#include "robot/dc1394/stereo_decode.h"

namespace refgrasp::dc1394 {

struct Bumblebee2Options {
  std::string guid;             ///< hex ("00b09d0100a1b2c3"); "" = the first Bumblebee2
  double frame_rate_hz = 20;    ///< the Bumblebee2 delivers up to 48 at 640x480
  double shutter_s = 0;         ///< > 0: manual shutter; 0: auto exposure
  double gain_db = -1;          ///< >= 0: manual gain; < 0: auto
  int dma_buffers = 4;
  bool output_bgr = false;      ///< colour sensors: deliver BGR instead of gray
  void check() const;
};

/// Reads options from YAML (all keys optional: guid, frame_rate_hz, shutter_s, gain_db,
/// dma_buffers, output_bgr). Throws ConfigError "<file>: <field>: <problem>".
Bumblebee2Options loadBumblebee2Options(const std::string& path);

class Bumblebee2Camera : public robot::StereoSource {
 public:
  /// \param rig the calibration; its image sizes must match the sensor.
  Bumblebee2Camera(std::unique_ptr<Dc1394Device> device, const StereoRig& rig,
                   const Bumblebee2Options& options);
  ~Bumblebee2Camera() override;

  const StereoRig& rig() const override { return rig_; }
  robot::ReturnType grab(Seconds time, std::optional<robot::StereoFrame>* frame) override;
  std::string lastError() const override { return error_; }

  const CameraInfo& info() const { return info_; }
  ColorFilter colorFilter() const { return filter_; }
  /// The frame rate the programmed packet size gives (>= options.frame_rate_hz when reachable).
  double frameRateHz() const { return fps_hz_; }
  const CaptureConfig& config() const { return config_; }

 private:
  std::unique_ptr<Dc1394Device> dev_;
  StereoRig rig_;
  Bumblebee2Options opt_;
  CameraInfo info_;
  ColorFilter filter_ = ColorFilter::kNone;
  CaptureConfig config_;
  double fps_hz_ = 0;
  int64_t dequeued_ = 0;
  std::string error_;
};

}  // namespace refgrasp::dc1394
