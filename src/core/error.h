#pragma once
// Start-up errors. Inside a control loop nothing throws: functions return a status instead.
#include <stdexcept>
#include <string>

namespace refgrasp {

/// A configuration or input file that cannot be used. what() is one line:
/// "<file>: <field>: <problem>" (field omitted when the whole file is at fault). Control
/// characters (a newline in a hostile key) are escaped and each part is cut to oneLine()'s
/// length, so the message stays one readable line whatever the input.
class ConfigError : public std::runtime_error {
 public:
  ConfigError(const std::string& file, const std::string& field, const std::string& problem);
  ConfigError(const std::string& file, const std::string& problem);
  /// The parts as they appear in what().
  const std::string& file() const { return file_; }
  const std::string& field() const { return field_; }
  const std::string& problem() const { return problem_; }

 private:
  ConfigError(std::string file, std::string field, std::string problem, bool has_field);
  std::string file_, field_, problem_;
};

/// An output (a file, stdout) that could not be written: "<file>: <problem>", one line. Tools
/// exit with their "output failed" code (docs/errors.md), never silently losing data.
class OutputError : public std::runtime_error {
 public:
  OutputError(const std::string& file, const std::string& problem);
};

/// `text` with control characters escaped (\n, \t, \xNN) and, beyond max_chars, cut to
/// max_chars characters ending in "...". Idempotent.
std::string oneLine(const std::string& text, size_t max_chars = 300);

/// Throws std::invalid_argument("<what>: <problem>") unless cond; used by Options::check().
void check(bool cond, const std::string& what, const std::string& problem);

}  // namespace refgrasp
