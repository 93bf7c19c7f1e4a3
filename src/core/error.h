#pragma once
// Start-up errors. Inside a control loop nothing throws: functions return a status instead.
#include <stdexcept>
#include <string>

namespace refgrasp {

/// A configuration or input file that cannot be used. what() is one line:
/// "<file>: <field>: <problem>" (field omitted when the whole file is at fault).
class ConfigError : public std::runtime_error {
 public:
  ConfigError(const std::string& file, const std::string& field, const std::string& problem);
  ConfigError(const std::string& file, const std::string& problem);
  const std::string& file() const { return file_; }
  const std::string& field() const { return field_; }

 private:
  std::string file_, field_;
};

/// Throws std::invalid_argument("<what>: <problem>") unless cond; used by Options::check().
void check(bool cond, const std::string& what, const std::string& problem);

}  // namespace refgrasp
