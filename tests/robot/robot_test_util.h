#pragma once
// Shared helpers for the robot HAL / simulated enon tests.
#include <gtest/gtest.h>

#include "common/temp_dir.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <string>

#include "robot/enon_model.h"
#include "robot/hal.h"
#include "robot/sim_enon.h"

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

/// A simulated enon behind the HAL, configured and active.
struct SimRig {
  refgrasp::robot::EnonModel model;
  sim::SimEnon* sim = nullptr;
  std::unique_ptr<refgrasp::robot::Robot> robot;
  double dt;

  explicit SimRig(const sim::Scenario& sc, refgrasp::robot::EnonModel m = enonModel())
      : model(std::move(m)), dt(model.control_period_s) {
    auto hw = std::make_unique<sim::SimEnon>(model, sc);
    sim = hw.get();
    auto cam = hw->makeCamera();
    robot = std::make_unique<refgrasp::robot::Robot>(model, std::move(hw), std::move(cam));
    EXPECT_EQ(robot->configure(), refgrasp::robot::ReturnType::kOk);
    EXPECT_EQ(robot->activate(), refgrasp::robot::ReturnType::kOk);
  }
  /// Cycles k = 0..n-1 at t = t0 + k dt: read, command(t), write.
  void run(int n, const std::function<void(double)>& command, double t0 = 0) {
    for (int k = 0; k < n; ++k) {
      const double t = t0 + k * dt;
      ASSERT_EQ(robot->read(t, dt), refgrasp::robot::ReturnType::kOk);
      if (command) command(t);
      ASSERT_EQ(robot->write(t, dt), refgrasp::robot::ReturnType::kOk);
    }
  }
};

}  // namespace refgrasp::testing_util
