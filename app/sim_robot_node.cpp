// sim_robot_node: the simulated enon as a robot on the DDS bus (the topics of
// src/robot/dds/robot_topics.h), for `enon_grasp --backend dds`, the vision component and ROS 2
// nodes. Runs in real time until SIGINT/SIGTERM or --duration.
#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "robot/dds/driver_node.h"
#include "robot/dds/transport.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"
#include "tool/tool.h"

using namespace refgrasp;
using json = nlohmann::ordered_json;

namespace {

const char* kDescription = R"(The simulated enon (a scenario of config/scenarios/) served on DDS as a ROS 2 robot driver:
  <ns>/cmd_vel (geometry_msgs/Twist), <ns>/head/command, <ns>/arm/command, <ns>/gripper/command
  (trajectory_msgs/JointTrajectory) in; <ns>/joint_states (sensor_msgs/JointState), <ns>/odom
  (nav_msgs/Odometry), <ns>/left|right/image_raw + camera_info (sensor_msgs) out.
Commands older than the watchdog period (enon.yaml) are dropped: a silent controller stops the
robot. Real time; the robot's clock starts at 0. With --result, the simulator's ground truth at
exit (held object, true base pose, object poses) is written as JSON.
Cyclone DDS reads CYCLONEDDS_URI (config/dds/cyclonedds_loopback.xml for one machine).
Exit status: 0 after SIGINT/SIGTERM or --duration; 2 bad options or files; 3 DDS failure;
4 the --result file could not be written.)";

std::atomic<bool> g_stop{false};
extern "C" void onSignal(int) { g_stop = true; }

json poseJson(const Pose& p) {
  const Eigen::Vector3d r = p.rotationVector();
  return {{"translation", {p.t.x(), p.t.y(), p.t.z()}}, {"rotation_vector", {r.x(), r.y(), r.z()}}};
}

int simRobotNode(int argc, char** argv) {
  CLI::App app(kDescription, "sim_robot_node");
  std::string enon = "config/enon.yaml", scenario_file, result_file;
  dds::DriverNodeOptions opt;
  double duration_s = 0;
  opt.camera_rate_hz = 15;
  app.add_option("--scenario", scenario_file, "scenario YAML (config/scenarios/)")->required();
  app.add_option("--enon", enon, "robot model")->capture_default_str();
  app.add_option("--ns", opt.ns, "ROS namespace of the robot's topics")->capture_default_str();
  // Range checked below (dds::domainOrNamespaceProblem); CLI11 refuses what an int cannot hold.
  auto* domain_opt = app.add_option("--domain", opt.domain, "DDS domain id, 0..232 (default: $ROS_DOMAIN_ID, else 0)");
  app.add_option("--camera-rate", opt.camera_rate_hz,
                 "stereo frames published per second at most (0: the camera's rate, 48 Hz)")
      ->check(tool::Finite(0, 1000))
      ->capture_default_str();
  app.add_option("--duration", duration_s, "stop after this many seconds (0: run until a signal)")
      ->check(tool::Finite(0, 1e7));
  app.add_option("--result", result_file, "write the ground truth at exit to this JSON file");
  tool::parse(app, argc, argv);
  const int env_domain = tool::checkDdsEnvironment();
  if (!*domain_opt) opt.domain = env_domain;
  tool::Paths paths;
  paths.input("--enon", enon);
  paths.input("--scenario", scenario_file);
  paths.output("--result", result_file);
  paths.check();
  if (!result_file.empty())
    if (const std::string p = tool::outputFileProblem(result_file); !p.empty())
      throw std::invalid_argument("--result " + result_file + ": " + p);
  // Until the node serves, a signal ends the tool at once (the robot has not moved yet).
  tool::exitOnSignal();
  if (const std::string p = dds::domainOrNamespaceProblem(opt.domain, opt.ns); !p.empty()) {
    std::fprintf(stderr, "sim_robot_node: %s\n", p.c_str());
    return 2;
  }
  if (!(opt.camera_rate_hz >= 0) || !(duration_s >= 0)) {
    std::fprintf(stderr, "sim_robot_node: --camera-rate and --duration must be >= 0\n");
    return 2;
  }
  std::unique_ptr<sim::SimEnon> sim;
  robot::EnonModel model;
  try {
    model = robot::loadEnonModel(enon);
    sim = std::make_unique<sim::SimEnon>(model, sim::loadScenario(scenario_file));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sim_robot_node: %s\n", e.what());
    return 2;
  }
  auto camera = sim->makeCamera();
  std::unique_ptr<dds::RobotDriverNode> node;
  try {
    node = std::make_unique<dds::RobotDriverNode>(model, *sim, camera.get(), opt);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sim_robot_node: %s\n", tool::withDdsError(e.what()).c_str());
    return 3;
  }
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  std::fprintf(stderr, "sim_robot_node: serving %s on DDS domain %d\n",
               dds::joinRosName(opt.ns, "joint_states").c_str(), opt.domain);
  dds::runRealTime(*node, model.control_period_s, g_stop, duration_s);
  const dds::DriverNodeStats st = node->stats();
  if (!result_file.empty()) {
    json j;
    j["time_s"] = sim->time();
    j["held_object"] = sim->heldObject() >= 0 ? sim->world().objects[static_cast<size_t>(sim->heldObject())].name : "";
    j["gripper"] = robot::toString(sim->gripperPhase());
    const auto b = sim->trueBasePose();
    j["base_true"] = {{"x_m", b.x_m}, {"y_m", b.y_m}, {"theta_rad", b.theta_rad}};
    j["objects"] = json::array();
    for (const auto& o : sim->world().objects) j["objects"].push_back({{"name", o.name}, {"wMo", poseJson(o.wMo)}});
    j["steps"] = st.steps;
    j["commands"] = st.commands;
    j["bad_commands"] = st.bad_commands;
    j["frames_published"] = st.frames_published;
    j["hardware_errors"] = st.hardware_errors;
    std::ofstream out(result_file);
    out << j.dump(2) << "\n";
    tool::checkWritten(out, result_file);
  }
  std::fprintf(stderr, "sim_robot_node: stopped after %ld steps, %ld commands, %ld stereo frames\n",
               st.steps, st.commands, st.frames_published);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  tool::RunOptions codes;
  codes.output_failed = 4;
  return tool::run("sim_robot_node", argc, argv, simRobotNode, codes);
}
