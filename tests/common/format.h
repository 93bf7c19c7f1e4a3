#pragma once
// printf-style formatting into a std::string, for assertion messages and SCOPED_TRACE: a case's
// figures are shown when one of its assertions fails instead of being printed on every run.
#include <cstdarg>
#include <cstdio>
#include <string>

namespace refgrasp::testing {

[[gnu::format(printf, 1, 2)]] inline std::string formatted(const char* fmt, ...) {
  va_list a, b;
  va_start(a, fmt);
  va_copy(b, a);
  const int n = std::vsnprintf(nullptr, 0, fmt, a);
  va_end(a);
  std::string s(n > 0 ? static_cast<size_t>(n) : 0, '\0');
  if (n > 0) std::vsnprintf(s.data(), s.size() + 1, fmt, b);
  va_end(b);
  return s;
}

}  // namespace refgrasp::testing
