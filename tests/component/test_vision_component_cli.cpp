// vision_component as a process: options and exit codes, clean shutdown on signals, and a ROS 2
// node's view of it: the plain-C probe (tests/robot/dds/ros_probe.c, written from the ROS 2
// message definitions only) publishes camera frames, decodes the results, calls the service.
#include <gtest/gtest.h>

#include <csignal>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "common/subprocess.h"
#include "common/temp_dir.h"
#include "component_test_util.h"
#include "robot/dds/dds_test_util.h"

using nlohmann::json;
using namespace refgrasp;
using namespace refgrasp::testing;

namespace {

const std::string kSource = REFGRASP_SOURCE_DIR;
const std::string kApp = std::string(REFGRASP_APP_DIR) + "/vision_component";
const std::string kObject = kSource + "/config/objects/cereal_box.yaml";
constexpr double kDeg = M_PI / 180;

class ComponentCli : public ::testing::Test {
 protected:
  void SetUp() override {
    useLoopbackDds();
    domain_ = std::to_string(privateDomain());
    ns_ = privateNamespace("vcli");
    dir_ = tempDir("refgrasp_vc_cli");
  }
  std::vector<std::string> args(std::vector<std::string> extra) const {
    std::vector<std::string> a = {kApp, "--domain", domain_, "--ns", ns_};
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  }
  /// Runs to completion (bad-option cases exit at once).
  std::pair<int, std::string> run(const std::vector<std::string>& a) {
    Subprocess p(a, dir_, "run");
    const int rc = p.wait(30);
    return {rc, p.err()};
  }
  /// Waits for the "serving" line.
  static bool waitServing(Subprocess& p, double timeout_s) {
    return waitUntil([&] { return p.err().find("vision_component: serving") != std::string::npos || !p.running(); },
                     timeout_s) &&
           p.running();
  }
  std::vector<std::string> probe(std::vector<std::string> a) const {
    std::vector<std::string> v = {probePath(), "--domain", domain_};
    v.insert(v.end(), a.begin(), a.end());
    return v;
  }

  std::string domain_, ns_;
  std::filesystem::path dir_;
};

}  // namespace

TEST_F(ComponentCli, HelpAndBadOptions) {
  {
    Subprocess p({kApp, "--help"}, dir_, "help");
    EXPECT_EQ(p.wait(10), 0);
    EXPECT_NE(p.out().find("--object"), std::string::npos);
    EXPECT_NE(p.out().find("Exit status"), std::string::npos);
  }
  auto [rc, err] = run({kApp});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find("--object"), std::string::npos) << err;
  std::tie(rc, err) = run(args({"--object", "/no/such/object.yaml"}));
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find("/no/such/object.yaml"), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  std::tie(rc, err) = run({kApp, "--object", kObject, "--ns", "refgrasp"});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find("--ns: 'refgrasp' is not fully qualified"), std::string::npos) << err;
  std::tie(rc, err) = run({kApp, "--object", kObject, "--domain", "300"});
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find("--domain: 300 not in [0, 232]"), std::string::npos) << err;
  std::tie(rc, err) = run(args({"--object", kObject, "--stereo", "/no/rig.yaml"}));
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find("/no/rig.yaml"), std::string::npos) << err;
  std::tie(rc, err) = run(args({"--object", kObject, "--object", kObject}));
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find("name: object name 'cereal_box' used twice"), std::string::npos) << err;
  std::tie(rc, err) = run(args({"--object", kObject, "--detector-config", "/no/detector.yaml"}));
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find("/no/detector.yaml"), std::string::npos) << err;
  const auto bad_config = dir_ / "detector.yaml";
  std::ofstream(bad_config) << "match:\n  min_inliers: 2\n";
  std::tie(rc, err) = run(args({"--object", kObject, "--detector-config", bad_config.string()}));
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find(bad_config.string() + ": match.min_inliers:"), std::string::npos) << err;
  // A 2D-only object (no reference_pose) has no pose to fuse in stereo.
  const auto flat = dir_ / "flat.yaml";
  std::ofstream(flat) << "reference_image: " << kSource << "/media/targets/cereal_box.png\n";
  std::tie(rc, err) = run(args({"--object", flat.string(), "--stereo", kSource + "/config/cameras/bb2_rig.yaml"}));
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find(flat.string() + ": reference_pose: required with --stereo"), std::string::npos) << err;
  // The tracker's re-detection option: only with --track, a finite number >= 0.
  std::tie(rc, err) = run(args({"--prior-max-scale", "0.4", "--object", kObject}));
  EXPECT_EQ(rc, 2);
  EXPECT_NE(err.find("vision_component: --prior-max-scale: needs --track"), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  for (const char* bad : {"-1", "nan", "x"}) {
    std::tie(rc, err) = run(args({"--object", kObject, "--track", "--prior-max-scale", bad}));
    EXPECT_EQ(rc, 2) << bad;
    EXPECT_NE(err.find("--prior-max-scale"), std::string::npos) << bad << ": " << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  }
}

