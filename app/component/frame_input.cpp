#include "component/frame_input.h"

#include <algorithm>
#include <cstdint>

namespace refgrasp::component {

namespace msg = dds::msg;

namespace {

int64_t stampNs(const msg::Header& header) {
  return static_cast<int64_t>(header.stamp.sec) * 1000000000LL + header.stamp.nanosec;
}
std::string frameOf(const msg::Header& header) { return header.frame_id ? header.frame_id : ""; }

/// Stereo: images kept per eye while they wait for their partner; more means the eyes' stamps
/// do not match (a few frames of one eye arriving ahead of the other must still pair).
constexpr size_t kMaxWaitingImages = 8;

}  // namespace

FrameInput::FrameInput(dds::Participant& participant, dds::WaitSet& waitset, const std::string& ns,
                       bool stereo, SharedStats& stats, RateLimitedLog& log)
    : stats_(stats), log_(log) {
  eyes_.resize(stereo ? 2 : 1);
  for (size_t index = 0; index < eyes_.size(); ++index) {
    Eye& eye = eyes_[index];
    const std::string base = stereo ? dds::joinRosName(ns, index == 0 ? "left" : "right") : ns;
    eye.image_topic = dds::joinRosName(base, "image_raw");
    eye.info_topic = dds::joinRosName(base, "camera_info");
    eye.image_reader = std::make_unique<dds::Reader<msg::Image>>(
        participant, dds::ddsTopicName(eye.image_topic), dds::QosProfile::sensorData());
    eye.info_reader = std::make_unique<dds::Reader<msg::CameraInfo>>(
        participant, dds::ddsTopicName(eye.info_topic), dds::QosProfile::sensorData());
    // WaitSet tags: images 1 and 2, camera_info 3 and 4 (the detect service has 5).
    waitset.attach(eye.image_reader->condition(), 1 + static_cast<intptr_t>(index));
    waitset.attach(eye.info_reader->condition(), 3 + static_cast<intptr_t>(index));
  }
}

void FrameInput::takeSamples() {
  for (Eye& eye : eyes_) {
    dds::Sample<msg::CameraInfo> info;
    if (eye.info_reader->takeNewest(&info) > 0)
      eye.latest_info = std::make_shared<dds::Sample<msg::CameraInfo>>(std::move(info));
  }
  if (stereo()) takeStereo();
  else takeMono();
}

void FrameInput::enqueue(FrameJob job) {
  job.queued_at = steadyNow();
  std::lock_guard<std::mutex> lock(stats_.mutex);
  job.seq = ++stats_.counts.received;
  if (slot_.put(std::move(job))) ++stats_.counts.dropped;
}

void FrameInput::takeMono() {
  std::vector<dds::Sample<msg::Image>> images = eyes_[0].image_reader->takeAll();
  if (images.empty()) return;
  {
    // Only the newest reaches the detector; the others are dropped now.
    std::lock_guard<std::mutex> lock(stats_.mutex);
    stats_.counts.received += static_cast<long>(images.size()) - 1;
    stats_.counts.dropped += static_cast<long>(images.size()) - 1;
  }
  FrameJob job;
  job.received_at = steadyNow();
  job.image[0] = std::make_shared<dds::Sample<msg::Image>>(std::move(images.back()));
  job.camera_info[0] = eyes_[0].latest_info;
  enqueue(std::move(job));
}

void FrameInput::takeStereo() {
  for (Eye& eye : eyes_)
    for (auto& image : eye.image_reader->takeAll()) {
      const int64_t stamp = stampNs(image->header);
      eye.waiting[stamp] = std::make_shared<dds::Sample<msg::Image>>(std::move(image));
    }
  enqueueNewestPair();
  evictUnpaired();
}

void FrameInput::enqueueNewestPair() {
  // The newest stamp both eyes have; everything older on either side will never pair.
  int64_t newest = INT64_MIN;
  for (const auto& [stamp, image] : eyes_[0].waiting)
    if (eyes_[1].waiting.count(stamp)) newest = std::max(newest, stamp);
  if (newest == INT64_MIN) return;
  FrameJob job;
  job.received_at = steadyNow();
  for (size_t index = 0; index < 2; ++index) {
    job.image[index] = eyes_[index].waiting[newest];
    job.camera_info[index] = eyes_[index].latest_info;
  }
  long unpaired = 0;
  for (Eye& eye : eyes_) {
    for (auto it = eye.waiting.begin(); it != eye.waiting.end() && it->first < newest;) {
      it = eye.waiting.erase(it);
      ++unpaired;
    }
    eye.waiting.erase(newest);
  }
  {
    std::lock_guard<std::mutex> lock(stats_.mutex);
    stats_.counts.unpaired += unpaired;
  }
  enqueue(std::move(job));
}

void FrameInput::evictUnpaired() {
  long evicted = 0;
  for (Eye& eye : eyes_)
    while (eye.waiting.size() > kMaxWaitingImages) {
      eye.waiting.erase(eye.waiting.begin());
      ++evicted;
    }
  if (evicted == 0) return;
  {
    std::lock_guard<std::mutex> lock(stats_.mutex);
    stats_.counts.unpaired += evicted;
  }
  log_.warn("unpaired", "vision_component: warning: " + eyes_[0].image_topic + " and " +
                            eyes_[1].image_topic + " have no images with equal stamps");
}

CheckedFrame FrameInput::checkFrame(const FrameJob& job) const {
  CheckedFrame frame;
  for (size_t eye = 0; eye < eyes_.size(); ++eye) {
    frame.problem = checkEye(job, eye, &frame);
    if (!frame.problem.empty()) break;
  }
  return frame;
}

std::string FrameInput::checkEye(const FrameJob& job, size_t index, CheckedFrame* frame) const {
  const Eye& eye = eyes_[index];
  const msg::Image& image = **job.image[index];
  dds::GrayImage& gray = frame->gray[index];
  gray = dds::toGray(image);
  if (!gray.ok()) return eye.image_topic + ": " + gray.error;
  if (!job.camera_info[index]) return "no camera_info received on " + eye.info_topic;
  const msg::CameraInfo& info = **job.camera_info[index];
  std::string error;
  const std::optional<Intrinsics> camera = dds::toIntrinsics(info, &error);
  if (!camera) return eye.info_topic + ": " + error;
  if (camera->width != gray.gray.cols || camera->height != gray.gray.rows)
    return eye.info_topic + " is " + std::to_string(camera->width) + "x" + std::to_string(camera->height) +
           " but " + eye.image_topic + " is " + std::to_string(gray.gray.cols) + "x" +
           std::to_string(gray.gray.rows);
  if (frameOf(image.header) != frameOf(info.header))
    return eye.image_topic + ": frame '" + frameOf(image.header) + "' has no camera_info (" +
           eye.info_topic + " is for frame '" + frameOf(info.header) + "')";
  frame->camera[index] = *camera;
  return "";
}

}  // namespace refgrasp::component
