// The Bumblebee2 source on a scripted IEEE-1394 bus (everything but the libdc1394 calls), and
// the real libdc1394 device on this machine's bus (no camera: a one-line error).
#include <gtest/gtest.h>

#include <deque>
#include <filesystem>
#include <fstream>
#include <map>

#include "common/temp_dir.h"
#include "core/error.h"
#include "robot/dc1394/bumblebee2.h"

using namespace refgrasp;
using namespace refgrasp::dc1394;
using robot::ReturnType;

namespace {

// A scripted bus with at most one camera; frames are queued raw buffers.
class FakeBus : public Dc1394Device {
 public:
  struct Frame {
    std::vector<uint8_t> data;
    int width = 640, height = 480;
    uint64_t timestamp_us = 0;
    uint32_t packets = 400;
  };
  std::vector<CameraInfo> cameras;
  std::map<uint64_t, uint32_t> registers;
  std::map<uint64_t, uint32_t> written;
  std::optional<CaptureConfig> setup_config;
  std::deque<Frame> frames;
  bool fail_dequeue = false, stopped = false;
  int enqueued = 0, dequeued = 0;
  bool holding = false;

  bool enumerate(std::vector<CameraInfo>* c, std::string*) override {
    *c = cameras;
    return true;
  }
  bool open(const CameraInfo&, std::string*) override { return true; }
  bool readRegister(uint64_t offset, uint32_t* v, std::string* error) override {
    const auto it = registers.find(offset);
    if (it == registers.end()) {
      *error = "no such register";
      return false;
    }
    *v = it->second;
    return true;
  }
  bool writeRegister(uint64_t offset, uint32_t v, std::string*) override {
    written[offset] = v;
    return true;
  }
  bool packetLimits(const CaptureConfig&, uint32_t* unit, uint32_t* max, std::string*) override {
    *unit = 4;
    *max = 4096;
    return true;
  }
  bool setup(const CaptureConfig& c, std::string*) override {
    setup_config = c;
    return true;
  }
  DequeueStatus dequeue(RawFrame* f, std::string* error) override {
    EXPECT_FALSE(holding) << "dequeue() before the previous frame was given back";
    if (fail_dequeue) {
      *error = "dc1394_capture_dequeue: Failure";
      return DequeueStatus::kError;
    }
    if (frames.empty()) return DequeueStatus::kNone;
    current_ = frames.front();
    frames.pop_front();
    f->data = current_.data.data();
    f->bytes = current_.data.size();
    f->width = current_.width;
    f->height = current_.height;
    f->timestamp_us = current_.timestamp_us;
    f->packets_per_frame = current_.packets;
    f->frames_behind = static_cast<uint32_t>(frames.size());
    ++dequeued;
    holding = true;
    return DequeueStatus::kFrame;
  }
  bool enqueue(std::string*) override {
    holding = false;
    ++enqueued;
    return true;
  }
  void stop() override { stopped = true; }