TEST_F(ComponentCli, DdsFailureIsExit3) {
  const std::string keep = std::getenv("CYCLONEDDS_URI");
  ::setenv("CYCLONEDDS_URI", "<CycloneDDS><Domain><General><NoSuchSetting/></General></Domain></CycloneDDS>", 1);
  auto [rc, err] = run(args({"--object", kObject}));
  ::setenv("CYCLONEDDS_URI", keep.c_str(), 1);
  EXPECT_EQ(rc, 3) << err;
  EXPECT_NE(err.find("vision_component: domain " + domain_ + ": cannot create a participant"), std::string::npos) << err;
}

TEST_F(ComponentCli, SignalsStopItCleanly) {
  for (int sig : {SIGINT, SIGTERM}) {
    // (with the shipped detector options, which must be accepted; SIGTERM with --track)
    std::vector<std::string> a = {"--object", kObject, "--detector-config", kSource + "/config/detector.yaml"};
    const bool track = sig == SIGTERM;
    if (track) a.push_back("--track");
    Subprocess p(args(a), dir_, "sig" + std::to_string(sig));
    ASSERT_TRUE(waitServing(p, 30)) << p.err();
    EXPECT_EQ(p.err().find("tracking") != std::string::npos, track) << p.err();
    p.signal(sig);
    EXPECT_EQ(p.wait(10), 0) << "signal " << sig << ": " << p.err();
    const json j = json::parse(p.out());
    EXPECT_EQ(j["frames_received"], 0);
    EXPECT_EQ(j["frames_dropped"], 0);
    EXPECT_EQ(j.contains("frames_tracked"), track) << p.out();
  }
}

