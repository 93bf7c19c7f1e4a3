#pragma once
// Copying a frame source into a recording: the behaviour of the `record` tool, in-process.
#include <atomic>
#include <functional>
#include <string>

#include "robot/files/recording.h"
#include "robot/sources.h"

namespace refgrasp::files {

struct RecordLimits {
  int64_t max_frames = 0;   ///< stop after this many frames (0 = no limit)
  double max_seconds = 0;   ///< stop after this much wall-clock time (0 = no limit)
  void check() const;
};

struct RecordProgress {
  int64_t frames = 0;       ///< written so far
  double elapsed_s = 0;     ///< wall clock since the start
  int64_t total = -1;       ///< frames expected (offline source with a known count, or the limit); -1 unknown
};

struct RecordResult {
  int64_t frames = 0;       ///< written
  int frame_errors = 0;     ///< frames the source could not deliver (skipped, reported)
  bool source_failed = false;  ///< a live source failed: the recording ends there
  std::string write_error;  ///< non-empty when a write failed (disk full, ...): the recording ends there
  bool stopped = false;     ///< `stop` was raised
};

/// Grabs frames from source.mono or source.stereo (whichever is set) and writes them until the
/// source ends, a limit is reached, `stop` is raised, a write fails, or a live source fails.
/// An offline source's bad frame (undecodable, wrong size) is reported through on_error and
/// skipped. Live sources are polled (1 ms sleeps between empty grabs) with the steady clock as
/// `time`. on_progress is called after every frame. Never throws.
RecordResult recordFrames(robot::OpenedSource& source, RecordingWriter& writer,
                          const RecordLimits& limits, const std::atomic<bool>& stop,
                          const std::function<void(const std::string&)>& on_error,
                          const std::function<void(const RecordProgress&)>& on_progress);

}  // namespace refgrasp::files
