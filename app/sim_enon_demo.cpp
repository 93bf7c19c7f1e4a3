// Runs a scripted command sequence on the simulated enon in a scenario; writes a CSV log of the
// robot state every cycle and a few stereo frames as PNG.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "core/error.h"
#include "robot/hal.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"

using namespace refgrasp;
using namespace refgrasp::robot;

namespace {

// The script: look around, drive an arc towards the table, raise the arm forward, close the hand.
void command(Robot& robot, double t) {
  if (t < 2.0) {
    robot.head().setVelocity(0.6 * (t < 1.0 ? 1 : -1), 0.0);
  } else if (t < 5.0) {
    robot.head().setPosition(0.0, 0.35);
    // 2.5 s of arc: half a second more would bring the base body onto the table's corner.
    if (t < 4.5) robot.base().setVelocity(0.4, 0.15);
    else robot.base().setVelocity(0, 0);
  } else if (t < 8.0) {
    Twist v;
    v.v = Eigen::Vector3d(0.06, 0.0, 0.08);  // forward and up, in the base frame
    robot.arm().setVelocity(ArmFrame::kBase, v);
  } else if (t < 8.05) {
    robot.gripper().close();
  } else {
    // Commands are latched: stop each actuator explicitly.
    robot.base().setVelocity(0, 0);
    robot.arm().setJointVelocity(Eigen::VectorXd::Zero(robot.arm().kinematics().dof()));
  }
}

int run(const std::string& enon_path, const std::string& scenario_path, const std::string& out,
        double duration_s, int png_every) {
  const EnonModel model = loadEnonModel(enon_path);
  const sim::Scenario scenario = sim::loadScenario(scenario_path);
  std::unique_ptr<Robot> robot = sim::makeSimRobot(model, scenario);
  std::filesystem::create_directories(out);
  std::ofstream csv(out + "/state.csv");
  csv << RobotState::csvHeader(model.arm.dof()) << '\n';
  if (robot->configure() != ReturnType::kOk || robot->activate() != ReturnType::kOk) {
    std::fprintf(stderr, "sim_enon_demo: could not activate the simulated enon\n");
    return 2;
  }
  const double dt = model.control_period_s;
  const int cycles = static_cast<int>(std::ceil(std::min(duration_s, scenario.max_duration_s) / dt));
  int frames = 0, written = 0;
  for (int k = 0; k <= cycles; ++k) {
    const double t = k * dt;
    if (robot->read(t, dt) != ReturnType::kOk) {
      std::fprintf(stderr, "sim_enon_demo: read failed at t=%.3f s: %s\n", t,
                   robot->hardware().lastError().c_str());
      return 3;
    }
    csv << robot->state().csvRow() << '\n';
    std::optional<StereoFrame> frame;
    if (robot->camera().grab(t, &frame) == ReturnType::kOk && frame) {
      if (frames++ % png_every == 0) {
        char name[64];
        std::snprintf(name, sizeof(name), "/frame_%05ld_", frame->index);
        cv::imwrite(out + name + "left.png", frame->left);
        cv::imwrite(out + name + "right.png", frame->right);
        ++written;
      }
    }
    command(*robot, t);
    if (robot->write(t, dt) != ReturnType::kOk) {
      std::fprintf(stderr, "sim_enon_demo: write failed at t=%.3f s: %s\n", t,
                   robot->hardware().lastError().c_str());
      return 3;
    }
  }
  robot->deactivate();
  const RobotState& s = robot->state();
  std::printf("%d cycles, %d frames (%d written as PNG pairs) in %s\n", cycles + 1, frames, written,
              out.c_str());
  std::printf("final odometry x=%.3f y=%.3f m, gripper %s%s%s\n", s.wMb_odom.t.x(), s.wMb_odom.t.y(),
              toString(s.gripper), s.held_object.empty() ? "" : " holding ", s.held_object.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Scripted run of the simulated enon: CSV state log and stereo PNG frames."};
  std::string enon = "config/enon.yaml";
  std::string scenario = "config/scenarios/table_single.yaml";
  std::string out = "sim_enon_demo_out";
  double duration = 10.0;
  int every = 48;
  app.add_option("--enon", enon, "robot model YAML")->capture_default_str();
  app.add_option("--scenario", scenario, "scenario YAML")->capture_default_str();
  app.add_option("--out", out, "output directory")->capture_default_str();
  app.add_option("--duration", duration, "simulated seconds")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--png-every", every, "write every N-th delivered frame")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    return run(enon, scenario, out, duration, every);
  } catch (const ConfigError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
}
