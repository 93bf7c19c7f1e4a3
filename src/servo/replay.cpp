#include "servo/replay.h"

namespace refgrasp::servo {

namespace {

TargetTrackerOptions pipelineOptions(const ReplayOptions& o, bool have_tracker) {
  o.check();
  TargetTrackerOptions p = o.pipeline;
  p.track = o.track && have_tracker;
  return p;
}

}  // namespace

PoseReplay::PoseReplay(const detector::Detector& detector, const ReplayOptions& options,
                       TrackerFactory trackers)
    : pipeline_(detector, pipelineOptions(options, static_cast<bool>(trackers)), trackers) {}

PoseReplay::~PoseReplay() = default;

bool PoseReplay::tracking() const { return pipeline_.tracking(); }

ReplayFrame PoseReplay::convert(int64_t frame, const TargetFrame& t,
                                const std::vector<robot::ObjectTruth>& truth, bool stereo) const {
  ReplayFrame r;
  r.frame = frame;
  r.stamp = t.stamp;
  r.ok = t.ok;
  r.error = t.error;
  r.detector_calls = t.detector_calls;
  r.time_ms = t.time_ms;
  for (const TargetState& s : t.objects) {
    ObjectFrame o;
    o.object = s.object;
    o.name = s.name;
    o.mode = s.mode;
    o.confirmed = s.confirmed;
    o.detection = s.detection;
    o.cMo = s.cMo;
    o.corners = s.corners;
    o.H = s.H;
    if (stereo && t.ok) o.eyes = detector::eyesUsedName(s.eyes);
    o.quality = s.quality;
    for (const robot::ObjectTruth& g : truth)
      if (g.object == o.name) o.truth_cMo = g.cMo;
    r.objects.push_back(o);
  }
  return r;
}

ReplayFrame PoseReplay::failed(int64_t frame, const FrameStamp& stamp, const std::string& error) {
  return convert(frame, pipeline_.failed(stamp, error), {}, false);
}

ReplayFrame PoseReplay::process(int64_t frame, const robot::MonoFrame& f, const Intrinsics& camera) {
  const TargetFrame t = pipeline_.process(f, camera);
  return convert(frame, t, t.ok ? f.truth : std::vector<robot::ObjectTruth>{}, false);
}

ReplayFrame PoseReplay::process(int64_t frame, const robot::StereoFrame& f, const StereoRig& rig) {
  const TargetFrame t = pipeline_.process(f, rig);
  return convert(frame, t, t.ok ? f.truth : std::vector<robot::ObjectTruth>{}, true);
}

}  // namespace refgrasp::servo
