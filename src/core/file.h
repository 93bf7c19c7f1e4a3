#pragma once
// Input files read safely: only regular files, of bounded size. A FIFO, a directory or a device
// given where a config or an image is expected is one clear error, never a hang. Line-oriented
// files (a recording's index.jsonl, image-folder stamps files) are read line by line in bounded
// memory: a file over its size limit is refused from its size before a byte is read, and a line
// over its length limit stops the read (at most that many bytes are buffered).
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>

namespace refgrasp {

/// Size cap of text configuration files (YAML, XML, recording.json): far above any real one.
constexpr uint64_t kMaxConfigFileBytes = uint64_t{4} << 20;

/// "" when `path` names a regular file (after symlinks) of at most max_bytes, else the problem:
/// "file not found", "is a directory, expected a file", "is a FIFO, not a regular file",
/// "is a character device, not a regular file", "is N bytes, more than the limit of M".
std::string regularFileProblem(const std::string& path, uint64_t max_bytes);

/// The whole file. Opened without blocking and checked on the open descriptor (a path swapped for
/// a FIFO after a check cannot hang the read). Throws ConfigError("<path>: <problem>").
std::string readRegularFile(const std::string& path, uint64_t max_bytes);

/// One line of a line-oriented file, without its '\n'.
struct TextLine {
  uint64_t number = 0;    ///< 1-based
  std::string_view text;  ///< valid during the callback only; may hold any byte (NUL, '\r')
  /// false for a last line without '\n' (a write cut short): the caller decides what it means.
  bool complete = true;
};

/// Calls `fn` for each line of `path` in order until it returns false or the file ends. The file
/// is opened as readRegularFile does, refused when its size (fstat on the open descriptor) exceeds
/// max_total_bytes, and read only up to that size (a file that grows meanwhile is read as it was).
/// Throws ConfigError "<path>: <problem>" for the open and size problems of readRegularFile and
/// "<path>: line N: longer than the limit of M bytes" as soon as a line exceeds max_line_bytes;
/// an exception from `fn` propagates.
void forEachLine(const std::string& path, uint64_t max_total_bytes, uint64_t max_line_bytes,
                 const std::function<bool(const TextLine&)>& fn);

}  // namespace refgrasp