 private:
  Frame current_;
};

constexpr uint64_t kGuid = 0x00b09d0100a1b2c3ull;

FakeBus* colourBb2(std::unique_ptr<FakeBus>* owner) {
  *owner = std::make_unique<FakeBus>();
  FakeBus* bus = owner->get();
  bus->cameras.push_back({kGuid, 0, "Point Grey Research", "Bumblebee2 BB2-03S2C"});
  bus->registers[kPgrSensorBoardInfo] = 0xA;           // colour 640x480
  bus->registers[kPgrBayerTileMapping] = 0x42474752;   // "BGGR"
  return bus;
}

StereoRig rig640() {
  StereoRig rig;
  rig.left = rig.right = Intrinsics::pinhole(640, 480, 500, 319.5, 239.5);
  rig.lMr = Pose::fromRotationVector({0, 0, 0}, {0.12, 0, 0});
  return rig;
}

// A BGGR mosaic of a uniform colour in one byte of every pixel.
FakeBus::Frame uniformFrame(uint8_t left_gray_level, uint8_t right_gray_level, uint64_t t_us) {
  FakeBus::Frame f;
  f.timestamp_us = t_us;
  f.data.resize(2 * 640 * 480);
  for (int r = 0; r < 480; ++r)
    for (int c = 0; c < 640; ++c) {
      const size_t k = static_cast<size_t>(2 * (r * 640 + c));
      f.data[k] = right_gray_level;      // even byte: right eye
      f.data[k + 1] = left_gray_level;   // odd byte: left eye
    }
  return f;
}

std::string errorOf(std::unique_ptr<FakeBus> bus, const StereoRig& rig, Bumblebee2Options o = {}) {
  try {
    Bumblebee2Camera cam(std::move(bus), rig, o);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(Bumblebee2, StartUpProgramsFormat7Mode3FromTheCameraRegisters) {
  std::unique_ptr<FakeBus> owner;
  FakeBus* bus = colourBb2(&owner);
  Bumblebee2Options o;
  o.frame_rate_hz = 20;
  o.shutter_s = 0.008;
  Bumblebee2Camera cam(std::move(owner), rig640(), o);
  EXPECT_EQ(cam.colorFilter(), ColorFilter::kBGGR);
  EXPECT_EQ(bus->written.at(kPgrImageDataFormat), kPgrLittleEndian);
  ASSERT_TRUE(bus->setup_config.has_value());
  EXPECT_TRUE(bus->setup_config->raw16);
  EXPECT_EQ(bus->setup_config->width, 640);
  EXPECT_EQ(bus->setup_config->packet_bytes, 1536u);
  EXPECT_DOUBLE_EQ(cam.frameRateHz(), 20.0);
  ASSERT_TRUE(bus->setup_config->shutter_s.has_value());
  EXPECT_DOUBLE_EQ(*bus->setup_config->shutter_s, 0.008);
  EXPECT_FALSE(bus->setup_config->gain_db.has_value());  // auto gain
}

TEST(Bumblebee2, GrabReturnsTheNewestFrameDeinterlacedDemosaicedAndStamped) {
  std::unique_ptr<FakeBus> owner;
  FakeBus* bus = colourBb2(&owner);
  Bumblebee2Options o;
  o.shutter_s = 0.010;
  Bumblebee2Camera cam(std::move(owner), rig640(), o);
  std::optional<robot::StereoFrame> f;
  EXPECT_EQ(cam.grab(0, &f), ReturnType::kOk);  // nothing captured yet
  EXPECT_FALSE(f.has_value());
  bus->frames.push_back(uniformFrame(50, 60, 1000000000ull));  // stale by the time we grab
  bus->frames.push_back(uniformFrame(180, 90, 1000050000ull));
  ASSERT_EQ(cam.grab(0, &f), ReturnType::kOk) << cam.lastError();
  ASSERT_TRUE(f.has_value());
  EXPECT_EQ(bus->dequeued, 2);
  EXPECT_EQ(bus->enqueued, 2);  // both buffers given back
  EXPECT_EQ(f->index, 1);       // the second frame dequeued
  EXPECT_NEAR(f->stamp, 1000.05 - 400 * 125e-6 - 0.005, 1e-9);
  ASSERT_EQ(f->left.type(), CV_8UC1);  // gray by default
  // A uniform mosaic value v demosaics to (v, v, v) whatever the pattern: left 180, right 90.
  EXPECT_EQ(f->left.at<uint8_t>(240, 320), 180);
  EXPECT_EQ(f->right.at<uint8_t>(240, 320), 90);
  EXPECT_EQ(cam.grab(0, &f), ReturnType::kOk);
  EXPECT_FALSE(f.has_value());  // nothing new
}

TEST(Bumblebee2, ColourOutputUsesTheCameraBayerPattern) {
  std::unique_ptr<FakeBus> owner;
  FakeBus* bus = colourBb2(&owner);  // BGGR
  Bumblebee2Options o;
  o.output_bgr = true;
  Bumblebee2Camera cam(std::move(owner), rig640(), o);
  // Left sensor sees pure blue: B cells (even rows, even columns for BGGR) = 240, others 0.
  FakeBus::Frame fr = uniformFrame(0, 0, 1);
  for (int r = 0; r < 480; r += 2)
    for (int c = 0; c < 640; c += 2) fr.data[static_cast<size_t>(2 * (r * 640 + c) + 1)] = 240;
  bus->frames.push_back(fr);
  std::optional<robot::StereoFrame> f;
  ASSERT_EQ(cam.grab(0, &f), ReturnType::kOk) << cam.lastError();
  ASSERT_EQ(f->left.type(), CV_8UC3);
  const cv::Vec3b p = f->left.at<cv::Vec3b>(100, 100);
  EXPECT_EQ(p[0], 240);  // blue
  EXPECT_EQ(p[1], 0);
  EXPECT_EQ(p[2], 0);
  EXPECT_EQ(f->right.at<cv::Vec3b>(100, 100), cv::Vec3b(0, 0, 0));
}

TEST(Bumblebee2, MonoSensorsAreNotDemosaiced) {
  auto bus = std::make_unique<FakeBus>();
  bus->cameras.push_back({kGuid, 0, "Point Grey Research", "Bumblebee2 BB2-03S2M"});
  bus->registers[kPgrSensorBoardInfo] = 0xB;  // mono 640x480; no Bayer register needed
  FakeBus* b = bus.get();
  Bumblebee2Camera cam(std::move(bus), rig640(), {});
  EXPECT_FALSE(b->setup_config->raw16);
  FakeBus::Frame fr = uniformFrame(7, 9, 5);
  fr.data[1] = 250;  // left (0, 0)
  b->frames.push_back(fr);
  std::optional<robot::StereoFrame> f;
  ASSERT_EQ(cam.grab(0, &f), ReturnType::kOk);
  EXPECT_EQ(f->left.at<uint8_t>(0, 0), 250);
  EXPECT_EQ(f->left.at<uint8_t>(0, 1), 7);
  EXPECT_EQ(f->right.at<uint8_t>(0, 0), 9);
}

TEST(Bumblebee2, DeviceErrorsAreOneLineAndKError) {
  std::unique_ptr<FakeBus> owner;
  FakeBus* bus = colourBb2(&owner);
  Bumblebee2Camera cam(std::move(owner), rig640(), {});
  bus->fail_dequeue = true;
  std::optional<robot::StereoFrame> f;
  EXPECT_EQ(cam.grab(0, &f), ReturnType::kError);
  EXPECT_EQ(cam.lastError(), "bb2: frame capture failed: dc1394_capture_dequeue: Failure");
  bus->fail_dequeue = false;
  FakeBus::Frame shortFrame = uniformFrame(1, 2, 3);
  shortFrame.data.resize(1000);
  bus->frames.push_back(shortFrame);
  EXPECT_EQ(cam.grab(0, &f), ReturnType::kError);
  EXPECT_EQ(cam.lastError().rfind("bb2: frame of 1000 bytes", 0), 0u) << cam.lastError();
  EXPECT_EQ(bus->enqueued, bus->dequeued);  // the bad buffer was given back too
}

TEST(Bumblebee2, StartUpErrorsAreOneLine) {
  EXPECT_EQ(errorOf(std::make_unique<FakeBus>(), rig640()), "bb2: no IEEE-1394 camera found");
  auto other = std::make_unique<FakeBus>();
  other->cameras.push_back({0x1234, 0, "Sony", "DFW-X700"});
  EXPECT_EQ(errorOf(std::move(other), rig640()),
            "bb2: no Bumblebee2 among 1 camera(s): DFW-X700 0000000000001234");
  std::unique_ptr<FakeBus> bus;
  colourBb2(&bus);
  Bumblebee2Options o;
  o.guid = "abc";
  EXPECT_EQ(errorOf(std::move(bus), rig640(), o),
            "bb2: no camera with GUID abc among 1 camera(s): Bumblebee2 BB2-03S2C 00b09d0100a1b2c3");
  colourBb2(&bus);
  StereoRig small = rig640();
  small.left.width = 320;
  EXPECT_EQ(errorOf(std::move(bus), small),
            "bb2: Bumblebee2 BB2-03S2C 00b09d0100a1b2c3: sensor is 640x480, the rig calibration is 320x480");
  colourBb2(&bus);
  bus->registers.erase(kPgrBayerTileMapping);
  EXPECT_EQ(errorOf(std::move(bus), rig640()),
            "bb2: Bumblebee2 BB2-03S2C 00b09d0100a1b2c3: cannot read BAYER_TILE_MAPPING: no such register");
  colourBb2(&bus);
  o = {};
  o.frame_rate_hz = 0;
  EXPECT_THROW(Bumblebee2Camera(std::move(bus), rig640(), o), std::invalid_argument);
}

TEST(Bumblebee2, OptionsFromYaml) {
  const auto dir = refgrasp::testing::tempDir("refgrasp_test_dc1394");
  const std::string p = (dir / "bb2.yaml").string();
  std::ofstream(p) << "guid: 00b09d0100a1b2c3\nframe_rate_hz: 30\nshutter_s: 0.005\n";
  const Bumblebee2Options o = loadBumblebee2Options(p);
  EXPECT_EQ(o.guid, "00b09d0100a1b2c3");
  EXPECT_DOUBLE_EQ(o.frame_rate_hz, 30);
  EXPECT_DOUBLE_EQ(o.shutter_s, 0.005);
  EXPECT_LT(o.gain_db, 0);
  std::ofstream(p) << "frame_rate: 30\n";
  try {
    loadBumblebee2Options(p);
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), p + ": frame_rate: unknown field");
  }
  std::ofstream(p) << "frame_rate_hz: -3\n";
  try {
    loadBumblebee2Options(p);
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), p + ": frame_rate_hz: must be in (0, 240]");
  }
}

// The real libdc1394 device on this machine: there is no FireWire camera in CI, so this is the
// "no camera found" path of the real implementation (on a machine with a Bumblebee2 attached it
// would open it; asking for an impossible GUID keeps the test valid there too).
TEST(Bumblebee2, RealLibdc1394WithoutTheCameraIsAOneLineError) {
  Bumblebee2Options o;
  o.guid = "ffffffffffffffff";
  try {
    Bumblebee2Camera cam(makeLibDc1394Device(), rig640(), o);
    FAIL() << "opened a camera with GUID ffffffffffffffff";
  } catch (const ConfigError& err) {
    const std::string what = err.what();
    EXPECT_TRUE(what == "bb2: no IEEE-1394 camera found" ||
                what.rfind("bb2: no camera with GUID ffffffffffffffff among", 0) == 0)
        << what;
    EXPECT_EQ(what.find('\n'), std::string::npos);
  }
}
