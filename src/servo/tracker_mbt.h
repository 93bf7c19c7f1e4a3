#pragma once
// TrackerMethod::kMbt: ViSP's vpMbGenericTracker on a one-face model made of the pattern polygon
// (servo/tracker.h). Internal to servo: use makePlanarTracker().
#include <memory>

#include "servo/tracker.h"

namespace refgrasp::servo {

/// Throws std::invalid_argument when the model cannot be built (start-up).
std::unique_ptr<FrameTracker> makeMbtTracker(const detector::ObjectModel& object,
                                             const TrackerOptions& options);

}  // namespace refgrasp::servo
