#pragma once
// The component's counters and per-frame timings (ComponentStats), written by the receive thread
// (FrameInput: received, dropped, unpaired; DetectService: requests) and by the detector thread
// (Worker: processed, tracked, rejected, timings). One lock guards all of them, so that a snapshot
// is consistent across the three: every frame received is processed, rejected, dropped or still in
// flight. Also the steady clock that every timing and deadline of the component reads.
#include <algorithm>
#include <chrono>
#include <cstddef>
#include <deque>
#include <mutex>

#include "component/vision_component.h"

namespace refgrasp::component {

/// Seconds on the steady clock (an arbitrary origin): receive and queue times, request deadlines.
inline double steadyNow() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

struct SharedStats {
  /// The medians cover the last kTimingWindow processed frames: about a minute at 30 Hz, enough
  /// to be steady, short enough to follow a change of load.
  static constexpr size_t kTimingWindow = 2000;

  mutable std::mutex mutex;  ///< guards everything below
  ComponentStats counts;     ///< the *_median fields stay 0 here; snapshot() computes them
  /// Per processed frame (ms): the detector, the wait in the slot, the component's own work.
  std::deque<double> detect_ms, queue_ms, overhead_ms;

  /// The counts with the medians, under the lock.
  ComponentStats snapshot() const {
    std::lock_guard<std::mutex> lock(mutex);
    ComponentStats out = counts;
    out.detect_ms_median = median(detect_ms);
    out.queue_ms_median = median(queue_ms);
    out.overhead_ms_median = median(overhead_ms);
    return out;
  }

 private:
  /// The upper median (the element at size / 2 in order); 0 when empty.
  static double median(std::deque<double> values) {
    if (values.empty()) return 0;
    std::nth_element(values.begin(), values.begin() + static_cast<long>(values.size() / 2), values.end());
    return values[values.size() / 2];
  }
};

}  // namespace refgrasp::component
