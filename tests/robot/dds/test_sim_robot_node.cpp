// sim_robot_node as a process: options, and a ROS 2 teleop/listener (the plain-C probe) driving
// the simulated enon over the bus; the ground truth written at exit shows where it went.
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
const std::string kApp = std::string(REFGRASP_APP_DIR) + "/sim_robot_node";
const std::string kScenario = kSource + "/config/scenarios/table_single.yaml";
const std::string kEnon = kSource + "/config/enon.yaml";

class SimRobotNode : public ::testing::Test {
 protected:
  void SetUp() override {
    refgrasp::testing::useLoopbackDds();
    domain_ = std::to_string(refgrasp::testing::privateDomain());
    ns_ = refgrasp::testing::privateNamespace("enon");
    dir_ = refgrasp::testing::tempDir("refgrasp_sim_robot_node");
  }
  std::pair<int, std::string> run(const std::vector<std::string>& a) {
    Subprocess p(a, dir_, "run");
    const int rc = p.wait(30);
    return {rc, p.err()};
  }
  std::string domain_, ns_;
  std::filesystem::path dir_;
};

}  // namespace

TEST_F(SimRobotNode, BadOptionsAndFiles) {
  auto [rc, err] = run({kApp});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find("--scenario"), std::string::npos) << err;
  std::tie(rc, err) = run({kApp, "--scenario", "/no/scenario.yaml", "--enon", kEnon});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find("/no/scenario.yaml"), std::string::npos) << err;
  std::tie(rc, err) = run({kApp, "--scenario", kScenario, "--enon", "/no/enon.yaml"});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find("/no/enon.yaml"), std::string::npos) << err;
  std::tie(rc, err) = run({kApp, "--scenario", kScenario, "--enon", kEnon, "--ns", "enon"});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find("--ns: 'enon' is not fully qualified"), std::string::npos) << err;
  std::tie(rc, err) = run({kApp, "--scenario", kScenario, "--enon", kEnon, "--domain", "500"});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find("--domain: 500 not in [0, 232]"), std::string::npos) << err;
  std::tie(rc, err) = run({kApp, "--scenario", kScenario, "--enon", kEnon, "--camera-rate", "-1"});
  EXPECT_EQ(rc, 2);
}

TEST_F(SimRobotNode, RosTeleopDrivesItAndTheGroundTruthShowsIt) {
  const auto result = dir_ / "result.json";
  Subprocess node({kApp, "--scenario", kScenario, "--enon", kEnon, "--ns", ns_, "--domain", domain_,
                   "--camera-rate", "5", "--result", result.string()},
                  dir_, "node");
  auto probe = [&](std::vector<std::string> a) {
    std::vector<std::string> v = {refgrasp::testing::probePath(), "--domain", domain_};
    v.insert(v.end(), a.begin(), a.end());
    return v;
  };
  Subprocess js(probe({"echo", "rt" + ns_ + "/joint_states", "sensor_msgs::msg::dds_::JointState_",
                       "--count", "1", "--timeout", "30"}),
                dir_, "js");
  ASSERT_EQ(js.wait(40), 0) << js.err() << node.err();
  EXPECT_TRUE(json::parse(js.out())["ok"].get<bool>());
  Subprocess img(probe({"echo", "rt" + ns_ + "/left/image_raw", "sensor_msgs::msg::dds_::Image_",
                        "--count", "1", "--timeout", "30"}),
                 dir_, "img");
  ASSERT_EQ(img.wait(40), 0) << img.err();
  const json im = json::parse(img.out());
  ASSERT_TRUE(im["ok"].get<bool>());
  EXPECT_EQ(im["msg"]["encoding"], "mono8");
  EXPECT_EQ(im["msg"]["width"], 640);
  EXPECT_EQ(im["msg"]["header"]["frame_id"], "left_camera_optical_frame");
  Subprocess teleop(probe({"pub-twist", "rt" + ns_ + "/cmd_vel", "0.2", "0.0", "--count", "50", "--rate", "50"}),
                    dir_, "teleop");
  ASSERT_EQ(teleop.wait(20), 0) << teleop.err();
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  node.signal(SIGTERM);
  ASSERT_EQ(node.wait(10), 0) << node.err();
  std::ifstream in(result);
  const json r = json::parse(in);
  // 0.2 m/s for as long as the commands spanned (the first may come before the node has matched
  // the probe), plus at most the 0.2 s command lifetime (enon.yaml) and a control period.
  const double span = json::parse(teleop.out())["first_to_last_s"].get<double>();
  EXPECT_GT(r["base_true"]["x_m"].get<double>(), 0.2 * 0.3);
  EXPECT_LT(r["base_true"]["x_m"].get<double>(), 0.2 * (span + 0.2 + 0.05)) << "span " << span;
  EXPECT_NEAR(r["base_true"]["y_m"].get<double>(), 0.0, 1e-9);
  EXPECT_EQ(r["held_object"], "");
  EXPECT_EQ(r["bad_commands"], 0);
  EXPECT_GT(r["frames_published"].get<int>(), 0);
  EXPECT_NE(node.err().find("sim_robot_node: stopped after"), std::string::npos);
}
