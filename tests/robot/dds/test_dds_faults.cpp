// Faults of the robot's DDS link, with the real processes (sim_robot_node, enon_grasp --backend
// dds) on loopback in a private domain and namespace, watched by a listener in this process:
//   - the robot node killed (SIGKILL) or frozen (SIGSTOP) mid-approach: enon_grasp sends zero
//     commands to every actuator within the watchdog period and exits 3 with one line;
//   - enon_grasp killed mid-run: the node's watchdog stops the simulated robot;
//   - a driver that stalled (or was stopped) does not take a command that waited in its reader.
// REFGRASP_DDS_FAULT_RUNS=N repeats each fault N times (default 1) and prints one
// "dds_fault: ..." line per run: the numbers of docs/results.md "DDS faults".
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "common/subprocess.h"
#include "common/temp_dir.h"
#include "dds_test_util.h"
#include "robot/dds/convert.h"
#include "robot/dds/driver_node.h"
#include "robot/dds/robot_topics.h"
#include "robot/dds/transport.h"
#include "robot/enon_model.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"

using nlohmann::json;
using refgrasp::testing::Subprocess;
namespace dds = refgrasp::dds;

namespace {

const std::string kSource = REFGRASP_SOURCE_DIR;
const std::string kApps = REFGRASP_APP_DIR;
const std::string kScenario = kSource + "/config/scenarios/table_single.yaml";
const std::string kEnon = kSource + "/config/enon.yaml";

// Time a loaded 2-core machine may add to a deadline of the robot's (the processes' threads
// waiting for a core, the listener's 1 ms polling): 0.3 s.
constexpr double kSchedulingAllowanceS = 0.3;

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

int runs() {
  const char* v = std::getenv("REFGRASP_DDS_FAULT_RUNS");
  return v && std::atoi(v) > 0 ? std::atoi(v) : 1;
}

/// One message seen on the bus: when it arrived here (steady clock, s) and whether it asks for
/// (commands) or shows (states) motion.
struct Seen {
  double t = 0;
  bool moving = false;
};

/// Largest |x| of a sequence (0 when empty).
double maxAbs(const dds_sequence_double& s) {
  double m = 0;
  for (uint32_t i = 0; i < s._length; ++i) m = std::max(m, std::abs(s._buffer[i]));
  return m;
}

bool trajectoryMoves(const dds::msg::JointTrajectory& t) {
  if (t.points._length < 1) return false;
  const auto& p = t.points._buffer[0];
  return p.positions._length > 0 || maxAbs(p.velocities) > 0;  // a position target moves too
}

/// Listens to the robot's commands and states as any other node on the bus would, from a
/// thread polling every millisecond.
class BusListener {
 public:
  BusListener(int domain, const std::string& ns)
      : topics_(ns),
        pp_(domain),
        cmd_vel_(pp_, dds::ddsTopicName(topics_.cmd_vel), dds::QosProfile::reliable(100)),
        head_(pp_, dds::ddsTopicName(topics_.head_command), dds::QosProfile::reliable(100)),
        arm_(pp_, dds::ddsTopicName(topics_.arm_command), dds::QosProfile::reliable(100)),
        odom_(pp_, dds::ddsTopicName(topics_.odom), dds::QosProfile::reliable(100)),
        joints_(pp_, dds::ddsTopicName(topics_.joint_states), dds::QosProfile::reliable(100)),
        thread_([this] { loop(); }) {}
  ~BusListener() {
    stop_ = true;
    thread_.join();
  }
  struct Log {
    std::vector<Seen> cmd_vel, head, arm, odom, joints;
    std::vector<Eigen::Vector3d> odom_pose;  ///< (x m, y m, heading rad) of each odom message
  };
  Log log() {
    std::lock_guard<std::mutex> lock(mu_);
    return log_;
  }

