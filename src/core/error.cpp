#include "core/error.h"

namespace refgrasp {

ConfigError::ConfigError(const std::string& file, const std::string& field,
                         const std::string& problem)
    : std::runtime_error(file + ": " + field + ": " + problem), file_(file), field_(field) {}

ConfigError::ConfigError(const std::string& file, const std::string& problem)
    : std::runtime_error(file + ": " + problem), file_(file) {}

void check(bool cond, const std::string& what, const std::string& problem) {
  if (!cond) throw std::invalid_argument(what + ": " + problem);
}

}  // namespace refgrasp
