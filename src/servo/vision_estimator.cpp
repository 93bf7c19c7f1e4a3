#include "servo/vision_estimator.h"

#include <stdexcept>

namespace refgrasp::servo {

TargetTrackerOptions robotPipelineOptions() {
  TargetTrackerOptions o;
  o.redetect_every_frames = 10;
  return o;
}

VisionEstimator::VisionEstimator(const detector::Detector& detector, int object,
                                 const TargetTrackerOptions& options)
    : object_(object), tracker_(detector, options) {
  if (object < 0 || object >= detector.objectCount())
    throw std::invalid_argument("VisionEstimator: unknown object id " + std::to_string(object));
}

TargetObservation VisionEstimator::observe(const robot::StereoFrame& frame, const StereoRig& rig,
                                           const std::optional<Pose>&) {
  // The pipeline predicts from the frames' capture state itself; the controller's prior is the
  // same prediction, so it is not needed here.
  last_ = tracker_.process(frame, rig);
  TargetObservation o;
  o.status = TargetStatus::kLost;
  if (!last_.ok) {
    o.error = last_.error;
    return o;
  }
  const TargetState* s = last_.find(object_);
  if (s) {
    o.detector_stats = s->detector_stats;
    o.detector_best = s->detector_best;
  }
  if (!s || s->mode == TrackMode::kLost || !s->cMo) return o;
  o.status = s->confirmed ? TargetStatus::kConfirmed : TargetStatus::kUnconfirmed;
  o.cMo = s->cMo;
  o.corners = s->corners;
  o.source = toString(s->mode);
  return o;
}

void VisionEstimator::reset() { tracker_.reset(); }

}  // namespace refgrasp::servo