 private:
  void loop() {
    while (!stop_) {
      {
        std::lock_guard<std::mutex> lock(mu_);
        for (auto& s : cmd_vel_.takeAll())
          log_.cmd_vel.push_back({now(), s->linear.x != 0 || s->angular.z != 0});
        for (auto& s : head_.takeAll()) log_.head.push_back({now(), trajectoryMoves(*s)});
        for (auto& s : arm_.takeAll()) log_.arm.push_back({now(), trajectoryMoves(*s)});
        for (auto& s : odom_.takeAll()) {
          log_.odom.push_back({now(), s->twist.twist.linear.x != 0 || s->twist.twist.angular.z != 0});
          const auto& p = s->pose.pose;
          log_.odom_pose.emplace_back(p.position.x, p.position.y,
                                      2 * std::atan2(p.orientation.z, p.orientation.w));
        }
        for (auto& s : joints_.takeAll()) log_.joints.push_back({now(), maxAbs(s->velocity) > 0});
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }
  dds::RobotTopics topics_;
  dds::Participant pp_;
  dds::Reader<dds::msg::Twist> cmd_vel_;
  dds::Reader<dds::msg::JointTrajectory> head_, arm_;
  dds::Reader<dds::msg::Odometry> odom_;
  dds::Reader<dds::msg::JointState> joints_;
  std::mutex mu_;
  Log log_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

/// The first time >= after from which every message of `seen` is "not moving" (NAN when the
/// last one moves or none came after `after`).
double stillFrom(const std::vector<Seen>& seen, double after) {
  double from = NAN;
  for (const Seen& s : seen) {
    if (s.t < after) continue;
    if (s.moving) from = NAN;
    else if (std::isnan(from)) from = s.t;
  }
  return from;
}

class DdsFaults : public ::testing::Test {
 protected:
  void SetUp() override {
    refgrasp::testing::useLoopbackDds();
    domain_ = refgrasp::testing::privateDomain();
    ns_ = refgrasp::testing::privateNamespace("enon");
    dir_ = refgrasp::testing::tempDir("refgrasp_dds_faults");
    watchdog_s_ = refgrasp::robot::loadEnonModel(kEnon).watchdog_period_s;
    period_s_ = refgrasp::robot::loadEnonModel(kEnon).control_period_s;
  }
  std::unique_ptr<Subprocess> startNode(const std::string& tag) {
    return std::make_unique<Subprocess>(
        std::vector<std::string>{kApps + "/sim_robot_node", "--scenario", kScenario, "--enon", kEnon,
                                 "--ns", ns_, "--domain", std::to_string(domain_), "--camera-rate",
                                 "16", "--result", (dir_ / (tag + "_truth.json")).string()},
        dir_, tag + "_node");
  }
  std::unique_ptr<Subprocess> startGrasp(const std::string& tag) {
    std::filesystem::remove_all(dir_ / (tag + "_log"));
    return std::make_unique<Subprocess>(
        std::vector<std::string>{kApps + "/enon_grasp", "--backend", "dds", "--scenario", kScenario,
                                 "--enon", kEnon, "--ns", ns_, "--domain", std::to_string(domain_),
                                 "--max-time", "60", "--log", (dir_ / (tag + "_log")).string()},
        dir_, tag + "_grasp");
  }
  struct Run {
    std::unique_ptr<BusListener> bus;
    std::unique_ptr<Subprocess> node, grasp;
    bool approaching = false;  ///< the robot was driving to the target when this returned
    std::string errors() const { return grasp->err() + node->err(); }
  };
  /// The listener, the node and enon_grasp on it, returned once the robot drives to the target.
  Run startApproaching(const std::string& tag) {
    Run r;
    r.bus = std::make_unique<BusListener>(domain_, ns_);
    r.node = startNode(tag);
    r.grasp = startGrasp(tag);
    r.approaching = waitApproaching(tag, *r.grasp, *r.bus);
    return r;
  }
  /// Waits until enon_grasp's control.jsonl is in the approach phase and the listener has seen
  /// it command the base since (the robot is driving to the target).
  bool waitApproaching(const std::string& tag, Subprocess& grasp, BusListener& bus) {
    const auto control = dir_ / (tag + "_log") / "control.jsonl";
    double since = NAN;
    return refgrasp::testing::waitUntil(
        [&] {
          if (!grasp.running()) return true;
          if (std::isnan(since)) {
            std::ifstream in(control);
            for (std::string line; std::getline(in, line);)
              if (line.find("\"phase\":\"approach\"") != std::string::npos) since = now();
            return false;
          }
          const auto log = bus.log();
          return !log.cmd_vel.empty() && log.cmd_vel.back().moving && log.cmd_vel.back().t > since;
        },
        60) &&
           grasp.running();
  }

  int domain_ = 0;
  std::string ns_;
  std::filesystem::path dir_;
  double watchdog_s_ = 0, period_s_ = 0;
};

}  // namespace

// enon_grasp's watchdog: the newest robot state older than watchdog_period_s (enon.yaml) is an
// error: zero commands on cmd_vel, head and arm within that period of the robot's last state
// (plus a control period to notice it and the scheduling allowance), one line, exit 3. Its exit
// follows within one Cyclone writer linger (1 s: the dead robot never acknowledges the last
// commands; one per command writer, 3 s, if they were deleted one after the other) and the
// process's teardown (1 s allowed on a loaded machine). A frozen node thawed afterwards does not
// move.
TEST_F(DdsFaults, RobotNodeKilledOrFrozenMidApproachStopsEnonGraspWithinTheWatchdogPeriod) {
  constexpr double kWriterLingerS = 1.0, kTeardownS = 1.0;
  for (const int sig : {SIGKILL, SIGSTOP}) {
    const std::string name = sig == SIGKILL ? "sigkill" : "sigstop";
    for (int run = 0; run < runs(); ++run) {
      const std::string tag = name + std::to_string(run);
      SCOPED_TRACE(tag);
      Run r = startApproaching(tag);
      ASSERT_TRUE(r.approaching) << r.errors();
      BusListener& bus = *r.bus;
      Subprocess &node = *r.node, &grasp = *r.grasp;
      const double t_kill = now();
      node.signal(sig);
      ASSERT_NE(grasp.wait(30), -1) << "enon_grasp did not exit";
      const double t_exit = now();
      std::this_thread::sleep_for(std::chrono::milliseconds(200));  // the last messages in flight
      const BusListener::Log log = bus.log();

      EXPECT_EQ(grasp.wait(0), 3) << grasp.err();
      const std::string err = grasp.err();
      EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
      // The state may go stale between a step's read and its write: either names the cause.
      EXPECT_TRUE(err.rfind("enon_grasp: robot read failed at t=", 0) == 0 ||
                  err.rfind("enon_grasp: robot write failed at t=", 0) == 0)
          << err;
      EXPECT_NE(err.find(" s: dds robot: no robot state for "), std::string::npos) << err;
      const json summary = json::parse(grasp.out());
      EXPECT_EQ(summary["phases"]["approach"]["outcome"], "error") << grasp.out();

      // Every actuator commanded to rest, and nothing moving commanded after.
      double zero = t_kill;
      for (const auto* topic : {&log.cmd_vel, &log.head, &log.arm}) {
        const double still = stillFrom(*topic, t_kill);
        ASSERT_FALSE(std::isnan(still)) << "a topic's last command after the fault moves";
        zero = std::max(zero, still);
      }
      const double stop_s = zero - t_kill, exit_s = t_exit - t_kill;
      std::printf("dds_fault: robot_node_%s run %d: zero commands %.3f s, enon_grasp exit %.3f s\n",
                  name.c_str(), run, stop_s, exit_s);
      EXPECT_LE(stop_s, watchdog_s_ + period_s_ + kSchedulingAllowanceS);
      EXPECT_LE(exit_s, watchdog_s_ + period_s_ + kWriterLingerS + kTeardownS);

      if (sig == SIGSTOP) {
        // Thawed, the node takes the newest command, a zero one: the robot stays at rest.
        const double t_cont = now();
        node.signal(SIGCONT);
        std::this_thread::sleep_for(std::chrono::milliseconds(800));
        const BusListener::Log after = bus.log();
        size_t states = 0;
        for (const Seen& s : after.odom) {
          if (s.t < t_cont) continue;
          ++states;
          EXPECT_FALSE(s.moving) << "the thawed robot moves";
        }
        EXPECT_GT(states, 5u) << "the thawed node publishes its state again";
      }
      node.signal(SIGTERM);
      node.wait(10);
    }
  }
}

// sim_robot_node's watchdog: every command is dropped once older than watchdog_period_s, so a
// robot whose controller died stops within that period of the last command (plus a control
// period and the scheduling allowance), as its published odometry and joint states show, and
// stays stopped.
TEST_F(DdsFaults, EnonGraspKilledMidRunTheRobotNodeStopsTheRobotWithinTheWatchdogPeriod) {
  for (int run = 0; run < runs(); ++run) {
    const std::string tag = "grasp_killed" + std::to_string(run);
    SCOPED_TRACE(tag);
    Run r = startApproaching(tag);
    ASSERT_TRUE(r.approaching) << r.errors();
    BusListener& bus = *r.bus;
    Subprocess &node = *r.node, &grasp = *r.grasp;
    const double t_kill = now();
    grasp.signal(SIGKILL);
    ASSERT_EQ(grasp.wait(10), 128 + SIGKILL);
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));
    const BusListener::Log log = bus.log();
    ASSERT_TRUE(node.running()) << node.err();

    double last_command = -1;
    for (const auto* topic : {&log.cmd_vel, &log.head, &log.arm})
      if (!topic->empty()) last_command = std::max(last_command, topic->back().t);
    ASSERT_GT(last_command, 0);
    EXPECT_LE(last_command, t_kill + 0.05) << "commands after the kill";
    const double base = stillFrom(log.odom, last_command), joints = stillFrom(log.joints, last_command);
    ASSERT_FALSE(std::isnan(base)) << "the base still moves";
    ASSERT_FALSE(std::isnan(joints)) << "a joint still moves";
    const double moving_s = std::max(base, joints) - last_command;
    // How far the base went on after the last command (odometry).
    Eigen::Vector3d at_last = Eigen::Vector3d::Constant(NAN);
    for (size_t i = 0; i < log.odom.size(); ++i)
      if (log.odom[i].t <= last_command) at_last = log.odom_pose[i];
    const Eigen::Vector3d went = log.odom_pose.back() - at_last;
    std::printf("dds_fault: controller_killed run %d: robot moving %.3f s after the last command, "
                "base went on %.1f mm and %.2f deg\n",
                run, moving_s, 1000 * went.head<2>().norm(), std::abs(went.z()) * 180 / M_PI);
    EXPECT_LE(moving_s, watchdog_s_ + period_s_ + kSchedulingAllowanceS);

    node.signal(SIGTERM);
    ASSERT_EQ(node.wait(10), 0) << node.err();
    std::ifstream in(dir_ / (tag + "_truth.json"));
    const json truth = json::parse(in);
    EXPECT_EQ(truth["bad_commands"], 0);
  }
}

// The driver's watchdog counts a command's age from its writing, not from when the driver takes
// it: a driver that stalls longer than the watchdog period (here: not stepped for 0.5 s; a
// stopped or starved process alike) drops the command that waited in its reader, and the robot
// does not move; a command taken at once moves it.
TEST_F(DdsFaults, ACommandThatWaitedInAStalledDriverIsNotTaken) {
  const refgrasp::robot::EnonModel model = refgrasp::robot::loadEnonModel(kEnon);
  refgrasp::sim::SimEnon sim(model, refgrasp::sim::loadScenario(kScenario));
  dds::DriverNodeOptions o;
  o.domain = domain_;
  o.ns = ns_;
  dds::RobotDriverNode node(model, sim, nullptr, o);
  ASSERT_EQ(node.start(), refgrasp::robot::ReturnType::kOk);
  dds::Participant pp(domain_);
  dds::Writer<dds::msg::Twist> cmd(pp, dds::ddsTopicName(dds::RobotTopics(ns_).cmd_vel),
                                   dds::QosProfile::reliable(1));
  ASSERT_TRUE(cmd.waitForMatch(1, 30));
  dds::msg::Twist tw{};
  tw.linear.x = 0.3;
  const double dt = model.control_period_s;
  double t = 0;
  node.step(t);
  auto stepFor = [&](double seconds) {
    for (const double end = t + seconds; t < end;) node.step(t += dt);
  };

  ASSERT_TRUE(cmd.write(tw));
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // in the reader, not taken
  t += 0.5;
  stepFor(0.5);
  EXPECT_EQ(node.stats().commands, 1) << "the command did not reach the driver";
  EXPECT_NEAR(sim.trueBasePose().x_m, 0.0, 1e-12) << "the robot moved on a 0.5 s old command";

  ASSERT_TRUE(cmd.write(tw));
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  stepFor(0.5);
  // Taken at the next step: it moves the robot, for at most the watchdog period from its writing.
  EXPECT_GT(sim.trueBasePose().x_m, 0.3 * dt);
  EXPECT_LE(sim.trueBasePose().x_m, 0.3 * (model.watchdog_period_s + dt) + 1e-9);
  node.stop(t);
}
