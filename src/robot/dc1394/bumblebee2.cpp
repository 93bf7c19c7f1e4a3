#include "robot/dc1394/bumblebee2.h"

#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <set>

#include "core/error.h"
#include "core/yaml.h"

namespace refgrasp::dc1394 {

using robot::ReturnType;

namespace {

const char* kWhere = "bb2";  // names the camera in start-up errors

std::string hexGuid(uint64_t guid) {
  char buf[24];
  std::snprintf(buf, sizeof(buf), "%016llx", static_cast<unsigned long long>(guid));
  return buf;
}

bool isBumblebee2(const CameraInfo& c) { return c.model.rfind("Bumblebee2", 0) == 0; }

}  // namespace

void Bumblebee2Options::check() const {
  refgrasp::check(std::isfinite(frame_rate_hz) && frame_rate_hz > 0 && frame_rate_hz <= 240,
                  "Bumblebee2Options.frame_rate_hz", "must be in (0, 240]");
  refgrasp::check(std::isfinite(shutter_s) && shutter_s >= 0 && shutter_s < 1,
                  "Bumblebee2Options.shutter_s", "must be in [0, 1) (0 = auto)");
  refgrasp::check(std::isfinite(gain_db), "Bumblebee2Options.gain_db", "must be finite");
  refgrasp::check(dma_buffers >= 2 && dma_buffers <= 64, "Bumblebee2Options.dma_buffers",
                  "must be in 2..64");
  refgrasp::check(guid.find_first_not_of("0123456789abcdefABCDEFx") == std::string::npos,
                  "Bumblebee2Options.guid", "must be hexadecimal");
}

Bumblebee2Options loadBumblebee2Options(const std::string& path) {
  const YamlFile f(path);
  const YAML::Node& root = f.root();
  static const std::set<std::string> kKeys = {"guid",        "frame_rate_hz", "shutter_s",
                                              "gain_db",     "dma_buffers",   "output_bgr"};
  if (root.IsMap())
    for (const auto& kv : root)
      if (!kKeys.count(kv.first.as<std::string>()))
        f.fail(kv.first.as<std::string>(), "unknown field");
  Bumblebee2Options o;
  o.guid = f.string(root, "guid", "");
  o.frame_rate_hz = f.number(root, "frame_rate_hz", o.frame_rate_hz);
  o.shutter_s = f.number(root, "shutter_s", o.shutter_s);
  o.gain_db = f.number(root, "gain_db", o.gain_db);
  o.dma_buffers = f.integer(root, "dma_buffers", o.dma_buffers);
  o.output_bgr = f.boolean(root, "output_bgr", o.output_bgr);
  try {
    o.check();
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();  // "Bumblebee2Options.<field>: <problem>"
    const size_t dot = what.find('.'), colon = what.find(": ");
    f.fail(what.substr(dot + 1, colon - dot - 1), what.substr(colon + 2));
  }
  return o;
}

Bumblebee2Camera::Bumblebee2Camera(std::unique_ptr<Dc1394Device> device, const StereoRig& rig,
                                   const Bumblebee2Options& options)
    : dev_(std::move(device)), rig_(rig), opt_(options) {
  opt_.check();
  std::string err;
  const auto fail = [&](const std::string& what) -> void {
    dev_->stop();
    throw ConfigError(kWhere, what);
  };
  std::vector<CameraInfo> cams;
  if (!dev_->enumerate(&cams, &err)) fail("cannot enumerate IEEE-1394 cameras: " + err);
  if (cams.empty()) fail("no IEEE-1394 camera found");
  const CameraInfo* pick = nullptr;
  uint64_t want = 0;
  if (!opt_.guid.empty()) want = std::stoull(opt_.guid, nullptr, 16);
  std::string seen;
  for (const CameraInfo& c : cams) {
    seen += (seen.empty() ? "" : ", ") + c.model + " " + hexGuid(c.guid);
    if (!pick && (opt_.guid.empty() ? isBumblebee2(c) : c.guid == want)) pick = &c;
  }
  if (!pick)
    fail((opt_.guid.empty() ? std::string("no Bumblebee2") : "no camera with GUID " + opt_.guid) +
         " among " + std::to_string(cams.size()) + " camera(s): " + seen);
  info_ = *pick;
  const std::string cam = info_.model + " " + hexGuid(info_.guid);
  if (!dev_->open(info_, &err)) fail(cam + ": cannot open: " + err);

  uint32_t value = 0;
  if (!dev_->readRegister(kPgrSensorBoardInfo, &value, &err))
    fail(cam + ": cannot read SENSOR_BOARD_INFO: " + err);
  const std::optional<SensorInfo> sensor = sensorInfoFromRegister(value);
  if (!sensor) fail(cam + ": unknown sensor (SENSOR_BOARD_INFO " + hexGuid(value) + ")");
  if (sensor->width != rig_.left.width || sensor->height != rig_.left.height ||
      sensor->width != rig_.right.width || sensor->height != rig_.right.height)
    fail(cam + ": sensor is " + std::to_string(sensor->width) + "x" +
         std::to_string(sensor->height) + ", the rig calibration is " +
         std::to_string(rig_.left.width) + "x" + std::to_string(rig_.left.height));
  if (sensor->colour) {
    if (!dev_->readRegister(kPgrBayerTileMapping, &value, &err))
      fail(cam + ": cannot read BAYER_TILE_MAPPING: " + err);
    filter_ = colorFilterFromRegister(value);
    if (filter_ == ColorFilter::kNone) fail(cam + ": colour sensor without a known Bayer pattern");
  }
  if (!dev_->writeRegister(kPgrImageDataFormat, kPgrLittleEndian, &err))
    fail(cam + ": cannot set little-endian 16-bit transfers: " + err);

  config_.width = sensor->width;
  config_.height = sensor->height;
  config_.raw16 = sensor->colour;
  config_.dma_buffers = opt_.dma_buffers;
  if (opt_.shutter_s > 0) config_.shutter_s = opt_.shutter_s;
  if (opt_.gain_db >= 0) config_.gain_db = opt_.gain_db;
  uint32_t unit = 0, max = 0;
  if (!dev_->packetLimits(config_, &unit, &max, &err))
    fail(cam + ": cannot read the Format7 packet limits: " + err);
  config_.packet_bytes =
      packetBytesForFrameRate(config_.width, config_.height, 2, opt_.frame_rate_hz, unit, max);
  fps_hz_ = frameRateForPacketBytes(config_.width, config_.height, 2, config_.packet_bytes);
  if (!dev_->setup(config_, &err)) fail(cam + ": cannot start Format7 mode 3 capture: " + err);
}

Bumblebee2Camera::~Bumblebee2Camera() { dev_->stop(); }

ReturnType Bumblebee2Camera::grab(Seconds, std::optional<robot::StereoFrame>* frame) {
  frame->reset();
  RawFrame raw;
  bool have = false;
  for (;;) {
    RawFrame next;
    const DequeueStatus st = dev_->dequeue(&next, &error_);
    if (st == DequeueStatus::kError) {
      error_ = "bb2: frame capture failed: " + error_;
      return ReturnType::kError;
    }
    if (st == DequeueStatus::kNone) break;
    ++dequeued_;
    if (next.frames_behind > 0) {  // a newer frame is waiting: this one is stale
      if (!dev_->enqueue(&error_)) {
        error_ = "bb2: " + error_;
        return ReturnType::kError;
      }
      continue;
    }
    raw = next;
    have = true;
    break;
  }
  if (!have) return ReturnType::kOk;
  robot::StereoFrame f;
  const bool ok = deinterlaceStereo(raw.data, raw.bytes, raw.width, raw.height, true, &f.left,
                                    &f.right);
  std::string enqueue_err;
  const bool given_back = dev_->enqueue(&enqueue_err);
  if (!ok || raw.width != config_.width || raw.height != config_.height) {
    error_ = "bb2: frame of " + std::to_string(raw.bytes) + " bytes, " +
             std::to_string(raw.width) + "x" + std::to_string(raw.height) +
             " pixels: not a Format7 mode 3 frame of " + std::to_string(config_.width) + "x" +
             std::to_string(config_.height);
    return ReturnType::kError;
  }
  if (!given_back) {
    error_ = "bb2: " + enqueue_err;
    return ReturnType::kError;
  }
  if (filter_ != ColorFilter::kNone) {
    f.left = demosaic(f.left, filter_);
    f.right = demosaic(f.right, filter_);
    if (!opt_.output_bgr) {
      cv::cvtColor(f.left, f.left, cv::COLOR_BGR2GRAY);
      cv::cvtColor(f.right, f.right, cv::COLOR_BGR2GRAY);
    }
  }
  f.stamp = exposureCentre(raw.timestamp_us, raw.packets_per_frame, opt_.shutter_s);
  f.index = dequeued_ - 1;
  *frame = std::move(f);
  return ReturnType::kOk;
}

}  // namespace refgrasp::dc1394
