// Shared by the timer harnesses in bench/: wall-clock timing of a callable and the median of
// samples. Header-only; the benches are plain executables (not run by ctest).
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <exception>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <string>
#include <vector>

namespace refgrasp::bench {

using Clock = std::chrono::steady_clock;

/// Wall-clock time of one call of f, milliseconds.
template <class F>
double timeMs(F&& f) {
  const auto t0 = Clock::now();
  f();
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

/// CPU time of the calling thread during one call of f, milliseconds: what the call costs a core,
/// nearly independent of how many other jobs share the machine (unlike timeMs). Only for f that
/// run on the calling thread.
template <class F>
double threadCpuMs(F&& f) {
  timespec a{}, b{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &a);
  f();
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &b);
  return 1e3 * static_cast<double>(b.tv_sec - a.tv_sec) + 1e-6 * static_cast<double>(b.tv_nsec - a.tv_nsec);
}

/// CPU time of the whole process (every thread) during one call of f, milliseconds: for calls
/// that use a thread pool, what they cost the machine's cores in all.
template <class F>
double processCpuMs(F&& f) {
  timespec a{}, b{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &a);
  f();
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &b);
  return 1e3 * static_cast<double>(b.tv_sec - a.tv_sec) + 1e-6 * static_cast<double>(b.tv_nsec - a.tv_nsec);
}

/// The value of a numeric option, at least min_value: on anything else (not a number, trailing
/// characters, out of range) one line "<tool>: <option>: ..." on stderr and exit 2.
inline double numberArg(const char* tool, const char* option, const char* text, double min_value) {
  char* end = nullptr;
  const double v = std::strtod(text, &end);
  if (end == text || *end != '\0' || !std::isfinite(v) || v < min_value) {
    std::fprintf(stderr, "%s: %s: expected a number >= %g, got '%s'\n", tool, option, min_value, text);
    std::exit(2);
  }
  return v;
}

/// An integer option, at least min_value; the same one-line error and exit 2 otherwise.
inline long long intArg(const char* tool, const char* option, const char* text, long long min_value) {
  char* end = nullptr;
  const double v = std::strtod(text, &end);
  if (end == text || *end != '\0' || !std::isfinite(v) || v != std::floor(v) || v < static_cast<double>(min_value) ||
      v > 9e15) {
    std::fprintf(stderr, "%s: %s: expected an integer >= %lld, got '%s'\n", tool, option, min_value, text);
    std::exit(2);
  }
  return static_cast<long long>(v);
}

/// An argument no option of the tool took: one line on stderr and exit 2. An option that takes
/// a value (listed in value_options) given last, without it: "<tool>: <option>: missing value";
/// anything else: "<tool>: unknown argument '<arg>'".
[[noreturn]] inline void rejectArgument(const char* tool, const std::string& arg,
                                        std::initializer_list<const char*> value_options) {
  for (const char* o : value_options)
    if (arg == o) {
      std::fprintf(stderr, "%s: %s: missing value (see --help)\n", tool, o);
      std::exit(2);
    }
  std::fprintf(stderr, "%s: unknown argument '%s' (see --help)\n", tool, arg.c_str());
  std::exit(2);
}

/// Opens an output file before the long run that fills it, so that a path that cannot be written
/// fails at once (one line "<tool>: <path>: cannot write (does the folder exist?)", exit 2)
/// instead of after the run, with its rows lost.
inline void openOutput(const char* tool, const std::string& path, std::ofstream& out) {
  out.open(path);
  if (!out) {
    std::fprintf(stderr, "%s: %s: cannot write (does the folder exist?)\n", tool, path.c_str());
    std::exit(2);
  }
}

/// An existing folder for an option that writes into one; otherwise one line
/// "<tool>: <option>: <path>: not a folder" and exit 2.
inline void requireFolder(const char* tool, const char* option, const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_directory(path, ec)) {
    std::fprintf(stderr, "%s: %s: %s: not a folder\n", tool, option, path.c_str());
    std::exit(2);
  }
}

/// Median of the samples (the mean of the two middle ones for an even count); NaN when empty.
inline double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace refgrasp::bench
