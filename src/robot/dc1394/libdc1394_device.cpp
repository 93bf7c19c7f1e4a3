// Dc1394Device on libdc1394 2.x. Not covered by the tests (no FireWire camera in CI); everything
// around it is, through the scripted double in tests/robot/dc1394/.
#include <dc1394/dc1394.h>

#include <mutex>

#include "robot/dc1394/device.h"

namespace refgrasp::dc1394 {

namespace {

// libdc1394 prints its errors and warnings to stderr; collect them so that the caller reports
// one line instead. The handlers are process-wide; a mutex guards the shared buffer.
std::mutex g_log_mutex;
std::string g_log;

void collect(dc1394log_t, const char* message, void*) {
  std::lock_guard<std::mutex> lock(g_log_mutex);
  if (!g_log.empty()) g_log += "; ";
  g_log += message ? message : "?";
}

void installLogHandlers() {
  static std::once_flag once;
  std::call_once(once, [] {
    dc1394_log_register_handler(DC1394_LOG_ERROR, collect, nullptr);
    dc1394_log_register_handler(DC1394_LOG_WARNING, collect, nullptr);
  });
}

std::string takeLog() {
  std::lock_guard<std::mutex> lock(g_log_mutex);
  std::string s;
  s.swap(g_log);
  return s;
}

class LibDc1394Device : public Dc1394Device {
 public:
  LibDc1394Device() { installLogHandlers(); }
  ~LibDc1394Device() override {
    stop();
    if (ctx_) dc1394_free(ctx_);
  }

  bool enumerate(std::vector<CameraInfo>* cameras, std::string* error) override {
    cameras->clear();
    takeLog();
    if (!ctx_) ctx_ = dc1394_new();
    if (!ctx_) return fail(error, "libdc1394 could not start (no IEEE-1394 bus?)");
    dc1394camera_list_t* list = nullptr;
    if (dc1394_camera_enumerate(ctx_, &list) != DC1394_SUCCESS || !list) {
      // No /dev/fw* (no FireWire controller): libdc1394 reports that it found no bus.
      takeLog();
      return true;
    }
    for (uint32_t i = 0; i < list->num; ++i) {
      CameraInfo c;
      c.guid = list->ids[i].guid;
      c.unit = list->ids[i].unit;
      if (dc1394camera_t* cam = dc1394_camera_new_unit(ctx_, c.guid, c.unit)) {
        c.vendor = cam->vendor ? cam->vendor : "";
        c.model = cam->model ? cam->model : "";
        dc1394_camera_free(cam);
      }
      cameras->push_back(c);
    }
    dc1394_camera_free_list(list);
    takeLog();
    return true;
  }

  bool open(const CameraInfo& camera, std::string* error) override {
    if (!ctx_) return fail(error, "enumerate() first");
    cam_ = dc1394_camera_new_unit(ctx_, camera.guid, camera.unit);
    return cam_ || fail(error, "dc1394_camera_new_unit failed");
  }

  bool readRegister(uint64_t offset, uint32_t* value, std::string* error) override {
    return check(cam_ ? dc1394_get_control_register(cam_, offset, value) : DC1394_CAMERA_NOT_INITIALIZED,
                 "dc1394_get_control_register", error);
  }

  bool writeRegister(uint64_t offset, uint32_t value, std::string* error) override {
    return check(cam_ ? dc1394_set_control_register(cam_, offset, value) : DC1394_CAMERA_NOT_INITIALIZED,
                 "dc1394_set_control_register", error);
  }

  bool packetLimits(const CaptureConfig& config, uint32_t* unit, uint32_t* max,
                    std::string* error) override {
    if (!cam_) return fail(error, "no camera open");
    // The limits depend on the ROI and coding: program them first (packet size left alone).
    return check(dc1394_video_set_mode(cam_, DC1394_VIDEO_MODE_FORMAT7_3), "dc1394_video_set_mode", error) &&
           check(dc1394_format7_set_roi(cam_, DC1394_VIDEO_MODE_FORMAT7_3, coding(config),
                                        DC1394_QUERY_FROM_CAMERA, 0, 0, config.width, config.height),
                 "dc1394_format7_set_roi", error) &&
           check(dc1394_format7_get_packet_parameters(cam_, DC1394_VIDEO_MODE_FORMAT7_3, unit, max),
                 "dc1394_format7_get_packet_parameters", error);
  }

