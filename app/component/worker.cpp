#include "component/worker.h"

#include <algorithm>
#include <array>

#include "robot/camera.h"
#include "robot/dds/convert.h"
#include "servo/surface_model.h"

namespace refgrasp::component {

namespace msg = dds::msg;

namespace {

/// The image's capture stamp (its header, the camera's clock) and the component's frame counter.
FrameStamp frameStamp(const FrameJob& job) {
  return {dds::fromRosTime((**job.image[0]).header.stamp), job.seq};
}

}  // namespace

/// Where one object's pattern is in the image (its object_corners message).
struct PatternResult {
  bool found = false;
  bool tracked = false;  ///< from the tracker, no detection this frame
  std::array<Eigen::Vector2d, 4> corners{};  ///< TL, TR, BR, BL, image px
  std::optional<Eigen::Matrix3d> H;          ///< 2D-only: reference px -> undistorted image px
  int inliers = 0;       ///< the detection's inliers, or the tracker's features
};

/// What one frame gave.
struct Worker::FrameOutcome {
  FrameOutcome(size_t object_count, const std::vector<std::string>& two_d_errors)
      : results(object_count), inliers(object_count, 0), patterns(object_count) {
    for (size_t object = 0; object < object_count; ++object) {
      results[object].have = true;
      results[object].error = two_d_errors[object];
    }
  }
  /// The object's result: found at cMo, with `pose_inliers` behind the pose.
  void setFound(int object, const Pose& cMo, int pose_inliers) {
    results[static_cast<size_t>(object)].found = true;
    results[static_cast<size_t>(object)].cMo = cMo;
    inliers[static_cast<size_t>(object)] = pose_inliers;
  }
  std::vector<ObjectResult> results;            ///< per object: found and cMo of its first instance
  std::vector<std::pair<int, Pose>> instances;  ///< (object, cMo) of every instance found
  std::vector<int> inliers;  ///< per object: the inliers (tracked: the features) behind its pose
  std::vector<PatternResult> patterns;  ///< per object: its first instance's pattern in the image
  std::string problem;       ///< empty when the frame was usable
  bool tracked_only = false; ///< with track: the pipeline needed no detection
};

Worker::Worker(detector::Detector detector, const VisionComponentOptions& options,
               std::vector<std::string> object_names, dds::Participant& participant, const FrameInput& input,
               SharedStats& stats, RateLimitedLog& log)
    : detector_(std::move(detector)),
      lMr_(options.stereo ? options.stereo->lMr : Pose()),
      pipeline_(options.track ? std::make_unique<servo::TargetTracker>(detector_, options.tracking)
                              : nullptr),
      object_names_(std::move(object_names)),
      input_(input),
      stats_(stats),
      log_(log),
      // Reliable, keep last 10; object_info gets one sample per object per frame, so it keeps
      // at least two frames' worth.
      pose_writer_(participant, dds::ddsTopicName(dds::joinRosName(options.ns, "object_pose")),
                   dds::QosProfile::reliable(10)),
      detections_writer_(participant, dds::ddsTopicName(dds::joinRosName(options.ns, "detections")),
                         dds::QosProfile::reliable(10)),
      object_info_writer_(participant, dds::ddsTopicName(dds::joinRosName(options.ns, "object_info")),
                          dds::QosProfile::reliable(
                              std::max(10, static_cast<int>(object_names_.size()) * 2))),
      object_corners_writer_(participant, dds::ddsTopicName(dds::joinRosName(options.ns, "object_corners")),
                             dds::QosProfile::reliable(
                                 std::max(10, static_cast<int>(object_names_.size()) * 2))) {
  // What the detect service answers for an object without a pose.
  for (size_t object = 0; object < object_names_.size(); ++object)
    two_d_errors_.push_back(detector_.object(static_cast<int>(object)).hasPose()
                                ? ""
                                : object_names_[object] + " is 2D-only (no reference_pose): no pose; its corners are on " +
                                      dds::joinRosName(options.ns, "object_corners"));
}

std::vector<ObjectResult> Worker::process(const FrameJob& job, double taken_at) {
  FrameOutcome outcome(object_names_.size(), two_d_errors_);
  const CheckedFrame frame = input_.checkFrame(job);
  outcome.problem = frame.problem;
  const double detect_start = steadyNow();
  if (outcome.problem.empty()) detect(job, frame, &outcome);
  const double detect_end = steadyNow();
  if (!outcome.problem.empty()) reject(job, &outcome);
  publish((**job.image[0]).header, outcome);
  const double published_at = steadyNow();
  countFrame(job, outcome, taken_at, detect_start, detect_end, published_at);
  return std::move(outcome.results);
}

void Worker::detect(const FrameJob& job, const CheckedFrame& frame, FrameOutcome* outcome) {
  // The detector runs here (with track: inside the pipeline) and nowhere else.
  if (pipeline_) track(job, frame, outcome);
  else if (input_.stereo()) detectStereo(job, frame, outcome);
  else detectMono(job, frame, outcome);
}

void Worker::detectMono(const FrameJob& job, const CheckedFrame& frame, FrameOutcome* outcome) {
  const detector::DetectionResult result =
      detector_.detect(frame.gray[0].gray, frame.camera[0], frameStamp(job));
  if (!result.ok) outcome->problem = input_.imageTopic(0) + ": " + result.error;
  for (const detector::Detection& detection : result.detections) {
    if (!detection.found) continue;
    if (detection.instance == 0) {  // the object's result is its first instance
      PatternResult& pattern = outcome->patterns[static_cast<size_t>(detection.object)];
      pattern.found = true;
      pattern.corners = detection.corners;
      if (!detection.cMo) pattern.H = detection.H;
      pattern.inliers = detection.inliers;
    }
    if (!detection.cMo) continue;
    outcome->instances.emplace_back(detection.object, *detection.cMo);
    if (detection.instance != 0) continue;
    outcome->setFound(detection.object, *detection.cMo, detection.inliers);
  }
}

void Worker::detectStereo(const FrameJob& job, const CheckedFrame& frame, FrameOutcome* outcome) {
  const StereoRig rig{frame.camera[0], frame.camera[1], lMr_};
  const detector::StereoDetectionResult result =
      detector_.detectStereo(frame.gray[0].gray, frame.gray[1].gray, rig, frameStamp(job));
  if (!result.ok) outcome->problem = input_.imageTopic(0) + ": " + result.error;
  for (const detector::StereoDetection& detection : result.objects) {
    if (!detection.fused.lMo) continue;
    if (detection.left.found) {  // the corners are the left eye's, as the pose's frame
      PatternResult& pattern = outcome->patterns[static_cast<size_t>(detection.object)];
      pattern.found = true;
      pattern.corners = detection.left.corners;
      pattern.inliers = detection.left.inliers;
    }
    outcome->instances.emplace_back(detection.object, *detection.fused.lMo);
    outcome->setFound(detection.object, *detection.fused.lMo,
                      detection.left.inliers + detection.right.inliers);
  }
}

void Worker::track(const FrameJob& job, const CheckedFrame& frame, FrameOutcome* outcome) {
  const servo::TargetFrame tracked = trackFrame(job, frame);
  if (!tracked.ok) outcome->problem = input_.imageTopic(0) + ": " + tracked.error;
  outcome->tracked_only = tracked.ok && tracked.detector_calls == 0;
  for (const servo::TargetState& target : tracked.objects) {
    if (!target.confirmed) continue;  // an unconfirmed result is not published
    const bool detected = target.mode == servo::TrackMode::kDetect;
    const int support = detected ? target.detection.inliers : target.quality.features + target.quality_right.features;
    if (target.corners) {
      PatternResult& pattern = outcome->patterns[static_cast<size_t>(target.object)];
      pattern.found = true;
      pattern.tracked = !detected;
      pattern.corners = *target.corners;
      if (!target.cMo) pattern.H = detected ? std::optional<Eigen::Matrix3d>(target.detection.H) : target.H;
      pattern.inliers = support;
    }
    if (!target.cMo) continue;
    outcome->instances.emplace_back(target.object, *target.cMo);
    outcome->setFound(target.object, *target.cMo, support);
  }
}

servo::TargetFrame Worker::trackFrame(const FrameJob& job, const CheckedFrame& frame) {
  const FrameStamp stamp = frameStamp(job);
  if (!input_.stereo()) {
    robot::MonoFrame mono;
    mono.image = frame.gray[0].gray;
    mono.stamp = stamp.stamp;
    mono.index = stamp.index;
    return pipeline_->process(mono, frame.camera[0]);
  }
  robot::StereoFrame stereo;
  stereo.left = frame.gray[0].gray;
  stereo.right = frame.gray[1].gray;
  stereo.stamp = stamp.stamp;
  stereo.index = stamp.index;
  return pipeline_->process(stereo, StereoRig{frame.camera[0], frame.camera[1], lMr_});
}

void Worker::reject(const FrameJob& job, FrameOutcome* outcome) {
  // The trackers do not carry a pose across a frame they did not see.
  if (pipeline_) pipeline_->failed(frameStamp(job), outcome->problem);
  outcome->instances.clear();
  for (ObjectResult& result : outcome->results) {
    result.found = false;
    result.error = outcome->problem;
  }
  for (PatternResult& pattern : outcome->patterns) pattern = PatternResult();
  // One warning per kind of problem: the same message up to its numbers.
  std::string kind = outcome->problem;
  for (char& ch : kind)
    if (ch >= '0' && ch <= '9') ch = '#';
  log_.warn(kind, "vision_component: warning: " + outcome->problem + " (found = false)");
}

void Worker::publish(const msg::Header& image_header, const FrameOutcome& outcome) {
  const msg::Header header = image_header;  // the image's stamp and optical frame (borrowed)
  if (outcome.results[0].found) {
    msg::PoseStamped pose{};
    pose.header = header;
    pose.pose = dds::toRosPose(outcome.results[0].cMo);
    pose_writer_.write(pose);
  }
  publishDetections(header, outcome);
  publishObjectInfo(header, outcome);
  publishObjectCorners(header, outcome);
}

void Worker::publishDetections(const msg::Header& header, const FrameOutcome& outcome) {
  const size_t count = outcome.instances.size();
  std::vector<msg::ObjectHypothesisWithPose> hypotheses(count);
  std::vector<msg::Detection3D> detections(count);
  std::vector<std::string> ids(count);  // "<object>#<instance>"; the messages borrow them
  std::vector<int> instances_so_far(object_names_.size(), 0);
  for (size_t k = 0; k < count; ++k) {
    const auto& [object_id, cMo] = outcome.instances[k];
    const size_t object = static_cast<size_t>(object_id);
    hypotheses[k].hypothesis.class_id = const_cast<char*>(object_names_[object].c_str());
    hypotheses[k].hypothesis.score = 1.0;  // a sanity-checked detection; inliers are in object_info
    hypotheses[k].pose.pose = dds::toRosPose(cMo);
    detections[k].header = header;
    detections[k].results = {1, 1, &hypotheses[k], false};
    // The box around the pattern (several views: the view seen most squarely): its centre and
    // extent on the object plane.
    std::array<Eigen::Vector3d, 4> corners;
    corners.fill(Eigen::Vector3d::Zero());
    if (const auto q = servo::facingQuad(servo::patternQuads(detector_.object(object_id)), cMo)) corners = *q;
    const Eigen::Vector3d centre = (corners[0] + corners[1] + corners[2] + corners[3]) / 4.0;
    detections[k].bbox.center = dds::toRosPose(cMo * Pose(Eigen::Matrix3d::Identity(), centre));
    detections[k].bbox.size = {(corners[1] - corners[0]).norm(), (corners[3] - corners[0]).norm(), 0.0};
    ids[k] = object_names_[object] + "#" + std::to_string(instances_so_far[object]++);
    detections[k].id = const_cast<char*>(ids[k].c_str());
  }
  msg::Detection3DArray array{};
  array.header = header;
  array.detections = {static_cast<uint32_t>(count), static_cast<uint32_t>(count), detections.data(), false};
  detections_writer_.write(array);
}

void Worker::publishObjectInfo(const msg::Header& header, const FrameOutcome& outcome) {
  for (size_t object = 0; object < object_names_.size(); ++object) {
    const ObjectResult& result = outcome.results[object];
    msg::ObjectInfo info{};
    info.header = header;
    info.object_name = const_cast<char*>(object_names_[object].c_str());
    info.found = result.found;
    for (int k = 0; k < 9; ++k) info.rotation[k] = result.found ? result.cMo.R(k / 3, k % 3) : 0.0;
    for (int k = 0; k < 3; ++k) info.translation[k] = result.found ? result.cMo.t[k] : 0.0;
    info.inliers = result.found ? outcome.inliers[object] : 0;
    object_info_writer_.write(info);
  }
}

void Worker::publishObjectCorners(const msg::Header& header, const FrameOutcome& outcome) {
  for (size_t object = 0; object < object_names_.size(); ++object) {
    const PatternResult& pattern = outcome.patterns[object];
    msg::ObjectCorners corners{};
    corners.header = header;
    corners.object_name = const_cast<char*>(object_names_[object].c_str());
    corners.found = pattern.found;
    corners.tracked = pattern.tracked;
    for (int k = 0; k < 8; ++k) corners.corners[k] = pattern.found ? pattern.corners[k / 2][k % 2] : 0.0;
    for (int k = 0; k < 9; ++k) corners.homography[k] = pattern.found && pattern.H ? (*pattern.H)(k / 3, k % 3) : 0.0;
    corners.inliers = pattern.found ? pattern.inliers : 0;
    object_corners_writer_.write(corners);
  }
}

void Worker::countFrame(const FrameJob& job, const FrameOutcome& outcome, double taken_at,
                        double detect_start, double detect_end, double published_at) {
  std::lock_guard<std::mutex> lock(stats_.mutex);
  ComponentStats& counts = stats_.counts;
  if (!outcome.problem.empty()) {
    ++counts.rejected;
    return;
  }
  ++counts.processed;
  counts.tracked += outcome.tracked_only;
  const double detect_s = detect_end - detect_start;
  const double queue_s = taken_at - job.queued_at;
  stats_.detect_ms.push_back(detect_s * 1e3);
  stats_.queue_ms.push_back(queue_s * 1e3);
  stats_.overhead_ms.push_back(((published_at - job.received_at) - detect_s - queue_s) * 1e3);
  for (auto* timings : {&stats_.detect_ms, &stats_.queue_ms, &stats_.overhead_ms})
    if (timings->size() > SharedStats::kTimingWindow) timings->pop_front();
  counts.last_detect_ms = stats_.detect_ms.back();
  counts.last_queue_ms = stats_.queue_ms.back();
  counts.last_overhead_ms = stats_.overhead_ms.back();
}

}  // namespace refgrasp::component
