#include "core/error.h"

#include <cstdio>

namespace refgrasp {

std::string oneLine(const std::string& text, size_t max_chars) {
  std::string out;
  for (const char ch : text) {
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c == '\n') {
      out += "\\n";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c == '\r') {
      out += "\\r";
    } else if (c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    } else {
      out += ch;
    }
    if (out.size() > max_chars + 8) break;  // enough to know it is too long
  }
  if (out.size() > max_chars) out = out.substr(0, max_chars - 3) + "...";
  return out;
}

ConfigError::ConfigError(std::string file, std::string field, std::string problem, bool has_field)
    : std::runtime_error(has_field ? file + ": " + field + ": " + problem : file + ": " + problem),
      file_(std::move(file)),
      field_(std::move(field)),
      problem_(std::move(problem)) {}

ConfigError::ConfigError(const std::string& file, const std::string& field,
                         const std::string& problem)
    : ConfigError(oneLine(file, 1000), oneLine(field), oneLine(problem, 2000), true) {}

ConfigError::ConfigError(const std::string& file, const std::string& problem)
    : ConfigError(oneLine(file, 1000), "", oneLine(problem, 2000), false) {}

OutputError::OutputError(const std::string& file, const std::string& problem)
    : std::runtime_error(oneLine(file, 1000) + ": " + oneLine(problem, 2000)) {}

void check(bool cond, const std::string& what, const std::string& problem) {
  if (!cond) throw std::invalid_argument(what + ": " + problem);
}

}  // namespace refgrasp
