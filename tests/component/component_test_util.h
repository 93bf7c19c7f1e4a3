#pragma once
// Helpers for the vision component tests: rendered frames with ground truth, a camera publisher
// and a result listener on the component's topics (a private domain and namespace per process).
#include <array>
#include <chrono>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <string>
#include <thread>

#include "detector/detector.h"
#include "robot/dds/convert.h"
#include "robot/dds/service.h"
#include "robot/dds/transport.h"
#include "robot/sim/synthetic_scene.h"

namespace refgrasp::testing {

constexpr double kTargetWidth = 0.20;  // metres

inline detector::ObjectModel target(const std::string& name, const std::string& texture) {
  return detector::textureObject(name, loadMedia(texture), kTargetWidth);
}

struct Frame {
  cv::Mat image;
  Pose cMo;  // ground truth
};

/// The target at a random pose 0.35-0.9 m away, tilted up to 35 degrees, on clutter.
inline Frame renderFrame(const std::string& texture, uint64_t seed) {
  const cv::Mat tex = loadMedia(texture);
  const double h = kTargetWidth * tex.rows / tex.cols;
  std::mt19937_64 rng(seed);
  SceneSpec spec;
  spec.cMo = randomVisiblePose(rng, sceneCamera(), kTargetWidth, h, 0.35, 0.9, 35 * M_PI / 180);
  spec.seed = seed;
  const RenderedScene s = renderTarget(sceneCamera(), tex, kTargetWidth, h, spec);
  return {s.image, s.cMo};
}

/// Publishes image_raw + camera_info as a camera driver does (best effort images).
class CameraPublisher {
 public:
  CameraPublisher(const dds::Participant& pp, const std::string& ns)
      : image_(pp, dds::ddsTopicName(ns + "/image_raw"), dds::QosProfile::sensorData()),
        info_(pp, dds::ddsTopicName(ns + "/camera_info"), dds::QosProfile::reliable(1)) {}
  bool waitForComponent(double timeout_s) const {
    return image_.waitForMatch(1, timeout_s) && info_.waitForMatch(1, timeout_s);
  }
  void publishInfo(const Intrinsics& cam, Seconds stamp, const std::string& frame = "camera") {
    dds::CameraInfoOut ci(cam, stamp, frame);
    info_.write(ci.msg());
  }
  void publishImage(const cv::Mat& image, Seconds stamp, const std::string& frame = "camera") {
    dds::ImageOut img(image, stamp, frame);
    image_.write(img.msg());
  }
  void publish(const cv::Mat& image, Seconds stamp, const std::string& frame = "camera") {
    publishInfo(sceneCamera(), stamp, frame);
    publishImage(image, stamp, frame);
  }
  const dds::Writer<dds::msg::Image>& imageWriter() const { return image_; }

 private:
  dds::Writer<dds::msg::Image> image_;
  dds::Writer<dds::msg::CameraInfo> info_;
};

/// Everything the component published on one of its per-object topics (object_info,
/// object_corners), by image stamp (ns) and object name, as `decode` reads each sample.
template <class Msg, class Value>
class StampedListener {
 public:
  StampedListener(const dds::Participant& pp, const std::string& topic, std::function<Value(const Msg&)> decode)
      : reader_(pp, dds::ddsTopicName(topic), dds::QosProfile::reliable(100)), decode_(std::move(decode)) {}
  static int64_t key(Seconds stamp) {
    const dds::msg::Time t = dds::toRosTime(stamp);
    return static_cast<int64_t>(t.sec) * 1000000000LL + t.nanosec;
  }
  /// Waits for the sample of `object` for the image stamped `stamp`.
  std::optional<Value> waitFor(Seconds stamp, const std::string& object, double timeout_s) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    for (;;) {
      poll();
      const auto it = seen_.find({key(stamp), object});
      if (it != seen_.end()) return it->second;
      if (std::chrono::steady_clock::now() > end) return std::nullopt;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  }
  void poll() {
    for (auto& s : reader_.takeAll()) {
      const int64_t t = static_cast<int64_t>(s->header.stamp.sec) * 1000000000LL + s->header.stamp.nanosec;
      seen_[{t, s->object_name}] = decode_(*s);
      last_stamp_ = std::max(last_stamp_, t);
    }
  }
  size_t count() {
    poll();
    return seen_.size();
  }
  int64_t lastStamp() {
    poll();
    return last_stamp_;
  }

 private:
  dds::Reader<Msg> reader_;
  std::function<Value(const Msg&)> decode_;
  std::map<std::pair<int64_t, std::string>, Value> seen_;
  int64_t last_stamp_ = INT64_MIN;
};

/// What object_info said of one object in one frame.
struct ObjectInfoValue {
  bool found = false;
  Pose cMo;
  int inliers = 0;
  std::string frame;
};

/// Everything the component published on object_info.
class InfoListener : public StampedListener<dds::msg::ObjectInfo, ObjectInfoValue> {
 public:
  using Info = ObjectInfoValue;
  InfoListener(const dds::Participant& pp, const std::string& ns)
      : StampedListener(pp, ns + "/object_info", [](const dds::msg::ObjectInfo& s) {
          Info i;
          i.found = s.found;
          for (int k = 0; k < 9; ++k) i.cMo.R(k / 3, k % 3) = s.rotation[k];
          for (int k = 0; k < 3; ++k) i.cMo.t[k] = s.translation[k];
          i.inliers = s.inliers;
          i.frame = s.header.frame_id ? s.header.frame_id : "";
          return i;
        }) {}
};

/// What object_corners said of one object in one frame.
struct ObjectCornersValue {
  bool found = false, tracked = false;
  std::array<Eigen::Vector2d, 4> corners{};  ///< TL, TR, BR, BL, image px
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  int inliers = 0;
};

/// Everything the component published on object_corners.
class CornersListener : public StampedListener<dds::msg::ObjectCorners, ObjectCornersValue> {
 public:
  CornersListener(const dds::Participant& pp, const std::string& ns)
      : StampedListener(pp, ns + "/object_corners", [](const dds::msg::ObjectCorners& s) {
          ObjectCornersValue v;
          v.found = s.found;
          v.tracked = s.tracked;
          for (int k = 0; k < 8; ++k) v.corners[k / 2][k % 2] = s.corners[k];
          for (int k = 0; k < 9; ++k) v.H(k / 3, k % 3) = s.homography[k];
          v.inliers = s.inliers;
          return v;
        }) {}
};

/// Publishes the frame until the component answered for its stamp (best effort: the first frames
/// may go before the component has matched the publisher).
inline std::optional<InfoListener::Info> publishUntilAnswered(CameraPublisher& cam, InfoListener& infos,
                                                              const cv::Mat& image, Seconds stamp,
                                                              const std::string& object,
                                                              const std::string& frame = "camera") {
  std::optional<InfoListener::Info> r;
  for (int attempt = 0; attempt < 20 && !r; ++attempt) {
    cam.publish(image, stamp, frame);
    r = infos.waitFor(stamp, object, 3);
  }
  return r;
}

using DetectClient = dds::ServiceClient<dds::msg::DetectRequest, dds::msg::DetectResponse>;

/// A detect call; empty when no reply came within wait_s.
inline std::optional<dds::Sample<dds::msg::DetectResponse>> callDetect(DetectClient& c,
                                                                        const std::string& object,
                                                                        double timeout_s, double wait_s) {
  dds::msg::DetectRequest r{};
  r.object_name = const_cast<char*>(object.c_str());
  r.timeout_s = timeout_s;
  return c.call(r, wait_s);
}

}  // namespace refgrasp::testing
