#include "tool/tool.h"

#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <iostream>
#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <system_error>

#include "core/error.h"

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

}  // namespace

int run(const std::string& name, int argc, char** argv,
        const std::function<int(int, char**)>& body, const RunOptions& o) {
  // Third-party chatter never reaches stderr: refgrasp's one line says what went wrong.
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
  ::setenv("OPENCV_FFMPEG_LOGLEVEL", "-8", 0);
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

void writeImage(const std::string& path, const cv::Mat& image) {
  bool ok = false;
  try {
    ok = cv::imwrite(path, image);
  } catch (const cv::Exception& e) {
    throw OutputError(path, "cannot write the image: " + e.err);
  }
  if (!ok) throw OutputError(path, "cannot write the image");
}

}  // namespace refgrasp::tool
