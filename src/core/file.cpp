#include "core/file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "core/error.h"

namespace refgrasp {
namespace {

// "" for a regular file within the limit, else the problem.
std::string statProblem(const struct stat& st, uint64_t max_bytes) {
  if (S_ISREG(st.st_mode)) {
    if (static_cast<uint64_t>(st.st_size) > max_bytes)
      return "is " + std::to_string(st.st_size) + " bytes, more than the limit of " +
             std::to_string(max_bytes);
    return "";
  }
  if (S_ISDIR(st.st_mode)) return "is a directory, expected a file";
  if (S_ISFIFO(st.st_mode)) return "is a FIFO, not a regular file";
  if (S_ISCHR(st.st_mode)) return "is a character device, not a regular file";
  if (S_ISBLK(st.st_mode)) return "is a block device, not a regular file";
  if (S_ISSOCK(st.st_mode)) return "is a socket, not a regular file";
  return "is not a regular file";
}

std::string errnoProblem(int err) {
  if (err == ENOENT || err == ENOTDIR) return "file not found";
  return std::string("cannot open: ") + std::strerror(err);
}

}  // namespace

std::string regularFileProblem(const std::string& path, uint64_t max_bytes) {
  if (path.empty()) return "empty file name";
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return errnoProblem(errno);
  return statProblem(st, max_bytes);
}

std::string readRegularFile(const std::string& path, uint64_t max_bytes) {
  if (path.empty()) throw ConfigError(path, "empty file name");
  // O_NONBLOCK: opening a FIFO without a writer returns at once; fstat then refuses it.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
  if (fd < 0) throw ConfigError(path, errnoProblem(errno));
  struct stat st {};
  std::string problem = ::fstat(fd, &st) != 0 ? errnoProblem(errno) : statProblem(st, max_bytes);
  std::string data;
  if (problem.empty()) {
    data.resize(static_cast<size_t>(st.st_size));
    size_t got = 0;
    while (got < data.size()) {
      const ssize_t n = ::read(fd, &data[got], data.size() - got);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) {
        problem = std::string("read failed: ") + std::strerror(errno);
        break;
      }
      if (n == 0) break;  // shrank while reading
      got += static_cast<size_t>(n);
    }
    data.resize(got);
  }
  ::close(fd);
  if (!problem.empty()) throw ConfigError(path, problem);
  return data;
}

}  // namespace refgrasp
