#pragma once
// Shared helpers for the robot HAL tests (HAL only; the simulator's are in sim/sim_test_util.h).
#include <gtest/gtest.h>

#include "common/temp_dir.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include "robot/enon_model.h"
#include "robot/hal.h"

namespace refgrasp::testing_util {

/// config/enon.yaml, or the file named by REFGRASP_TEST_ENON (to run the suite on another model).
inline std::string enonPath() {
  if (const char* p = std::getenv("REFGRASP_TEST_ENON")) return p;
  return std::string(REFGRASP_SOURCE_DIR) + "/config/enon.yaml";
}

/// The shipped enon model (config/enon.yaml).
inline robot::EnonModel enonModel() { return robot::loadEnonModel(enonPath()); }

/// Writes `text` to a file in a per-test temporary directory and returns its path.
inline std::string writeTempFile(const std::string& name, const std::string& text) {
  const std::filesystem::path dir = refgrasp::testing::tempDir("refgrasp_test_robot");
  const std::filesystem::path p = dir / name;
  std::ofstream(p) << text;
  return p.string();
}

}  // namespace refgrasp::testing_util
