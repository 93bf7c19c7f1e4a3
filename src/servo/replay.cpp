#include "servo/replay.h"

#include <chrono>
#include <opencv2/imgproc.hpp>

namespace refgrasp::servo {

namespace {

cv::Mat toGray(const cv::Mat& image) {
  if (image.channels() == 1) return image;
  cv::Mat g;
  cv::cvtColor(image, g, image.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
  return g;
}

std::string sizeProblem(const cv::Mat& image, const Intrinsics& cam, const char* eye) {
  if (image.cols == cam.width && image.rows == cam.height) return "";
  return std::string(eye) + "image is " + std::to_string(image.cols) + "x" +
         std::to_string(image.rows) + ", the camera calibration is " + std::to_string(cam.width) +
         "x" + std::to_string(cam.height);
}

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

const char* toString(TrackMode m) {
  switch (m) {
    case TrackMode::kDetect: return "detect";
    case TrackMode::kTrack: return "track";
    case TrackMode::kLost: return "lost";
  }
  return "?";
}

std::array<Eigen::Vector2d, 4> projectPattern(const detector::ObjectModel& object, const Pose& cMo,
                                              const Intrinsics& camera) {
  std::array<Eigen::Vector2d, 4> px;
  for (size_t i = 0; i < 4; ++i) px[i] = camera.project(cMo * object.target->corners_o[i]);
  return px;
}

struct PoseReplay::Track {
  std::unique_ptr<FrameTracker> tracker;
  bool active = false;  ///< started on a detection and not lost since
};

PoseReplay::PoseReplay(const detector::Detector& detector, const ReplayOptions& options,
                       TrackerFactory trackers)
    : det_(detector), opt_(options), factory_(std::move(trackers)) {
  opt_.check();
  for (int id = 0; id < det_.objectCount(); ++id) {
    auto t = std::make_unique<Track>();
    // Only 3D objects can be tracked (the tracker needs a pose).
    if (factory_ && opt_.track && det_.object(id).has3d()) t->tracker = factory_(det_.object(id));
    tracks_.push_back(std::move(t));
  }
}

PoseReplay::~PoseReplay() = default;

bool PoseReplay::tracking() const {
  for (const auto& t : tracks_)
    if (t->tracker) return true;
  return false;
}

ReplayFrame PoseReplay::start(int64_t frame, const FrameStamp& stamp,
                              const std::vector<robot::ObjectTruth>& truth) const {
  ReplayFrame r;
  r.frame = frame;
  r.stamp = stamp;
  for (int id = 0; id < det_.objectCount(); ++id) {
    ObjectFrame o;
    o.object = id;
    o.name = det_.object(id).name;
    o.detection.object = id;
    for (const robot::ObjectTruth& t : truth)
      if (t.object == o.name) o.truth_cMo = t.cMo;
    r.objects.push_back(o);
  }
  return r;
}

void PoseReplay::fill(ObjectFrame* o, const Intrinsics& camera) const {
  if (o->detection.found)
    o->corners = o->detection.corners;
  else if (o->cMo)
    o->corners = projectPattern(det_.object(o->object), *o->cMo, camera);
}

bool PoseReplay::trackAll(ReplayFrame* r, const cv::Mat& gray, const Intrinsics& cam) {
  bool detect = false;
  for (ObjectFrame& o : r->objects) {
    Track& t = *tracks_[static_cast<size_t>(o.object)];
    if (t.active) {
      o.cMo = t.tracker->track(gray, cam);
      t.active = o.cMo.has_value();
      if (t.active) o.mode = TrackMode::kTrack;
    }
    detect = detect || !t.active;
  }
  return detect;
}

void PoseReplay::startTracker(const ObjectFrame& o, const cv::Mat& gray, const Intrinsics& cam) {
  Track& t = *tracks_[static_cast<size_t>(o.object)];
  if (!t.tracker || !o.cMo) return;
  t.tracker->start(gray, cam, *o.cMo);
  t.active = true;
}

ReplayFrame PoseReplay::failed(int64_t frame, const FrameStamp& stamp, const std::string& error) {
  ReplayFrame r = start(frame, stamp, {});
  r.ok = false;
  r.error = error;
  for (auto& t : tracks_) t->active = false;
  return r;
}

ReplayFrame PoseReplay::process(int64_t frame, const robot::MonoFrame& f, const Intrinsics& cam) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string bad = f.image.empty() ? "empty image" : sizeProblem(f.image, cam, "");
  if (!bad.empty()) return failed(frame, f.frameStamp(), bad);
  ReplayFrame r = start(frame, f.frameStamp(), f.truth);
  const cv::Mat gray = toGray(f.image);
  if (trackAll(&r, gray, cam)) {
    const detector::DetectionResult d = det_.detect(gray, cam, f.frameStamp());
    if (!d.ok) return failed(frame, f.frameStamp(), d.error);
    for (ObjectFrame& o : r.objects) {
      const std::optional<detector::Detection> hit = d.find(o.object);
      if (o.mode == TrackMode::kTrack || !hit) continue;
      o.mode = TrackMode::kDetect;
      o.detection = *hit;
      o.cMo = hit->cMo;
      startTracker(o, gray, cam);
    }
  }
  for (ObjectFrame& o : r.objects) fill(&o, cam);
  r.time_ms = msSince(t0);
  return r;
}

ReplayFrame PoseReplay::process(int64_t frame, const robot::StereoFrame& f, const StereoRig& rig) {
  const auto t0 = std::chrono::steady_clock::now();
  std::string bad = f.left.empty() || f.right.empty() ? "empty image"
                                                      : sizeProblem(f.left, rig.left, "left ");
  if (bad.empty()) bad = sizeProblem(f.right, rig.right, "right ");
  if (!bad.empty()) return failed(frame, f.frameStamp(), bad);
  ReplayFrame r = start(frame, f.frameStamp(), f.truth);
  const cv::Mat gray = toGray(f.left), gray_right = toGray(f.right);
  if (trackAll(&r, gray, rig.left)) {  // the trackers follow the left eye
    const detector::StereoDetectionResult d = det_.detectStereo(gray, gray_right, rig, f.frameStamp());
    if (!d.ok) return failed(frame, f.frameStamp(), d.error);
    for (ObjectFrame& o : r.objects) {
      if (o.mode == TrackMode::kTrack) continue;
      const detector::StereoDetection& s = d.objects[static_cast<size_t>(o.object)];
      o.eyes = detector::eyesUsedName(s.fused.eyes);
      if (s.fused.eyes == detector::EyesUsed::kNone) continue;
      o.mode = TrackMode::kDetect;
      if (s.left.found) o.detection = s.left;
      o.cMo = s.fused.lMo;
      startTracker(o, gray, rig.left);
    }
  }
  for (ObjectFrame& o : r.objects) fill(&o, rig.left);
  r.time_ms = msSince(t0);
  return r;
}

}  // namespace refgrasp::servo
