#pragma once
// The component's input. Reads the camera topics (mono: <ns>/image_raw and <ns>/camera_info;
// stereo: the same under <ns>/left and <ns>/right), keeps each eye's newest camera_info, pairs
// stereo images by equal stamps, and hands the newest frame to the detector through a one-frame
// slot: a frame that arrives before the detector took the previous one replaces it (a drop).
// It also checks a frame for the detector: encoding and sizes, camera_info present, of the
// image's size and optical frame.
//
// Threads: takeSamples() runs on the receive thread (the facade's WaitSet loop); takeFrame()
// and checkFrame() on the detector thread; close() on the thread that stops the component.
// checkFrame() reads only the topic names, which never change after construction.
// Owns: the image and camera_info readers (attached to the facade's WaitSet), each eye's newest
// camera_info, the stereo images waiting for their partner, the slot. Counts received, dropped
// and unpaired frames in the shared statistics; warns through the shared log.
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "component/latest_slot.h"
#include "component/rate_limited_log.h"
#include "component/shared_stats.h"
#include "core/camera.h"
#include "robot/dds/convert.h"
#include "robot/dds/transport.h"

namespace refgrasp::component {

using ImageSample = std::shared_ptr<dds::Sample<dds::msg::Image>>;
using CameraInfoSample = std::shared_ptr<dds::Sample<dds::msg::CameraInfo>>;

/// A frame for the detector. It holds the DDS samples, so the pixels stay valid while it lives
/// (mono8 images are used in place, not copied).
struct FrameJob {
  long seq = 0;             ///< its number among the frames received (dropped ones included), from 1
  ImageSample image[2];     ///< mono or left, then right (stereo)
  /// Each eye's newest camera_info when the frame was formed; null when none had come.
  CameraInfoSample camera_info[2];
  double received_at = 0;   ///< steady clock (s): taken from DDS
  double queued_at = 0;     ///< steady clock (s): put into the slot
};

/// A frame checked for the detector: per eye the 8-bit gray image and the intrinsics, or the
/// problem that makes the frame unusable.
struct CheckedFrame {
  dds::GrayImage gray[2];
  Intrinsics camera[2];
  std::string problem;  ///< empty when usable, else one line naming the topic
};

class FrameInput {
 public:
  /// Creates the readers of the topics under `ns` and attaches them to `waitset`. Throws
  /// dds::DdsError.
  FrameInput(dds::Participant& participant, dds::WaitSet& waitset, const std::string& ns, bool stereo,
             SharedStats& stats, RateLimitedLog& log);

  /// Takes what the readers hold: the newest camera_info of each eye, then the images; puts the
  /// newest frame (stereo: the newest pair) into the slot. Receive thread.
  void takeSamples();
  /// Waits up to timeout_s for the newest frame; empty on timeout or after close(). Detector thread.
  std::optional<FrameJob> takeFrame(double timeout_s) { return slot_.take(timeout_s); }
  /// Wakes takeFrame() for good.
  void close() { slot_.close(); }

  /// Converts each eye's image to gray and its camera_info to intrinsics, checking them.
  CheckedFrame checkFrame(const FrameJob& job) const;

  bool stereo() const { return eyes_.size() == 2; }
  /// The ROS name of an eye's image topic (0: mono or left, 1: right).
  const std::string& imageTopic(size_t eye) const { return eyes_[eye].image_topic; }

 private:
  /// One camera: its topics, readers and newest camera_info.
  struct Eye {
    std::string image_topic, info_topic;  ///< ROS names
    std::unique_ptr<dds::Reader<dds::msg::Image>> image_reader;
    std::unique_ptr<dds::Reader<dds::msg::CameraInfo>> info_reader;
    CameraInfoSample latest_info;
    std::map<int64_t, ImageSample> waiting;  ///< stereo: images by stamp (ns) until their partner comes
  };

  void takeMono();
  void takeStereo();
  /// Stereo: the newest pair of equal stamps into the slot; older images can never pair and are
  /// discarded (counted unpaired).
  void enqueueNewestPair();
  /// Stereo: bounds each eye's waiting images (counted unpaired, with a warning).
  void evictUnpaired();
  /// Numbers the frame and puts it into the slot (counting a drop when it replaced one).
  void enqueue(FrameJob job);
  /// The problem with eye `index` of the frame (empty when none); fills that eye of `frame`.
  std::string checkEye(const FrameJob& job, size_t index, CheckedFrame* frame) const;

  SharedStats& stats_;
  RateLimitedLog& log_;
  std::vector<Eye> eyes_;
  LatestSlot<FrameJob> slot_;
};

}  // namespace refgrasp::component