  bool setup(const CaptureConfig& config, std::string* error) override {
    if (!cam_) return fail(error, "no camera open");
    if (!check(dc1394_video_set_iso_speed(cam_, DC1394_ISO_SPEED_400), "dc1394_video_set_iso_speed", error) ||
        !check(dc1394_video_set_mode(cam_, DC1394_VIDEO_MODE_FORMAT7_3), "dc1394_video_set_mode", error) ||
        !check(dc1394_format7_set_roi(cam_, DC1394_VIDEO_MODE_FORMAT7_3, coding(config),
                                      static_cast<int32_t>(config.packet_bytes), 0, 0,
                                      config.width, config.height),
               "dc1394_format7_set_roi", error) ||
        !feature(DC1394_FEATURE_SHUTTER, config.shutter_s, error) ||
        !feature(DC1394_FEATURE_GAIN, config.gain_db, error) ||
        !check(dc1394_capture_setup(cam_, static_cast<uint32_t>(config.dma_buffers),
                                    DC1394_CAPTURE_FLAGS_DEFAULT),
               "dc1394_capture_setup", error))
      return false;
    capturing_ = true;
    if (!check(dc1394_video_set_transmission(cam_, DC1394_ON), "dc1394_video_set_transmission", error))
      return false;
    transmitting_ = true;
    return true;
  }

  DequeueStatus dequeue(RawFrame* frame, std::string* error) override {
    if (!capturing_) {
      fail(error, "capture not set up");
      return DequeueStatus::kError;
    }
    dc1394video_frame_t* f = nullptr;
    if (!check(dc1394_capture_dequeue(cam_, DC1394_CAPTURE_POLICY_POLL, &f), "dc1394_capture_dequeue", error))
      return DequeueStatus::kError;
    if (!f) return DequeueStatus::kNone;
    current_ = f;
    frame->data = f->image;
    frame->bytes = f->image_bytes;
    frame->width = static_cast<int>(f->size[0]);
    frame->height = static_cast<int>(f->size[1]);
    frame->timestamp_us = f->timestamp;
    frame->packets_per_frame = f->packets_per_frame;
    frame->frames_behind = f->frames_behind;
    return DequeueStatus::kFrame;
  }

  bool enqueue(std::string* error) override {
    if (!current_) return true;
    dc1394video_frame_t* f = current_;
    current_ = nullptr;
    return check(dc1394_capture_enqueue(cam_, f), "dc1394_capture_enqueue", error);
  }

  void stop() override {
    if (!cam_) return;
    std::string ignored;
    enqueue(&ignored);
    if (transmitting_) dc1394_video_set_transmission(cam_, DC1394_OFF);
    if (capturing_) dc1394_capture_stop(cam_);
    transmitting_ = capturing_ = false;
    dc1394_camera_free(cam_);
    cam_ = nullptr;
    takeLog();
  }

 private:
  static dc1394color_coding_t coding(const CaptureConfig& c) {
    return c.raw16 ? DC1394_COLOR_CODING_RAW16 : DC1394_COLOR_CODING_MONO16;
  }

  static bool fail(std::string* error, const std::string& what) {
    const std::string log = takeLog();
    *error = what + (log.empty() ? "" : " (libdc1394: " + log + ")");
    return false;
  }

  static bool check(dc1394error_t err, const char* call, std::string* error) {
    if (err == DC1394_SUCCESS) {
      takeLog();
      return true;
    }
    return fail(error, std::string(call) + ": " + dc1394_error_get_string(err));
  }

  // Manual absolute value when given, else the camera's auto mode.
  bool feature(dc1394feature_t f, const std::optional<double>& value, std::string* error) {
    if (!value) return check(dc1394_feature_set_mode(cam_, f, DC1394_FEATURE_MODE_AUTO), "dc1394_feature_set_mode", error);
    return check(dc1394_feature_set_mode(cam_, f, DC1394_FEATURE_MODE_MANUAL), "dc1394_feature_set_mode", error) &&
           check(dc1394_feature_set_absolute_control(cam_, f, DC1394_ON), "dc1394_feature_set_absolute_control", error) &&
           check(dc1394_feature_set_absolute_value(cam_, f, static_cast<float>(*value)),
                 "dc1394_feature_set_absolute_value", error);
  }

  dc1394_t* ctx_ = nullptr;
  dc1394camera_t* cam_ = nullptr;
  dc1394video_frame_t* current_ = nullptr;
  bool capturing_ = false, transmitting_ = false;
};

}  // namespace

std::unique_ptr<Dc1394Device> makeLibDc1394Device() { return std::make_unique<LibDc1394Device>(); }

}  // namespace refgrasp::dc1394
