// enon_grasp --backend dds against sim_robot_node: the same search-approach-grasp, in real time,
// with the robot on the DDS bus (loopback, a private domain and namespace, bounded in time). The
// simulator's ground truth at exit says whether the target is held.
#include <gtest/gtest.h>

#include <cmath>
#include <csignal>
#include <fstream>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/subprocess.h"
#include "common/temp_dir.h"
#include "dds_test_util.h"
#include "robot/enon_model.h"
#include "robot/files/recording.h"

using nlohmann::json;
using refgrasp::testing::Subprocess;

namespace {

const std::string kSource = REFGRASP_SOURCE_DIR;
const std::string kApps = REFGRASP_APP_DIR;

/// sim_robot_node on the default scenario in a private domain and namespace (loopback), with a
/// scratch folder; the node writes its ground truth to dir/truth.json when it ends.
struct NodeRun {
  std::string domain = std::to_string(refgrasp::testing::privateDomain());
  std::string ns = refgrasp::testing::privateNamespace("enon");
  std::filesystem::path dir;
  std::string scenario = kSource + "/config/scenarios/table_single.yaml";
  std::string enon = kSource + "/config/enon.yaml";
  std::filesystem::path result;
  explicit NodeRun(const std::string& name) : dir(refgrasp::testing::tempDir(name)), result(dir / "truth.json") {
    refgrasp::testing::useLoopbackDds();
  }
  struct Outcome {
    int rc = -1;
    std::string out, err;
  };
  /// The node, then enon_grasp --backend dds on it with `extra` options; the node is stopped
  /// (SIGTERM) when enon_grasp has ended and must exit 0.
  Outcome grasp(const std::vector<std::string>& extra, double timeout_s) const {
    Subprocess node({kApps + "/sim_robot_node", "--scenario", scenario, "--enon", enon, "--ns", ns,
                     "--domain", domain, "--camera-rate", "16", "--result", result.string()},
                    dir, "node");
    std::vector<std::string> argv = {kApps + "/enon_grasp", "--backend", "dds", "--scenario", scenario,
                                     "--enon", enon, "--ns", ns, "--domain", domain};
    argv.insert(argv.end(), extra.begin(), extra.end());
    Subprocess g(argv, dir, "grasp");
    Outcome o;
    o.rc = g.wait(timeout_s);
    o.out = g.out();
    o.err = g.err();
    node.signal(SIGTERM);
    EXPECT_EQ(node.wait(10), 0) << node.err();
    return o;
  }
};

}  // namespace

TEST(EnonGraspDds, GraspsOnTheDefaultScenarioAgainstSimRobotNode) {
  const NodeRun run("refgrasp_enon_grasp_dds");
  const NodeRun::Outcome grasp = run.grasp({"--max-time", "60"}, 90);
  ASSERT_EQ(grasp.rc, 0) << grasp.err << grasp.out;
  const json summary = json::parse(grasp.out);
  EXPECT_EQ(summary["success"], true);
  EXPECT_EQ(summary["phases"]["grasp"]["outcome"], "holding");
  std::ifstream in(run.result);
  const json truth = json::parse(in);
  EXPECT_EQ(truth["held_object"], "cereal_box");
  EXPECT_EQ(truth["bad_commands"], 0);
}

// The on-robot pairing (docs/tools/enon_grasp.md: --backend dds --camera bb2): the robot on the DDS
// bus, the frames from a camera on this computer. No FireWire camera here, so a recording stands in
// for the Bumblebee2 (the same option, the same re-stamping onto the loop's clock): every frame the
// run logs is the recording's (uniform gray: nothing to find), none is the node's image_raw,
// stamped on the loop's clock with the head pose the DDS states give at that time; the run ends
// without a grasp (exit 1) and the node saw no bad command.
TEST(EnonGraspDds, TheCameraOptionPairsTheDdsRobotWithALocalCamera) {
  const NodeRun run("refgrasp_enon_grasp_dds_camera");
  const std::filesystem::path& dir = run.dir;
  const refgrasp::robot::EnonModel model = refgrasp::robot::loadEnonModel(run.enon);
  {
    refgrasp::files::RecordingOptions o;
    o.fsync = false;
    auto w = refgrasp::files::RecordingWriter::createStereo((dir / "camera").string(), model.head.rig, o);
    for (int i = 0; i < 150; ++i) {
      refgrasp::robot::StereoFrame f;
      f.left = cv::Mat(model.head.rig.left.height, model.head.rig.left.width, CV_8UC1, cv::Scalar(60));
      f.right = cv::Mat(model.head.rig.right.height, model.head.rig.right.width, CV_8UC1, cv::Scalar(61));
      f.stamp = i / 20.0;
      f.index = i;
      ASSERT_TRUE(w->write(f).ok);
    }
  }
  const NodeRun::Outcome grasp = run.grasp(
      {"--max-time", "4", "--camera", "recording:" + (dir / "camera").string(), "--log", (dir / "log").string()}, 60);
  EXPECT_EQ(grasp.rc, 1) << grasp.err << grasp.out;
  const json summary = json::parse(grasp.out);
  EXPECT_EQ(summary["success"], false);
  int logged = 0;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir / "log")) {
    if (e.path().extension() != ".png") continue;
    const cv::Mat img = cv::imread(e.path().string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(img.empty()) << e.path();
    double lo = 0, hi = 0;
    cv::minMaxLoc(img, &lo, &hi);
    EXPECT_TRUE((lo == 60 && hi == 60) || (lo == 61 && hi == 61)) << e.path() << ": not the recording's";
    ++logged;
  }
  // Three stop-and-look views in 4 s, each a stereo pair.
  EXPECT_GE(logged, 6) << "frames from --camera reached the controller";
  // Stamped on the loop's clock at the grab (the recording's stamps were index / 20 s), with the
  // robot's head pose at that time from the DDS states.
  std::ifstream index(dir / "log" / "index.jsonl");
  int frames = 0;
  for (std::string line; std::getline(index, line);) {
    const json f = json::parse(line);
    const double stamp = f["stamp"].get<double>();
    EXPECT_GT(stamp, 0.1) << line;
    EXPECT_LT(stamp, 4.1) << line;
    EXPECT_GT(std::abs(stamp - frames / 20.0), 0.1) << line;
    EXPECT_NEAR(f["capture"]["head"]["pan_rad"].get<double>(), f["robot"]["pan_rad"].get<double>(), 0.02) << line;
    ++frames;
  }
  EXPECT_EQ(2 * frames, logged);
  std::ifstream in(run.result);
  const json truth = json::parse(in);
  EXPECT_EQ(truth["held_object"], "");
  EXPECT_EQ(truth["bad_commands"], 0);
}