// A ROS 2 camera driver, listeners and a service client (all the plain-C probe, each a separate
// process) against the component process: poses match the rendered ground truth.
TEST_F(ComponentCli, RosNodesUseTheComponent) {
  Subprocess vc(args({"--object", kObject}), dir_, "vc");
  ASSERT_TRUE(waitServing(vc, 30)) << vc.err();
  const Frame f = renderFrame("targets/cereal_box.png", 4242);
  const std::string pgm = (dir_ / "frame.pgm").string();
  ASSERT_TRUE(cv::imwrite(pgm, f.image));

  // Each camera run has its own stamps, so a result is matched to the run that caused it.
  int stamp0 = 1000;
  auto firstOfRun = [&](const std::string& out) {
    std::istringstream lines(out);
    std::string line;
    while (std::getline(lines, line)) {
      const json j = json::parse(line);
      if (j["msg"]["header"]["stamp"]["sec"].get<int>() >= stamp0) return j;
    }
    return json();
  };
  for (const std::string enc : {"mono8", "bgr8"}) {
    stamp0 += 1000;
    Subprocess info(probe({"echo", "rt" + ns_ + "/object_info", "refgrasp_msgs::msg::dds_::ObjectInfo_",
                           "--count", "6", "--timeout", "30"}),
                    dir_, "info");
    Subprocess pose(probe({"echo", "rt" + ns_ + "/object_pose", "geometry_msgs::msg::dds_::PoseStamped_",
                           "--count", "6", "--timeout", "30"}),
                    dir_, "pose");
    Subprocess dets(probe({"echo", "rt" + ns_ + "/detections", "vision_msgs::msg::dds_::Detection3DArray_",
                           "--count", "6", "--timeout", "30"}),
                    dir_, "dets");
    std::this_thread::sleep_for(std::chrono::milliseconds(500));  // let the listeners match
    Subprocess cam(probe({"pub-image", ns_, pgm, enc, "--f", "550", "--count", "40", "--rate", "4",
                          "--frame", "camera_optical_frame", "--stamp0", std::to_string(stamp0)}),
                   dir_, "cam");
    ASSERT_EQ(info.wait(40), 0) << info.err() << vc.err();
    ASSERT_EQ(pose.wait(30), 0) << pose.err();
    ASSERT_EQ(dets.wait(30), 0) << dets.err();
    cam.signal(SIGKILL);
    const json oi = firstOfRun(info.out());
    ASSERT_FALSE(oi.is_null()) << "no object_info for this run's frames:\n" << info.out();
    ASSERT_TRUE(oi["ok"].get<bool>()) << info.out();
    EXPECT_EQ(oi["msg"]["object_name"], "cereal_box");
    ASSERT_TRUE(oi["msg"]["found"].get<bool>()) << enc << ": " << vc.err();
    Pose P;
    for (int k = 0; k < 9; ++k) P.R(k / 3, k % 3) = oi["msg"]["rotation"][k].get<double>();
    for (int k = 0; k < 3; ++k) P.t[k] = oi["msg"]["translation"][k].get<double>();
    EXPECT_LT(rotationError(P, f.cMo), 1 * kDeg) << enc;
    EXPECT_LT(translationError(P, f.cMo), 0.01 * f.cMo.t.norm()) << enc;
    EXPECT_EQ(oi["msg"]["header"]["frame_id"], "camera_optical_frame");

    const json ps = firstOfRun(pose.out());
    ASSERT_FALSE(ps.is_null()) << pose.out();
    ASSERT_TRUE(ps["ok"].get<bool>()) << pose.out();
    const double px = ps["msg"]["pose"]["position"]["x"].get<double>(), py = ps["msg"]["pose"]["position"]["y"].get<double>(),
                 pz = ps["msg"]["pose"]["position"]["z"].get<double>();
    EXPECT_LT((Eigen::Vector3d(px, py, pz) - f.cMo.t).norm(), 0.01 * f.cMo.t.norm());
    const json da = firstOfRun(dets.out());
    ASSERT_FALSE(da.is_null()) << dets.out();
    ASSERT_TRUE(da["ok"].get<bool>()) << dets.out();
    ASSERT_EQ(da["msg"]["detections"].size(), 1u);
    EXPECT_EQ(da["msg"]["detections"][0]["results"][0]["hypothesis"]["class_id"], "cereal_box");
  }

  // The service, called as rmw_cyclonedds does (request header {writer instance handle, 1}).
  Subprocess call(probe({"call", ns_ + "/detect", "cereal_box", "0", "--wait", "10"}), dir_, "call");
  ASSERT_EQ(call.wait(20), 0) << call.err();
  json rep = json::parse(call.out());
  ASSERT_TRUE(rep["ok"].get<bool>()) << call.out();
  EXPECT_EQ(rep["msg"]["request_header"]["seq"], 1);
  EXPECT_TRUE(rep["msg"]["found"].get<bool>());
  EXPECT_EQ(rep["msg"]["error"], "");
  EXPECT_NEAR(rep["msg"]["translation"][2].get<double>(), f.cMo.t.z(), 0.01 * f.cMo.t.norm());
  Subprocess unknown(probe({"call", ns_ + "/detect", "x", "0", "--wait", "10"}), dir_, "unknown");
  ASSERT_EQ(unknown.wait(20), 0) << unknown.err();
  rep = json::parse(unknown.out());
  EXPECT_FALSE(rep["msg"]["found"].get<bool>());
  EXPECT_EQ(rep["msg"]["error"], "unknown object 'x'");

  // A frame the component cannot use: a warning on its stderr, found = false, serving goes on.
  stamp0 += 1000;
  Subprocess info(probe({"echo", "rt" + ns_ + "/object_info", "refgrasp_msgs::msg::dds_::ObjectInfo_",
                         "--count", "6", "--timeout", "30"}),
                  dir_, "info_bad");
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  Subprocess bad(probe({"pub-image", ns_, pgm, "yuv422", "--count", "40", "--rate", "4", "--stamp0",
                        std::to_string(stamp0)}),
                 dir_, "bad");
  ASSERT_EQ(info.wait(40), 0) << info.err();
  bad.signal(SIGKILL);
  const json oi = firstOfRun(info.out());
  ASSERT_FALSE(oi.is_null()) << info.out();
  EXPECT_FALSE(oi["msg"]["found"].get<bool>());
  EXPECT_NE(vc.err().find("warning: " + ns_ + "/image_raw: encoding 'yuv422' not supported"), std::string::npos)
      << vc.err();
  EXPECT_TRUE(vc.running());

  vc.signal(SIGINT);
  ASSERT_EQ(vc.wait(10), 0) << vc.err();
  const json stats = json::parse(vc.out());
  std::printf("vision_component stats: %s\n", stats.dump().c_str());
  EXPECT_GE(stats["frames_processed"].get<int>(), 2);
  EXPECT_GE(stats["frames_rejected"].get<int>(), 1);
  EXPECT_GE(stats["detect_requests"].get<int>(), 2);
}
