#pragma once
// Runs the grasp controller in-process on the simulated enon, for the servo tests: a scenario,
// a seed, an estimator (the oracle, vision, or a test double), and checks of the safety rules on
// every iteration of the run.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "detector/object.h"
#include "grasp/room_map.h"
#include "robot/enon_model.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"
#include "servo/grasp_controller.h"
#include "servo/target_estimator.h"

namespace refgrasp::testing {

inline const std::string kSourceDir = REFGRASP_SOURCE_DIR;

/// A scenario's target: its world object and its detector definition.
struct Target {
  sim::Scenario scenario;
  int index = -1;  ///< in scenario.world.objects
  detector::ObjectModel object;
  servo::ObjectExtent extent_o;  ///< the object's extent, object frame
  const sim::SimObject& world() const { return scenario.world.objects[static_cast<size_t>(index)]; }
};

inline Target loadTarget(const std::string& scenario_path, std::optional<uint64_t> seed = {}) {
  Target t;
  t.scenario = sim::loadScenario(scenario_path);
  if (seed) t.scenario.seed = *seed;
  for (size_t i = 0; i < t.scenario.world.objects.size(); ++i)
    if (t.scenario.world.objects[i].is_target) t.index = static_cast<int>(i);
  t.object = detector::loadObjectDefinition(t.world().definition);
  t.extent_o = servo::objectExtent(t.object);
  return t;
}

inline bool isStopped(const robot::RobotCommand& c) {
  return c.base_v_mps == 0 && c.base_w_radps == 0 && c.arm_qdot_radps.isZero(0) &&
         (c.head_mode == robot::HeadMode::kPosition || (c.pan == 0 && c.tilt == 0));
}

/// True when the head is commanded to move: velocity mode with a rate, or a position target
/// away from where the head is.
inline bool headMoves(const robot::RobotCommand& c, const robot::RobotState& s) {
  if (c.head_mode == robot::HeadMode::kVelocity) return c.pan != 0 || c.tilt != 0;
  return std::abs(c.pan - s.pan_rad) > 1e-3 || std::abs(c.tilt - s.tilt_rad) > 1e-3;
}

struct GraspRun {
  servo::GraspReport report;
  double sim_time_s = 0;
  std::string error;             ///< the controller's, when a step returned kError
  std::vector<std::string> violations;  ///< safety rules broken, one line each (empty: none)
  int iterations = 0;
  int frames_observed = 0;
  /// Over the run, the smallest distance of an arm joint to its nearer limit once it has left
  /// the limit it may have started on (the arm hangs with the elbow at 0, its lower limit).
  double min_joint_margin_rad = 1e9;
  std::vector<sim::Collision> collisions;
  std::optional<sim::GraspError> final_grasp_error;  ///< ground truth at the end
  bool holding_target = false;   ///< ground truth at the end
};

/// Per step: the iteration, and the simulated enon (ground truth); return false to stop the run.
using StepHook = std::function<bool(const servo::GraspStep&, const sim::SimEnon&)>;

/// Runs the controller on `target` until it finishes or `max_time_s`, checking on every
/// iteration that an unconfirmed or lost target never moves the robot (base, arm, head).
inline GraspRun runGrasp(const Target& target, servo::TargetEstimator& estimator,
                         const servo::GraspOptions& options = {}, double max_time_s = 120,
                         bool render = true, const StepHook& hook = nullptr) {
  const robot::EnonModel model = robot::loadEnonModel(kSourceDir + "/config/enon.yaml");
  auto robot = sim::makeSimRobot(model, target.scenario);
  auto& sim = dynamic_cast<sim::SimEnon&>(robot->hardware());
  sim.setRenderImages(render);
  GraspRun run;
  if (robot->configure() != robot::ReturnType::kOk || robot->activate() != robot::ReturnType::kOk) {
    run.error = "could not activate the simulated enon";
    return run;
  }
  servo::GraspController ctl(*robot, estimator, target.world().oMg, target.extent_o,
                             grasp_app::withRoom(options, target.scenario, target.extent_o));
  const double dt = model.control_period_s;
  std::vector<bool> left_start(static_cast<size_t>(model.arm.dof()), false);
  double t = 0;
  for (; t < max_time_s && !ctl.finished(); t += dt) {
    const servo::GraspStep s = ctl.step(t, dt);
    ++run.iterations;
    if (s.status != robot::ReturnType::kOk && run.error.empty()) run.error = s.error;
    const servo::GraspIteration& it = s.it;
    if (it.frame) ++run.frames_observed;
    const bool moves = !isStopped(it.command) || headMoves(it.command, it.state);
    char where[96];
    std::snprintf(where, sizeof(where), "t=%.2f %s/%s: ", t, toString(it.phase), it.detail.c_str());
    // An unconfirmed target never moves the robot; a lost one stops it (the search, which
    // only looks, moves on to its next look).
    if (moves && (it.observed == servo::TargetStatus::kUnconfirmed ||
                  (it.observed == servo::TargetStatus::kLost && it.phase != servo::GraspPhase::kSearch)))
      run.violations.push_back(std::string(where) + "moves on a " + toString(it.observed) + " target");
    if (moves && it.target_driven && !it.confirmed)
      run.violations.push_back(std::string(where) + "target-driven motion without a confirmed target");
    const Eigen::VectorXd margins = sim.jointLimitMargins();
    for (Eigen::Index i = 0; i < margins.size(); ++i) {
      if (margins[i] > 0.01) left_start[static_cast<size_t>(i)] = true;
      if (left_start[static_cast<size_t>(i)])
        run.min_joint_margin_rad = std::min(run.min_joint_margin_rad, margins[i]);
    }
    if (hook && !hook(s, sim)) break;
  }
  run.sim_time_s = t;
  run.report = ctl.report();
  run.collisions = sim.collisions();
  run.final_grasp_error = sim.graspError(target.index);
  run.holding_target = sim.heldObject() == target.index;
  return run;
}

}  // namespace refgrasp::testing
