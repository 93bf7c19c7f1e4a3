#include "tool/tool.h"

#include <dds/ddsrt/log.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <iostream>
#include <mutex>
#include <optional>
#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <system_error>

#include "core/error.h"
#include "core/file.h"
#include "core/image_io.h"

namespace refgrasp::tool {

namespace {

void printError(const std::string& name, const std::string& message) {
  std::fprintf(stderr, "%s: %s\n", name.c_str(), oneLine(message, 3000).c_str());
  std::fflush(stderr);
}

// "" when everything written to stdout reached it, else why not.
std::string flushStdout() {
  errno = 0;
  std::cout.flush();  // synced with stdio: this is the fflush that fails on a full disk
  int err = errno;
  const bool cout_ok = std::cout.good();
  errno = 0;
  const bool flushed = std::fflush(stdout) == 0;
  if (!err) err = errno;
  if (flushed && cout_ok && !std::ferror(stdout)) return "";
  return err ? std::strerror(err) : "write error";
}

// Cyclone DDS's own log lines never reach stderr; its first error is kept for our one line
// (ddsError()), since the failure that follows says only that a participant was not created.
std::mutex g_dds_mutex;
std::string g_dds_error;

void keepDdsError(void*, const dds_log_data_t* d) {
  if (!d || !d->message || !(d->priority & (DDS_LC_ERROR | DDS_LC_FATAL))) return;
  const std::lock_guard<std::mutex> lock(g_dds_mutex);
  if (!g_dds_error.empty()) return;
  std::string m(d->message, d->size);
  while (!m.empty() && std::isspace(static_cast<unsigned char>(m.back()))) m.pop_back();
  g_dds_error = oneLine(m, 300);
}

void discardDdsTrace(void*, const dds_log_data_t*) {}

// The tool's name for the signal handler (which may only use async-signal-safe calls).
char g_name[64] = "tool";
std::atomic<int> g_signal{0};

extern "C" void exitNow(int sig) {
  const char* what = sig == SIGINT ? ": interrupted by SIGINT during start-up\n"
                                   : ": interrupted by SIGTERM during start-up\n";
  [[maybe_unused]] ssize_t n = ::write(STDERR_FILENO, g_name, std::strlen(g_name));
  n = ::write(STDERR_FILENO, what, std::strlen(what));
  ::_exit(128 + sig);
}

extern "C" void flagSignal(int sig) { g_signal = sig; }

void install(void (*handler)(int)) {
  struct sigaction sa {};
  sa.sa_handler = handler;
  sigemptyset(&sa.sa_mask);
  ::sigaction(SIGINT, &sa, nullptr);
  ::sigaction(SIGTERM, &sa, nullptr);
}

// A whole number as sign and magnitude: every int64_t and uint64_t value, no wider type needed.
struct Whole {
  bool negative = false;
  uint64_t magnitude = 0;
};

Whole whole(int64_t v) {
  return {v < 0, v < 0 ? uint64_t(-(v + 1)) + 1 : uint64_t(v)};
}

int compare(const Whole& a, const Whole& b) {
  if (a.magnitude == 0 && b.magnitude == 0) return 0;
  if (a.negative != b.negative) return a.negative ? -1 : 1;
  const int m = a.magnitude < b.magnitude ? -1 : a.magnitude > b.magnitude ? 1 : 0;
  return a.negative ? -m : m;
}

std::string toString(const Whole& v) {
  return (v.negative && v.magnitude ? "-" : "") + std::to_string(v.magnitude);
}

// A whole decimal number: "" and *v, or the problem. A magnitude past 64 bits is out of range.
std::string parseWhole(const std::string& text, Whole* v) {
  size_t i = 0;
  Whole w;
  if (i < text.size() && (text[i] == '+' || text[i] == '-')) w.negative = text[i++] == '-';
  if (i == text.size()) return "'" + text + "' is not a whole number";
  for (; i < text.size(); ++i) {
    if (text[i] < '0' || text[i] > '9') return "'" + text + "' is not a whole number";
    const auto digit = static_cast<uint64_t>(text[i] - '0');
    if (w.magnitude > (UINT64_MAX - digit) / 10) return text + " is out of range";
    w.magnitude = w.magnitude * 10 + digit;
  }
  *v = w;
  return "";
}

CLI::Validator wholeIn(Whole lo, Whole hi) {
  const std::string range = "[" + toString(lo) + ", " + toString(hi) + "]";
  return CLI::Validator(
      [lo, hi, range](std::string& s) -> std::string {
        Whole v;
        if (std::string p = parseWhole(s, &v); !p.empty())
          return p.find("out of range") != std::string::npos ? s + " is outside " + range : p;
        if (compare(v, lo) < 0 || compare(v, hi) > 0) return s + " is outside " + range;
        return "";
      },
      "INTEGER in " + range);
}

// The whole number `text` when it lies in [lo, hi], else std::nullopt.
std::optional<uint64_t> wholeWithin(const char* text, uint64_t lo, uint64_t hi) {
  Whole v;
  if (!parseWhole(text, &v).empty() || (v.negative && v.magnitude) || v.magnitude < lo || v.magnitude > hi)
    return std::nullopt;
  return v.magnitude;
}

// Normalised absolute path: symlinks of the existing part resolved, "." and ".." folded.
std::filesystem::path normalised(const std::string& p) {
  std::error_code ec;
  std::filesystem::path a = std::filesystem::absolute(p, ec);
  if (ec) a = p;
  std::filesystem::path c = std::filesystem::weakly_canonical(a, ec);
  return (ec ? a : c).lexically_normal();
}

bool sameFile(const std::string& a, const std::string& b) {
  if (normalised(a) == normalised(b)) return true;
  struct stat sa {}, sb {};
  return ::stat(a.c_str(), &sa) == 0 && ::stat(b.c_str(), &sb) == 0 && sa.st_dev == sb.st_dev &&
         sa.st_ino == sb.st_ino;
}

// `inner` is `outer` or lies below it (paths normalised).
bool within(const std::string& inner, const std::string& outer) {
  const std::filesystem::path i = normalised(inner), o = normalised(outer);
  auto it = i.begin();
  for (auto ot = o.begin(); ot != o.end(); ++ot, ++it) {
    if (ot->empty()) continue;  // a trailing separator
    if (it == i.end() || *it != *ot) return false;
  }
  return true;
}

std::string fileEntryProblem(const std::string& path) {
  std::string problem = regularFileProblem(path, kMaxConfigFileBytes);
  if (!problem.empty()) return problem;
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return std::string("cannot be read: ") + std::strerror(errno);
  ::close(fd);
  return "";
}

// The end of the XML fragment that starts at `from` (a '<'): after the element that closes the
// first one opened, or the end of the text (Cyclone reads a missing close as the end).
size_t xmlEnd(const std::string& s, size_t from) {
  int depth = 0;
  bool opened = false;
  size_t i = from;
  while (i < s.size()) {
    if (s[i] != '<') {
      ++i;
      continue;
    }
    if (s.compare(i, 4, "<!--") == 0) {
      const size_t e = s.find("-->", i + 4);
      i = e == std::string::npos ? s.size() : e + 3;
      continue;
    }
    const size_t close = s.find('>', i);
    if (close == std::string::npos) return s.size();
    const char c = i + 1 < s.size() ? s[i + 1] : '\0';
    if (c == '/') {
      --depth;
    } else if (c != '?' && c != '!') {
      opened = true;
      if (s[close - 1] != '/') ++depth;
    }
    i = close + 1;
    if (opened && depth <= 0) return i;
  }
  return s.size();
}

}  // namespace

int interruptedCode(int signal_number) { return 128 + signal_number; }

int run(const std::string& name, int argc, char** argv,
        const std::function<int(int, char**)>& body, const RunOptions& o) {
  // Third-party chatter never reaches stderr: refgrasp's one line says what went wrong.
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
  ::setenv("OPENCV_FFMPEG_LOGLEVEL", "-8", 0);
  dds_set_log_sink(keepDdsError, nullptr);
  dds_set_trace_sink(discardDdsTrace, nullptr);
  std::snprintf(g_name, sizeof(g_name), "%s", name.c_str());
  // A file size limit (ulimit -f) fails the write (EFBIG) instead of killing the tool.
  std::signal(SIGXFSZ, SIG_IGN);
  int code = kOk;
  try {
    code = body(argc, argv);
  } catch (const Exit& e) {
    code = e.code;
  } catch (const OutputError& e) {
    printError(name, e.what());
    code = o.output_failed;
  } catch (const ConfigError& e) {
    printError(name, e.what());
    code = o.bad_input;
  } catch (const std::invalid_argument& e) {
    printError(name, e.what());
    code = o.bad_input;
  } catch (const std::bad_alloc&) {
    printError(name, "out of memory");
    code = o.failure;
  } catch (const cv::Exception& e) {
    printError(name, "OpenCV: " + e.err + (e.func.empty() ? "" : " (in " + e.func + ")"));
    code = o.failure;
  } catch (const std::filesystem::filesystem_error& e) {
    printError(name, (e.path1().empty() ? "" : e.path1().string() + ": ") + e.code().message());
    code = o.failure;
  } catch (const std::exception& e) {
    printError(name, e.what());
    code = o.failure;
  } catch (...) {
    printError(name, "unknown exception");
    code = o.failure;
  }
  if (const std::string problem = flushStdout(); !problem.empty()) {
    printError(name, "cannot write to standard output: " + problem);
    if (code == kOk || code == kSomeInputsUnusable) code = o.output_failed;
  }
  return code;
}

void parse(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {  // --help, --help-all, --version
    app.exit(e);
    throw Exit{kOk};
  } catch (const CLI::ParseError& e) {
    std::string what = e.what();
    if (what.empty()) what = e.get_name();
    throw std::invalid_argument(what + " (see --help)");
  }
  checkImageEnvironment();
}

StopOnError::StopOnError(std::function<void()> stop)
    : stop_(std::move(stop)), uncaught_(std::uncaught_exceptions()) {}

StopOnError::~StopOnError() {
  if (std::uncaught_exceptions() <= uncaught_ || !stop_) return;
  try {
    stop_();
  } catch (...) {
  }
}

CLI::Validator Finite(double lo, double hi) {
  std::ostringstream desc;
  desc << "NUMBER in [" << lo << ", " << hi << "]";
  return CLI::Validator(
      [lo, hi](std::string& s) -> std::string {
        char* end = nullptr;
        errno = 0;
        const double v = std::strtod(s.c_str(), &end);
        if (s.empty() || end == s.c_str() || *end != '\0')
          return "'" + s + "' is not a number";
        if (!std::isfinite(v) || errno == ERANGE) return "'" + s + "' is not a finite number";
        if (v < lo || v > hi) {
          std::ostringstream m;
          m << s << " is outside [" << lo << ", " << hi << "]";
          return m.str();
        }
        return "";
      },
      desc.str());
}

CLI::Validator Integer(int64_t lo, int64_t hi) { return wholeIn(whole(lo), whole(hi)); }

CLI::Validator Unsigned(uint64_t hi) { return wholeIn(Whole{}, Whole{false, hi}); }

void Paths::input(const std::string& option, const std::string& path) {
  if (!path.empty()) inputs_.push_back({option, path, false});
}

void Paths::inputSpec(const std::string& option, const std::string& spec) {
  input(option, spec);
  const size_t colon = spec.find(':');
  if (colon == std::string::npos) return;
  std::stringstream rest(spec.substr(colon + 1));
  for (std::string item; std::getline(rest, item, ',');) input(option, item);
}

void Paths::output(const std::string& option, const std::string& path) {
  if (!path.empty()) outputs_.push_back({option, path, false});
}

void Paths::outputFolder(const std::string& option, const std::string& path) {
  if (!path.empty()) outputs_.push_back({option, path, true});
}

void Paths::check() const {
  for (size_t k = 0; k < outputs_.size(); ++k) {
    const Entry& out = outputs_[k];
    for (const Entry& in : inputs_) {
      const bool clash = out.folder ? within(in.path, out.path) || sameFile(in.path, out.path)
                                    : sameFile(in.path, out.path);
      if (!clash) continue;
      const bool same = sameFile(in.path, out.path);
      throw std::invalid_argument(out.option + " " + out.path + ": " + (same ? "is" : "holds") +
                                  " the input " + in.option + " " + in.path +
                                  " (it would be overwritten)");
    }
    for (size_t j = 0; j < k; ++j) {
      const Entry& other = outputs_[j];
      if (out.folder == other.folder && sameFile(out.path, other.path))
        throw std::invalid_argument(out.option + " " + out.path + ": is also " + other.option +
                                    " (one would overwrite the other)");
    }
  }
}

std::string cycloneUriProblem(const std::string& uri) {
  const auto separator = [](char c) { return std::isspace(static_cast<unsigned char>(c)) || c == ','; };
  size_t i = 0;
  while (i < uri.size()) {
    while (i < uri.size() && separator(uri[i])) ++i;
    if (i == uri.size()) break;
    if (uri[i] == '<') {  // inline XML, checked by Cyclone itself
      i = xmlEnd(uri, i);
      continue;
    }
    const size_t comma = uri.find(',', i);
    const std::string entry = uri.substr(i, comma == std::string::npos ? std::string::npos : comma - i);
    i = comma == std::string::npos ? uri.size() : comma + 1;
    // Cyclone opens the entry as a path, then without its "file://".
    std::string problem = fileEntryProblem(entry);
    if (!problem.empty() && entry.rfind("file://", 0) == 0) {
      const std::string path = entry.substr(7);
      problem = fileEntryProblem(path);
      if (!problem.empty()) return path + ": " + problem;
    } else if (!problem.empty()) {
      return entry + ": " + problem;
    }
  }
  return "";
}

int checkDdsEnvironment() {
  if (const char* uri = std::getenv("CYCLONEDDS_URI"); uri && *uri) {
    if (const std::string p = cycloneUriProblem(uri); !p.empty())
      throw std::invalid_argument("CYCLONEDDS_URI: " + p);
  }
  const char* d = std::getenv("ROS_DOMAIN_ID");
  if (!d || !*d) return 0;
  const std::optional<uint64_t> v = wholeWithin(d, 0, 232);
  if (!v)
    throw std::invalid_argument("ROS_DOMAIN_ID: '" + oneLine(d, 100) +
                                "' is not a domain id (an integer in [0, 232])");
  return static_cast<int>(*v);
}

void checkImageEnvironment() {
  const char* e = std::getenv("REFGRASP_MAX_IMAGE_PIXELS");
  if (!e || !*e) return;
  if (!wholeWithin(e, 1, uint64_t{1} << 62))
    throw std::invalid_argument("REFGRASP_MAX_IMAGE_PIXELS: '" + oneLine(e, 100) +
                                "' is not a pixel count (an integer in [1, 2^62])");
}

std::string ddsError() {
  const std::lock_guard<std::mutex> lock(g_dds_mutex);
  return g_dds_error;
}

std::string withDdsError(const std::string& message) {
  const std::string e = ddsError();
  return e.empty() ? message : message + " (Cyclone DDS: " + e + ")";
}

void exitOnSignal() { install(exitNow); }

void flagOnSignal() {
  g_signal = 0;
  install(flagSignal);
}

int interruptedBy() { return g_signal; }

std::string outputFileProblem(const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path parent = fs::path(path).parent_path();
  const std::string dir = parent.empty() ? "." : parent.string();
  std::error_code ec;
  const fs::file_status st = fs::status(dir, ec);
  if (!fs::exists(st)) return "folder " + dir + " does not exist";
  if (!fs::is_directory(st)) return dir + " is not a folder";
  if (::access(dir.c_str(), W_OK | X_OK) != 0) return "folder " + dir + " is not writable";
  if (fs::is_directory(path, ec)) return "is a folder";
  return "";
}

void makeOutputDir(const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw OutputError(dir, "cannot create folder: " + ec.message());
  if (!std::filesystem::is_directory(dir, ec)) throw OutputError(dir, "cannot create folder: not a directory");
}

void checkWritten(std::ostream& out, const std::string& file) {
  errno = 0;
  out.flush();
  if (out.good()) return;
  const int err = errno;
  throw OutputError(file, std::string("write failed: ") + (err ? std::strerror(err) : "I/O error"));
}

void writeImage(const std::string& path, const cv::Mat& image, const std::vector<int>& params) {
  if (const std::string p = writeImageFile(path, image, params); !p.empty())
    throw OutputError(path, "cannot write the image: " + p);
}

}  // namespace refgrasp::tool
