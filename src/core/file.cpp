#include "core/file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
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

// A regular file within its size limit, open for reading; closed on destruction. Opened with
// O_NONBLOCK (a FIFO without a writer returns at once) and checked on the descriptor (a path
// swapped for a FIFO after a check cannot hang a read). Throws ConfigError("<path>: <problem>").
class CheckedFile {
 public:
  CheckedFile(const std::string& path, uint64_t max_bytes) : path_(path) {
    if (path.empty()) throw ConfigError(path, "empty file name");
    fd_ = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
    if (fd_ < 0) throw ConfigError(path, errnoProblem(errno));
    struct stat st {};
    const std::string problem = ::fstat(fd_, &st) != 0 ? errnoProblem(errno) : statProblem(st, max_bytes);
    if (!problem.empty()) {
      ::close(fd_);
      throw ConfigError(path, problem);
    }
    size_ = static_cast<uint64_t>(st.st_size);
  }
  ~CheckedFile() { ::close(fd_); }
  CheckedFile(const CheckedFile&) = delete;
  CheckedFile& operator=(const CheckedFile&) = delete;

  /// The size when opened: reads never go past it.
  uint64_t size() const { return size_; }
  /// Up to n bytes (0 at the end); throws ConfigError on a read error.
  size_t read(char* p, size_t n) {
    for (;;) {
      const ssize_t got = ::read(fd_, p, n);
      if (got >= 0) return static_cast<size_t>(got);
      if (errno != EINTR) throw ConfigError(path_, std::string("read failed: ") + std::strerror(errno));
    }
  }

 private:
  std::string path_;
  int fd_ = -1;
  uint64_t size_ = 0;
};

[[noreturn]] void lineTooLong(const std::string& path, uint64_t number, uint64_t max_line_bytes) {
  throw ConfigError(path, "line " + std::to_string(number),
                    "longer than the limit of " + std::to_string(max_line_bytes) + " bytes");
}

}  // namespace

std::string regularFileProblem(const std::string& path, uint64_t max_bytes) {
  if (path.empty()) return "empty file name";
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return errnoProblem(errno);
  return statProblem(st, max_bytes);
}

std::string readRegularFile(const std::string& path, uint64_t max_bytes) {
  CheckedFile f(path, max_bytes);
  std::string data(static_cast<size_t>(f.size()), '\0');
  size_t got = 0;
  while (got < data.size()) {
    const size_t n = f.read(&data[got], data.size() - got);
    if (n == 0) break;  // shrank while reading
    got += n;
  }
  data.resize(got);
  return data;
}

void forEachLine(const std::string& path, uint64_t max_total_bytes, uint64_t max_line_bytes,
                 const std::function<bool(const TextLine&)>& fn) {
  constexpr size_t kChunk = size_t{64} << 10;
  CheckedFile f(path, max_total_bytes);
  uint64_t left = f.size(), number = 0;
  // buf holds the bytes after the last complete line: at most max_line_bytes + kChunk.
  std::string buf;
  size_t scanned = 0;  // bytes of buf known to hold no '\n'
  while (left > 0) {
    const size_t want = static_cast<size_t>(std::min<uint64_t>(kChunk, left));
    const size_t old = buf.size();
    buf.resize(old + want);
    const size_t n = f.read(&buf[old], want);
    buf.resize(old + n);
    if (n == 0) break;  // shrank while reading
    left -= n;
    size_t start = 0;
    for (size_t nl = buf.find('\n', scanned); nl != std::string::npos; nl = buf.find('\n', start)) {
      if (nl - start > max_line_bytes) lineTooLong(path, number + 1, max_line_bytes);
      if (!fn({++number, std::string_view(buf).substr(start, nl - start), true})) return;
      start = nl + 1;
    }
    buf.erase(0, start);
    scanned = buf.size();
    if (buf.size() > max_line_bytes) lineTooLong(path, number + 1, max_line_bytes);
  }
  if (!buf.empty()) fn({++number, buf, false});
}

}  // namespace refgrasp
