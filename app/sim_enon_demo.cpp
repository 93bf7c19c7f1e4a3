// Runs a scripted command sequence on the simulated enon in a scenario; writes a CSV log of the
// robot state every cycle and a few stereo frames as PNG.
// Exit status: 0 done; 2 bad options or files; 3 an output could not be written; 4 the robot
// failed (it is stopped first).
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "core/error.h"
#include "robot/hal.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"
#include "tool/tool.h"

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

constexpr int kRobotFailed = 4;

int run(const std::string& enon_path, const std::string& scenario_path, const std::string& out,
        double duration_s, int64_t png_every) {
  const EnonModel model = loadEnonModel(enon_path);
  const sim::Scenario scenario = sim::loadScenario(scenario_path);
  std::unique_ptr<Robot> robot = sim::makeSimRobot(model, scenario);
  const tool::StopOnError stop_on_error([&] { robot->stop(); });
  tool::makeOutputDir(out);
  const std::string csv_path = out + "/state.csv";
  std::ofstream csv(csv_path);
  csv << RobotState::csvHeader(model.arm.dof()) << '\n';
  tool::checkWritten(csv, csv_path);
  if (robot->configure() != ReturnType::kOk || robot->activate() != ReturnType::kOk) {
    robot->stop();
    std::fprintf(stderr, "sim_enon_demo: could not activate the simulated enon\n");
    return kRobotFailed;
  }
  const double dt = model.control_period_s;
  // 64-bit: cycles and frames of a long run at a short period never wrap.
  const int64_t cycles = static_cast<int64_t>(std::ceil(std::min(duration_s, scenario.max_duration_s) / dt));
  int64_t frames = 0, written = 0;
  for (int64_t k = 0; k <= cycles; ++k) {
    const double t = static_cast<double>(k) * dt;
    if (robot->read(t, dt) != ReturnType::kOk) {
      robot->stop();
      std::fprintf(stderr, "sim_enon_demo: read failed at t=%.3f s: %s\n", t,
                   robot->hardware().lastError().c_str());
      return kRobotFailed;
    }
    csv << robot->state().csvRow() << '\n';
    std::optional<StereoFrame> frame;
    if (robot->camera().grab(t, &frame) == ReturnType::kOk && frame) {
      if (frames++ % png_every == 0) {
        char name[64];
        std::snprintf(name, sizeof(name), "/frame_%05lld_", static_cast<long long>(frame->index));
        tool::writeImage(out + name + "left.png", frame->left);
        tool::writeImage(out + name + "right.png", frame->right);
        ++written;
      }
    }
    command(*robot, t);
    if (robot->write(t, dt) != ReturnType::kOk) {
      robot->stop();
      std::fprintf(stderr, "sim_enon_demo: write failed at t=%.3f s: %s\n", t,
                   robot->hardware().lastError().c_str());
      return kRobotFailed;
    }
  }
  robot->deactivate();
  tool::checkWritten(csv, csv_path);
  const RobotState& s = robot->state();
  std::printf("%lld cycles, %lld frames (%lld written as PNG pairs) in %s\n",
              static_cast<long long>(cycles + 1), static_cast<long long>(frames),
              static_cast<long long>(written), out.c_str());
  std::printf("final odometry x=%.3f y=%.3f m, gripper %s%s%s\n", s.wMb_odom.t.x(), s.wMb_odom.t.y(),
              toString(s.gripper), s.held_object.empty() ? "" : " holding ", s.held_object.c_str());
  return 0;
}

int simEnonDemo(int argc, char** argv) {
  CLI::App app{"Scripted run of the simulated enon: CSV state log and stereo PNG frames.\n"
               "Exit status: 0 done; 2 bad options or files; 3 an output could not be written;\n"
               "4 the robot failed (it is stopped first)."};
  std::string enon = "config/enon.yaml";
  std::string scenario = "config/scenarios/table_single.yaml";
  std::string out = "sim_enon_demo_out";
  double duration = 10.0;
  int64_t every = 48;
  app.add_option("--enon", enon, "robot model YAML")->capture_default_str();
  app.add_option("--scenario", scenario, "scenario YAML")->capture_default_str();
  app.add_option("--out", out, "output directory")->capture_default_str();
  app.add_option("--duration", duration, "simulated seconds (at most the scenario's max_duration_s)")
      ->check(tool::Finite(1e-3, 3600))
      ->capture_default_str();
  app.add_option("--png-every", every, "write every N-th delivered frame")
      ->check(tool::Integer(1, int64_t{1} << 40))
      ->capture_default_str();
  tool::parse(app, argc, argv);
  tool::Paths paths;
  paths.input("--enon", enon);
  paths.input("--scenario", scenario);
  paths.outputFolder("--out", out);
  paths.check();
  return run(enon, scenario, out, duration, every);
}

}  // namespace

int main(int argc, char** argv) { return tool::run("sim_enon_demo", argc, argv, simEnonDemo); }
