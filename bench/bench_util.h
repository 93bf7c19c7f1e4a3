// Shared by the timer harnesses in bench/: wall-clock timing of a callable and the median of
// samples. Header-only; the benches are plain executables (not run by ctest).
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
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

/// Median of the samples (the mean of the two middle ones for an even count); NaN when empty.
inline double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace refgrasp::bench
