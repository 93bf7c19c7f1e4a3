#pragma once
// Shared helpers for the robot HAL / simulated enon tests.
#include <filesystem>
#include <fstream>
#include <string>

#include "robot/enon_model.h"

namespace refgrasp::testing_util {

inline std::string enonPath() {
  if (const char* p = std::getenv("REFGRASP_TEST_ENON")) return p;
  return std::string(REFGRASP_SOURCE_DIR) + "/config/enon.yaml";
}

/// The shipped enon model (config/enon.yaml).
inline robot::EnonModel enonModel() { return robot::loadEnonModel(enonPath()); }

/// Writes `text` to a file in a per-test temporary directory and returns its path.
inline std::string writeTempFile(const std::string& name, const std::string& text) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "refgrasp_test_robot";
  std::filesystem::create_directories(dir);
  const std::filesystem::path p = dir / name;
  std::ofstream(p) << text;
  return p.string();
}

}  // namespace refgrasp::testing_util
