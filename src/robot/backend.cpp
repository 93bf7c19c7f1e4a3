#include "robot/backend.h"

#include <mutex>

#include "core/error.h"

namespace refgrasp::robot {

namespace {
std::mutex& registryMutex() {
  static std::mutex m;
  return m;
}
std::map<std::string, BackendFactory>& registry() {
  static std::map<std::string, BackendFactory> r;
  return r;
}
}  // namespace

void registerBackend(const std::string& name, BackendFactory factory) {
  std::lock_guard<std::mutex> lock(registryMutex());
  registry()[name] = std::move(factory);
}

std::vector<std::string> backendNames() {
  std::lock_guard<std::mutex> lock(registryMutex());
  std::vector<std::string> names;
  for (const auto& [name, f] : registry()) names.push_back(name);
  return names;
}

std::unique_ptr<Robot> makeRobot(const EnonModel& model, const BackendConfig& config) {
  BackendFactory f;
  {
    std::lock_guard<std::mutex> lock(registryMutex());
    const auto it = registry().find(config.backend);
    if (it != registry().end()) f = it->second;
  }
  if (!f) {
    std::string known;
    for (const auto& n : backendNames()) known += (known.empty() ? "" : ", ") + n;
    throw ConfigError(config.source.empty() ? model.path : config.source, "backend",
                      "unknown backend '" + config.backend + "' (available: " +
                          (known.empty() ? "none registered" : known) + ")");
  }
  return f(model, config);
}

}  // namespace refgrasp::robot
