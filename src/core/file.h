#pragma once
// Input files read safely: only regular files, of bounded size. A FIFO, a directory or a device
// given where a config or an image is expected is one clear error, never a hang.
#include <cstdint>
#include <string>

namespace refgrasp {

/// Size cap of text configuration files (YAML, XML): far above any real one.
constexpr uint64_t kMaxConfigFileBytes = uint64_t{4} << 20;

/// "" when `path` names a regular file (after symlinks) of at most max_bytes, else the problem:
/// "file not found", "is a directory, expected a file", "is a FIFO, not a regular file",
/// "is a character device, not a regular file", "is N bytes, more than the limit of M".
std::string regularFileProblem(const std::string& path, uint64_t max_bytes);

/// The whole file. Opened without blocking and checked on the open descriptor (a path swapped for
/// a FIFO after a check cannot hang the read). Throws ConfigError("<path>: <problem>").
std::string readRegularFile(const std::string& path, uint64_t max_bytes);

}  // namespace refgrasp
