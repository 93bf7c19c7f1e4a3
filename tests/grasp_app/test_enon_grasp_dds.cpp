// enon_grasp --backend dds against sim_robot_node (issue 10, "The robot over DDS"): the same
// search-approach-grasp, in real time, with the robot on the DDS bus (loopback, a private domain
// and namespace, bounded in time). The simulator's ground truth at exit says whether the target
// is held.
#include <gtest/gtest.h>

#include <csignal>
#include <fstream>
#include <nlohmann/json.hpp>

#include "common/subprocess.h"
#include "common/temp_dir.h"
#include "dds_test_util.h"

using nlohmann::json;
using refgrasp::testing::Subprocess;

namespace {

const std::string kSource = REFGRASP_SOURCE_DIR;
const std::string kApps = REFGRASP_APP_DIR;

}  // namespace

TEST(EnonGraspDds, GraspsOnTheDefaultScenarioAgainstSimRobotNode) {
  refgrasp::testing::useLoopbackDds();
  const std::string domain = std::to_string(refgrasp::testing::privateDomain());
  const std::string ns = refgrasp::testing::privateNamespace("enon");
  const auto dir = refgrasp::testing::tempDir("refgrasp_enon_grasp_dds");
  const std::string scenario = kSource + "/config/scenarios/table_single.yaml";
  const std::string enon = kSource + "/config/enon.yaml";
  const auto result = dir / "truth.json";
  Subprocess node({kApps + "/sim_robot_node", "--scenario", scenario, "--enon", enon, "--ns", ns,
                   "--domain", domain, "--camera-rate", "16", "--result", result.string()},
                  dir, "node");
  Subprocess grasp({kApps + "/enon_grasp", "--backend", "dds", "--scenario", scenario, "--enon",
                    enon, "--ns", ns, "--domain", domain, "--max-time", "60"},
                   dir, "grasp");
  const int rc = grasp.wait(90);
  node.signal(SIGTERM);
  ASSERT_EQ(node.wait(10), 0) << node.err();
  ASSERT_EQ(rc, 0) << grasp.err() << grasp.out();
  const json summary = json::parse(grasp.out());
  EXPECT_EQ(summary["success"], true);
  EXPECT_EQ(summary["phases"]["grasp"]["outcome"], "holding");
  std::ifstream in(result);
  const json truth = json::parse(in);
  EXPECT_EQ(truth["held_object"], "cereal_box");
  EXPECT_EQ(truth["bad_commands"], 0);
}
