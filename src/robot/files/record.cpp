#include "robot/files/record.h"

#include <chrono>
#include <cmath>
#include <thread>

#include "core/error.h"

namespace refgrasp::files {

using robot::ReturnType;

void RecordLimits::check() const {
  refgrasp::check(max_frames >= 0, "RecordLimits.max_frames", "must be >= 0");
  refgrasp::check(std::isfinite(max_seconds) && max_seconds >= 0, "RecordLimits.max_seconds",
                  "must be >= 0");
}

RecordResult recordFrames(robot::OpenedSource& source, RecordingWriter& writer,
                          const RecordLimits& limits, const std::atomic<bool>& stop,
                          const std::function<void(const std::string&)>& on_error,
                          const std::function<void(const RecordProgress&)>& on_progress) {
  RecordResult res;
  const auto t0 = std::chrono::steady_clock::now();
  const auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  RecordProgress progress;
  progress.total = limits.max_frames > 0 ? limits.max_frames : -1;
  if (source.frames && (progress.total < 0 || *source.frames < progress.total))
    progress.total = *source.frames;
  for (;;) {
    if (stop.load()) {
      res.stopped = true;
      break;
    }
    if ((limits.max_frames > 0 && res.frames >= limits.max_frames) ||
        (limits.max_seconds > 0 && elapsed() >= limits.max_seconds))
      break;
    const Seconds now = std::chrono::duration<double>(
                            std::chrono::steady_clock::now().time_since_epoch()).count();
    ReturnType r;
    WriteStatus st;
    bool got = false;
    std::string error;
    if (source.stereo) {
      std::optional<robot::StereoFrame> f;
      r = source.stereo->grab(now, &f);
      if (f) {
        st = writer.write(*f);
        got = true;
      }
      if (r == ReturnType::kError) error = source.stereo->lastError();
    } else {
      std::optional<robot::MonoFrame> f;
      r = source.mono->grab(now, &f);
      if (f) {
        st = writer.write(*f);
        got = true;
      }
      if (r == ReturnType::kError) error = source.mono->lastError();
    }
    if (r == ReturnType::kDeactivate && !got) break;
    if (r == ReturnType::kError) {
      on_error(error.empty() ? "frame source error" : error);
      ++res.frame_errors;
      if (source.live) {
        res.source_failed = true;
        break;
      }
      continue;
    }
    if (!got) {
      if (source.live) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      continue;
    }
    if (!st.ok && !st.fatal) {  // a refused frame (wrong size): skipped
      on_error(st.error);
      ++res.frame_errors;
      continue;
    }
    if (!st.ok) {  // an I/O failure ends the recording (valid up to the previous frame)
      res.write_error = st.error;
      break;
    }
    ++res.frames;
    progress.frames = res.frames;
    progress.elapsed_s = elapsed();
    on_progress(progress);
  }
  return res;
}

}  // namespace refgrasp::files
