#pragma once
// Shared helpers for the simulated enon tests.
#include <functional>
#include <memory>

#include "robot/sim/sim_enon.h"
#include "robot_test_util.h"

namespace refgrasp::testing_util {

/// A simulated enon behind the HAL, configured and active.
struct SimRig {
  refgrasp::robot::EnonModel model;
  sim::SimEnon* sim = nullptr;
  std::unique_ptr<refgrasp::robot::Robot> robot;
  double dt;

  explicit SimRig(const sim::Scenario& sc, refgrasp::robot::EnonModel m = enonModel())
      : model(std::move(m)), dt(model.control_period_s) {
    robot = sim::makeSimRobot(model, sc);
    sim = &dynamic_cast<sim::SimEnon&>(robot->hardware());
    EXPECT_EQ(robot->configure(), refgrasp::robot::ReturnType::kOk);
    EXPECT_EQ(robot->activate(), refgrasp::robot::ReturnType::kOk);
  }
  /// Cycles k = 0..n-1 at t = t0 + k dt: read, command(t), write.
  void run(int n, const std::function<void(double)>& command, double t0 = 0) {
    for (int k = 0; k < n; ++k) {
      const double t = t0 + k * dt;
      ASSERT_EQ(robot->read(t, dt), refgrasp::robot::ReturnType::kOk) << sim->lastError();
      if (command) command(t);
      ASSERT_EQ(robot->write(t, dt), refgrasp::robot::ReturnType::kOk) << sim->lastError();
    }
  }
};

}  // namespace refgrasp::testing_util
