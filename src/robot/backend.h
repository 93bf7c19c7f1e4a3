#pragma once
// Building a Robot on a backend chosen by configuration. Each backend library (src/robot/<name>/)
// registers one factory under its name; adding a backend is one new registration, never a change
// to the HAL. robot/backends.h registers every backend this build has.
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "robot/enon_model.h"
#include "robot/hal.h"

namespace refgrasp::robot {

/// Which backend, with its own settings as text (from a config file or the command line).
struct BackendConfig {
  std::string backend;                        ///< "sim" or "dds" (robot/backends.h registers them)
  std::map<std::string, std::string> params;  ///< e.g. {"scenario": "config/scenarios/x.yaml"}
  /// Where the configuration came from (file or "command line"), named in errors.
  std::string source;
};

/// Builds a Robot from the model and the backend's settings; throws ConfigError (start-up).
using BackendFactory =
    std::function<std::unique_ptr<Robot>(const EnonModel& model, const BackendConfig& config)>;

/// Registers (or replaces) the factory for `name`. Thread-safe.
void registerBackend(const std::string& name, BackendFactory factory);
/// Registered backend names, sorted.
std::vector<std::string> backendNames();

/// Builds a Robot on config.backend. Throws ConfigError naming config.source (or the model file)
/// and the field `backend` for an unknown backend (listing the known ones), and whatever the
/// backend's factory throws for its own settings.
std::unique_ptr<Robot> makeRobot(const EnonModel& model, const BackendConfig& config);

}  // namespace refgrasp::robot
