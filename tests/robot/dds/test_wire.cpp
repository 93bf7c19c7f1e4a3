// The wire contract with ROS 2 (rmw_cyclonedds): topic and type names, CDR layout, services.
// The other side is ros_probe (tests/robot/dds/ros_probe.c), a plain-C participant written from the
// ROS 2 message definitions alone that matches by type NAME (no type information) and decodes the
// CDR by hand; it runs as a separate process.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <sstream>

#include "common/noise_image.h"
#include "common/subprocess.h"
#include "common/temp_dir.h"
#include "dds_test_util.h"
#include "robot/dds/convert.h"
#include "robot/dds/service.h"
#include "robot/dds/transport.h"

using nlohmann::json;
using namespace refgrasp;
using namespace refgrasp::dds;
using refgrasp::testing::Subprocess;

namespace {

class Wire : public ::testing::Test {
 protected:
  void SetUp() override {
    refgrasp::testing::useLoopbackDds();
    domain_ = refgrasp::testing::privateDomain();
    ns_ = refgrasp::testing::privateNamespace("wire");
    dir_ = refgrasp::testing::tempDir("refgrasp_wire");
    pp_ = std::make_unique<Participant>(domain_);
  }

  /// Runs `ros_probe echo topic type` and publishes with `publish` until it printed one sample.
  json echo(const std::string& dds_topic, const std::string& type,
            const std::function<void()>& publish, double timeout_s = 10) {
    Subprocess p({refgrasp::testing::probePath(), "--domain", std::to_string(domain_), "echo",
                  dds_topic, type, "--count", "1", "--timeout", std::to_string(timeout_s)},
                 dir_, "echo");
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s + 1);
    while (p.running() && std::chrono::steady_clock::now() < end) {
      publish();
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    const int rc = p.wait(2);
    EXPECT_EQ(rc, 0) << "ros_probe echo " << dds_topic << " " << type << ": " << p.err();
    std::istringstream lines(p.out());
    std::string first;
    std::getline(lines, first);
    if (first.empty()) return json();
    json j = json::parse(first);
    EXPECT_EQ(j["encapsulation"], "CDR_LE") << first;  // XCDR1, little endian
    EXPECT_TRUE(j["ok"].get<bool>()) << "bytes did not decode exactly as ROS's definition: " << first;
    return j["msg"];
  }

  int domain_ = 0;
  std::string ns_;
  std::filesystem::path dir_;
  std::unique_ptr<Participant> pp_;
};

void expectHeader(const json& h, Seconds stamp, const std::string& frame) {
  const msg::Time t = toRosTime(stamp);
  EXPECT_EQ(h["stamp"]["sec"], t.sec);
  EXPECT_EQ(h["stamp"]["nanosec"], t.nanosec);
  EXPECT_EQ(h["frame_id"], frame);
}

void expectPose(const json& j, const Pose& p) {
  const msg::Pose r = toRosPose(p);
  EXPECT_DOUBLE_EQ(j["position"]["x"].get<double>(), r.position.x);
  EXPECT_DOUBLE_EQ(j["position"]["y"].get<double>(), r.position.y);
  EXPECT_DOUBLE_EQ(j["position"]["z"].get<double>(), r.position.z);
  EXPECT_DOUBLE_EQ(j["orientation"]["x"].get<double>(), r.orientation.x);
  EXPECT_DOUBLE_EQ(j["orientation"]["y"].get<double>(), r.orientation.y);
  EXPECT_DOUBLE_EQ(j["orientation"]["z"].get<double>(), r.orientation.z);
  EXPECT_DOUBLE_EQ(j["orientation"]["w"].get<double>(), r.orientation.w);
}

const Pose kPose = Pose::fromRotationVector({0.1, -0.2, 0.3}, {0.05, -0.02, 0.8});

}  // namespace

// The names rmw_cyclonedds gives ROS 2 types, literally (a ROS node matches on these strings).
TEST_F(Wire, TypeNamesAreTheOnesRos2NodesUse) {
  const std::pair<const char*, const char*> names[] = {
      {MessageType<msg::Image>::typeName(), "sensor_msgs::msg::dds_::Image_"},
      {MessageType<msg::CameraInfo>::typeName(), "sensor_msgs::msg::dds_::CameraInfo_"},
      {MessageType<msg::JointState>::typeName(), "sensor_msgs::msg::dds_::JointState_"},
      {MessageType<msg::PoseStamped>::typeName(), "geometry_msgs::msg::dds_::PoseStamped_"},
      {MessageType<msg::Twist>::typeName(), "geometry_msgs::msg::dds_::Twist_"},
      {MessageType<msg::Detection3DArray>::typeName(), "vision_msgs::msg::dds_::Detection3DArray_"},
      {MessageType<msg::Odometry>::typeName(), "nav_msgs::msg::dds_::Odometry_"},
      {MessageType<msg::JointTrajectory>::typeName(), "trajectory_msgs::msg::dds_::JointTrajectory_"},
      {MessageType<msg::ObjectInfo>::typeName(), "refgrasp_msgs::msg::dds_::ObjectInfo_"},
      {MessageType<msg::ObjectCorners>::typeName(), "refgrasp_msgs::msg::dds_::ObjectCorners_"},
      {MessageType<msg::DetectRequest>::typeName(), "refgrasp_msgs::srv::dds_::Detect_Request_"},
      {MessageType<msg::DetectResponse>::typeName(), "refgrasp_msgs::srv::dds_::Detect_Response_"},
  };
  for (const auto& [have, want] : names) EXPECT_STREQ(have, want);
  // And what a topic created from the descriptor reports at run time.
  Writer<msg::PoseStamped> w(*pp_, ddsTopicName(ns_ + "/object_pose"), QosProfile::reliable());
  char buf[256];
  const dds_entity_t topic = dds_get_topic(w.handle());
  ASSERT_GE(dds_get_type_name(topic, buf, sizeof buf), 0);
  EXPECT_STREQ(buf, "geometry_msgs::msg::dds_::PoseStamped_");
  ASSERT_GE(dds_get_name(topic, buf, sizeof buf), 0);
  EXPECT_EQ(std::string(buf), "rt" + ns_ + "/object_pose");
}

TEST(RosNames, TopicAndServiceNamesFollowRmwCyclonedds) {
  EXPECT_EQ(ddsTopicName("/refgrasp/image_raw"), "rt/refgrasp/image_raw");
  EXPECT_EQ(ddsRequestTopicName("/refgrasp/detect"), "rq/refgrasp/detectRequest");
  EXPECT_EQ(ddsReplyTopicName("/refgrasp/detect"), "rr/refgrasp/detectReply");
  EXPECT_EQ(joinRosName("/refgrasp", "image_raw"), "/refgrasp/image_raw");
  EXPECT_EQ(joinRosName("/", "image_raw"), "/image_raw");
  EXPECT_EQ(rosNameProblem("/refgrasp", true), "");
  EXPECT_EQ(rosNameProblem("/", true), "");
  EXPECT_EQ(rosNameProblem("/a/b_2/c"), "");
  EXPECT_NE(rosNameProblem("refgrasp", true), "");
  EXPECT_NE(rosNameProblem("/a//b"), "");
  EXPECT_NE(rosNameProblem("/a/"), "");
  EXPECT_NE(rosNameProblem("/a/2b"), "");
  EXPECT_NE(rosNameProblem("/a-b"), "");
  EXPECT_NE(rosNameProblem("/a__b"), "");
  EXPECT_NE(rosNameProblem(""), "");
}

// What `ros2 topic list -t` builds on: the DCPSPublication / DCPSSubscription built-in topics,
// read by an independent process.
TEST_F(Wire, DiscoveryShowsRosTopicAndTypeNames) {
  Writer<msg::PoseStamped> pose(*pp_, ddsTopicName(ns_ + "/object_pose"), QosProfile::reliable());
  Writer<msg::Detection3DArray> det(*pp_, ddsTopicName(ns_ + "/detections"), QosProfile::reliable());
  Writer<msg::ObjectInfo> info(*pp_, ddsTopicName(ns_ + "/object_info"), QosProfile::reliable());
  Reader<msg::Image> img(*pp_, ddsTopicName(ns_ + "/image_raw"), QosProfile::sensorData());
  Reader<msg::CameraInfo> cam(*pp_, ddsTopicName(ns_ + "/camera_info"), QosProfile::sensorData());
  ServiceServer<msg::DetectRequest, msg::DetectResponse> srv(*pp_, ns_ + "/detect");
  Subprocess p({refgrasp::testing::probePath(), "--domain", std::to_string(domain_), "list",
                "--wait", "2"},
               dir_, "list");
  ASSERT_EQ(p.wait(10), 0) << p.err();
  const std::string out = p.out();
  for (const std::string& line :
       {"pub rt" + ns_ + "/object_pose geometry_msgs::msg::dds_::PoseStamped_",
        "pub rt" + ns_ + "/detections vision_msgs::msg::dds_::Detection3DArray_",
        "pub rt" + ns_ + "/object_info refgrasp_msgs::msg::dds_::ObjectInfo_",
        "sub rt" + ns_ + "/image_raw sensor_msgs::msg::dds_::Image_",
        "sub rt" + ns_ + "/camera_info sensor_msgs::msg::dds_::CameraInfo_",
        "sub rq" + ns_ + "/detectRequest refgrasp_msgs::srv::dds_::Detect_Request_",
        "pub rr" + ns_ + "/detectReply refgrasp_msgs::srv::dds_::Detect_Response_"})
    EXPECT_NE(out.find(line + "\n"), std::string::npos) << "missing '" << line << "' in\n" << out;

  // The same from a DCPSPublication reader in this process (a second participant).
  Participant other(domain_);
  const dds_entity_t rd = dds_create_reader(other.handle(), DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr, nullptr);
  ASSERT_GT(rd, 0);
  std::string type_of_pose;
  refgrasp::testing::waitUntil(
      [&] {
        void* samples[32] = {nullptr};
        dds_sample_info_t infos[32];
        const int n = dds_take(rd, samples, infos, 32, 32);
        for (int i = 0; i < n; ++i) {
          const auto* e = static_cast<const dds_builtintopic_endpoint_t*>(samples[i]);
          if (infos[i].valid_data && std::string(e->topic_name) == "rt" + ns_ + "/object_pose")
            type_of_pose = e->type_name;
        }
        if (n > 0) dds_return_loan(rd, samples, n);
        return !type_of_pose.empty();
      },
      5);
  EXPECT_EQ(type_of_pose, "geometry_msgs::msg::dds_::PoseStamped_");
}

// A misspelt type name does not match: the probe really matches by name (the test can fail).
TEST_F(Wire, AWrongTypeNameDoesNotMatch) {
  Writer<msg::PoseStamped> w(*pp_, ddsTopicName(ns_ + "/object_pose"), QosProfile::reliable());
  Subprocess p({refgrasp::testing::probePath(), "--domain", std::to_string(domain_), "echo",
                "rt" + ns_ + "/object_pose", "geometry_msgs::msg::PoseStamped", "--count", "1",
                "--timeout", "1.5"},
               dir_, "wrong");
  const std::string frame = "cam";
  msg::PoseStamped m{};
  m.header = makeHeader(1.0, frame);
  while (p.running()) {
    w.write(m);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_EQ(p.wait(1), 1) << p.out();
  EXPECT_EQ(w.matched(), 0);
}

TEST_F(Wire, PoseStampedDecodesAsRos) {
  Writer<msg::PoseStamped> w(*pp_, ddsTopicName(ns_ + "/object_pose"), QosProfile::reliable());
  const std::string frame = "camera_optical_frame";
  msg::PoseStamped m{};
  m.header = makeHeader(12.345678901, frame);
  m.pose = toRosPose(kPose);
  const json j = echo("rt" + ns_ + "/object_pose", "geometry_msgs::msg::dds_::PoseStamped_",
                      [&] { w.write(m); });
  ASSERT_FALSE(j.is_null());
  expectHeader(j["header"], 12.345678901, frame);
  expectPose(j["pose"], kPose);
}

TEST_F(Wire, ImageAndCameraInfoDecodeAsRos) {
  std::mt19937_64 rng(211);
  const cv::Mat img = refgrasp::testing::noiseImage(rng, 64, 48);
  ImageOut out(img, 3.25, "left_optical");
  Writer<msg::Image> w(*pp_, ddsTopicName(ns_ + "/image_raw"), QosProfile::sensorData());
  const json j = echo("rt" + ns_ + "/image_raw", "sensor_msgs::msg::dds_::Image_",
                      [&] { w.write(out.msg()); });
  ASSERT_FALSE(j.is_null());
  expectHeader(j["header"], 3.25, "left_optical");
  EXPECT_EQ(j["height"], 48);
  EXPECT_EQ(j["width"], 64);
  EXPECT_EQ(j["encoding"], "mono8");
  EXPECT_EQ(j["is_bigendian"], 0);
  EXPECT_EQ(j["step"], 64);
  EXPECT_EQ(j["data_size"], 48 * 64);
  EXPECT_EQ(j["data_sum"].get<double>(), cv::sum(img)[0]);

  Intrinsics cam = Intrinsics::pinhole(640, 480, 550, 319.5, 239.5);
  cam.dist = {-0.1, 0.02, 0.001, -0.002, 0.003};
  CameraInfoOut ci(cam, 3.25, "right_optical", 0.12);
  Writer<msg::CameraInfo> wc(*pp_, ddsTopicName(ns_ + "/camera_info"), QosProfile::reliable(1));
  const json c = echo("rt" + ns_ + "/camera_info", "sensor_msgs::msg::dds_::CameraInfo_",
                      [&] { wc.write(ci.msg()); });
  ASSERT_FALSE(c.is_null());
  expectHeader(c["header"], 3.25, "right_optical");
  EXPECT_EQ(c["height"], 480);
  EXPECT_EQ(c["width"], 640);
  EXPECT_EQ(c["distortion_model"], "plumb_bob");
  EXPECT_EQ(c["d"], json({-0.1, 0.02, 0.001, -0.002, 0.003}));
  EXPECT_EQ(c["k"], json({550.0, 0.0, 319.5, 0.0, 550.0, 239.5, 0.0, 0.0, 1.0}));
  EXPECT_EQ(c["r"], json({1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0}));
  EXPECT_EQ(c["p"], json({550.0, 0.0, 319.5, -550.0 * 0.12, 0.0, 550.0, 239.5, 0.0, 0.0, 0.0, 1.0, 0.0}));
  EXPECT_EQ(c["binning_x"], 0);
  EXPECT_EQ(c["roi"]["width"], 0);
}

TEST_F(Wire, Detection3DArrayDecodesAsVisionMsgs4) {
  Writer<msg::Detection3DArray> w(*pp_, ddsTopicName(ns_ + "/detections"), QosProfile::reliable());
  const std::string frame = "cam", cls[2] = {"tea_box", "poster"}, id[2] = {"tea_box#0", "poster#0"};
  msg::ObjectHypothesisWithPose hyp[2]{};
  msg::Detection3D dets[2]{};
  for (int i = 0; i < 2; ++i) {
    hyp[i].hypothesis.class_id = const_cast<char*>(cls[i].c_str());
    hyp[i].hypothesis.score = 0.5 + i * 0.25;
    hyp[i].pose.pose = toRosPose(kPose);
    hyp[i].pose.covariance[7] = 0.01 * (i + 1);
    dets[i].header = makeHeader(5.5, frame);
    dets[i].results = {1, 1, &hyp[i], false};
    dets[i].bbox.center = toRosPose(kPose);
    dets[i].bbox.size = {0.2, 0.3 + i, 0.0};
    dets[i].id = const_cast<char*>(id[i].c_str());
  }
  msg::Detection3DArray m{};
  m.header = makeHeader(5.5, frame);
  m.detections = {2, 2, dets, false};
  const json j = echo("rt" + ns_ + "/detections", "vision_msgs::msg::dds_::Detection3DArray_",
                      [&] { w.write(m); });
  ASSERT_FALSE(j.is_null());
  expectHeader(j["header"], 5.5, frame);
  ASSERT_EQ(j["detections"].size(), 2u);
  for (int i = 0; i < 2; ++i) {
    const json& d = j["detections"][i];
    expectHeader(d["header"], 5.5, frame);
    ASSERT_EQ(d["results"].size(), 1u);
    EXPECT_EQ(d["results"][0]["hypothesis"]["class_id"], cls[i]);
    EXPECT_DOUBLE_EQ(d["results"][0]["hypothesis"]["score"].get<double>(), 0.5 + i * 0.25);
    expectPose(d["results"][0]["pose"]["pose"], kPose);
    EXPECT_DOUBLE_EQ(d["results"][0]["pose"]["covariance"][7].get<double>(), 0.01 * (i + 1));
    expectPose(d["bbox"]["center"], kPose);
    EXPECT_DOUBLE_EQ(d["bbox"]["size"]["y"].get<double>(), 0.3 + i);
    EXPECT_EQ(d["id"], id[i]);
  }
}

TEST_F(Wire, ObjectInfoDecodesAsItsMsgFile) {
  Writer<msg::ObjectInfo> w(*pp_, ddsTopicName(ns_ + "/object_info"), QosProfile::reliable());
  const std::string frame = "cam", name = "cereal_box";
  msg::ObjectInfo m{};
  m.header = makeHeader(7.0, frame);
  m.object_name = const_cast<char*>(name.c_str());
  m.found = true;
  for (int i = 0; i < 9; ++i) m.rotation[i] = kPose.R(i / 3, i % 3);
  for (int i = 0; i < 3; ++i) m.translation[i] = kPose.t[i];
  m.inliers = 42;
  const json j = echo("rt" + ns_ + "/object_info", "refgrasp_msgs::msg::dds_::ObjectInfo_",
                      [&] { w.write(m); });
  ASSERT_FALSE(j.is_null());
  expectHeader(j["header"], 7.0, frame);
  EXPECT_EQ(j["object_name"], name);
  EXPECT_EQ(j["found"], true);
  for (int i = 0; i < 9; ++i) EXPECT_DOUBLE_EQ(j["rotation"][i].get<double>(), kPose.R(i / 3, i % 3));
  for (int i = 0; i < 3; ++i) EXPECT_DOUBLE_EQ(j["translation"][i].get<double>(), kPose.t[i]);
  EXPECT_EQ(j["inliers"], 42);
}

TEST_F(Wire, ObjectCornersDecodesAsItsMsgFile) {
  Writer<msg::ObjectCorners> w(*pp_, ddsTopicName(ns_ + "/object_corners"), QosProfile::reliable());
  const std::string frame = "cam", name = "poster";
  msg::ObjectCorners m{};
  m.header = makeHeader(8.5, frame);
  m.object_name = const_cast<char*>(name.c_str());
  m.found = true;
  m.tracked = true;
  for (int i = 0; i < 8; ++i) m.corners[i] = 10.25 * i - 3.5;
  for (int i = 0; i < 9; ++i) m.homography[i] = 0.5 * i + 0.125;
  m.inliers = 77;
  const json j = echo("rt" + ns_ + "/object_corners", "refgrasp_msgs::msg::dds_::ObjectCorners_",
                      [&] { w.write(m); });
  ASSERT_FALSE(j.is_null());
  expectHeader(j["header"], 8.5, frame);
  EXPECT_EQ(j["object_name"], name);
  EXPECT_EQ(j["found"], true);
  EXPECT_EQ(j["tracked"], true);
  for (int i = 0; i < 8; ++i) EXPECT_DOUBLE_EQ(j["corners"][i].get<double>(), 10.25 * i - 3.5);
  for (int i = 0; i < 9; ++i) EXPECT_DOUBLE_EQ(j["homography"][i].get<double>(), 0.5 * i + 0.125);
  EXPECT_EQ(j["inliers"], 77);
}

TEST_F(Wire, RobotMessagesDecodeAsRos) {
  Writer<msg::JointState> wj(*pp_, ddsTopicName(ns_ + "/joint_states"), QosProfile::reliable());
  JointStateOut js(2.5);
  js.add("head_pan", 0.1, -0.2);
  js.add("gripper", 1.0, 0.0, 0.5);
  const json j = echo("rt" + ns_ + "/joint_states", "sensor_msgs::msg::dds_::JointState_",
                      [&] { wj.write(js.msg()); });
  ASSERT_FALSE(j.is_null());
  EXPECT_EQ(j["name"], json({"head_pan", "gripper"}));
  EXPECT_EQ(j["position"], json({0.1, 1.0}));
  EXPECT_EQ(j["velocity"], json({-0.2, 0.0}));
  EXPECT_EQ(j["effort"], json({0.0, 0.5}));

  Writer<msg::Odometry> wo(*pp_, ddsTopicName(ns_ + "/odom"), QosProfile::reliable());
  const std::string odom = "odom", base = "base_link";
  msg::Odometry od{};
  od.header = makeHeader(2.5, odom);
  od.child_frame_id = const_cast<char*>(base.c_str());
  od.pose.pose = toRosPose(kPose);
  od.pose.covariance[35] = 0.25;
  od.twist.twist.linear.x = 0.3;
  od.twist.twist.angular.z = -0.4;
  const json o = echo("rt" + ns_ + "/odom", "nav_msgs::msg::dds_::Odometry_", [&] { wo.write(od); });
  ASSERT_FALSE(o.is_null());
  expectHeader(o["header"], 2.5, odom);
  EXPECT_EQ(o["child_frame_id"], base);
  expectPose(o["pose"]["pose"], kPose);
  EXPECT_DOUBLE_EQ(o["pose"]["covariance"][35].get<double>(), 0.25);
  EXPECT_DOUBLE_EQ(o["twist"]["twist"]["linear"]["x"].get<double>(), 0.3);
  EXPECT_DOUBLE_EQ(o["twist"]["twist"]["angular"]["z"].get<double>(), -0.4);

  Writer<msg::Twist> wt(*pp_, ddsTopicName(ns_ + "/cmd_vel"), QosProfile::reliable(1));
  msg::Twist tw{};
  tw.linear.x = 0.2;
  tw.angular.z = 0.7;
  const json t = echo("rt" + ns_ + "/cmd_vel", "geometry_msgs::msg::dds_::Twist_", [&] { wt.write(tw); });
  ASSERT_FALSE(t.is_null());
  EXPECT_DOUBLE_EQ(t["linear"]["x"].get<double>(), 0.2);
  EXPECT_DOUBLE_EQ(t["angular"]["z"].get<double>(), 0.7);

  Writer<msg::JointTrajectory> wa(*pp_, ddsTopicName(ns_ + "/arm/command"), QosProfile::reliable(1));
  TrajectoryOut tr(2.5, {"shoulder_pitch", "elbow_pitch"}, TrajectoryOut::Kind::kVelocities,
                   {0.25, -0.5}, 0.2);
  const json a = echo("rt" + ns_ + "/arm/command", "trajectory_msgs::msg::dds_::JointTrajectory_",
                      [&] { wa.write(tr.msg()); });
  ASSERT_FALSE(a.is_null());
  EXPECT_EQ(a["joint_names"], json({"shoulder_pitch", "elbow_pitch"}));
  ASSERT_EQ(a["points"].size(), 1u);
  EXPECT_EQ(a["points"][0]["positions"], json::array());
  EXPECT_EQ(a["points"][0]["velocities"], json({0.25, -0.5}));
  EXPECT_EQ(a["points"][0]["time_from_start"]["sec"], 0);
  EXPECT_EQ(a["points"][0]["time_from_start"]["nanosec"], 200000000);
}

// rmw_cyclonedds' request header: guid = the client's writer instance handle, seq from 1.
TEST_F(Wire, ServiceRequestsCarryTheRmwCycloneddsHeader) {
  ServiceClient<msg::DetectRequest, msg::DetectResponse> client(*pp_, ns_ + "/detect");
  const std::string name = "tea_box";
  Subprocess p({refgrasp::testing::probePath(), "--domain", std::to_string(domain_), "echo",
                "rq" + ns_ + "/detectRequest", "refgrasp_msgs::srv::dds_::Detect_Request_",
                "--count", "3", "--timeout", "8"},
               dir_, "req");
  // The probe's reader matching is all this needs (no server: replies are not expected).
  int64_t last = 0;
  while (p.running() && last < 100) {
    msg::DetectRequest r{};
    r.object_name = const_cast<char*>(name.c_str());
    r.timeout_s = 0.5;
    last = client.send(r);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_EQ(p.wait(2), 0) << p.err();
  std::istringstream lines(p.out());
  std::string line;
  int64_t prev = 0;
  int n = 0;
  while (std::getline(lines, line)) {
    const json j = json::parse(line);
    ASSERT_TRUE(j["ok"].get<bool>()) << line;
    EXPECT_EQ(j["msg"]["request_header"]["guid"].get<uint64_t>(), client.guid());
    const int64_t seq = j["msg"]["request_header"]["seq"].get<int64_t>();
    EXPECT_GT(seq, prev);
    prev = seq;
    EXPECT_EQ(j["msg"]["object_name"], name);
    EXPECT_DOUBLE_EQ(j["msg"]["timeout_s"].get<double>(), 0.5);
    ++n;
  }
  EXPECT_EQ(n, 3);
  EXPECT_NE(client.guid(), 0u);
}

// A client built like rmw_cyclonedds' (the probe) gets the reply with its own header back.
TEST_F(Wire, ServiceRepliesCopyTheRequestHeader) {
  ServiceServer<msg::DetectRequest, msg::DetectResponse> srv(*pp_, ns_ + "/detect");
  Subprocess p({refgrasp::testing::probePath(), "--domain", std::to_string(domain_), "call",
                ns_ + "/detect", "poster", "0.25", "--wait", "8"},
               dir_, "call");
  uint64_t guid = 0;
  int64_t seq = 0;
  std::string object;
  double timeout = 0;
  const std::string error = "unknown object 'poster'";
  while (p.running()) {
    for (auto& in : srv.take()) {
      guid = in.request->header.guid;
      seq = in.request->header.seq;
      object = in.request->object_name;
      timeout = in.request->timeout_s;
      msg::DetectResponse rep{};
      rep.found = false;
      rep.translation[2] = 1.5;
      rep.error = const_cast<char*>(error.c_str());
      EXPECT_TRUE(srv.reply(in, rep));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_EQ(p.wait(2), 0) << p.err();
  EXPECT_EQ(object, "poster");
  EXPECT_DOUBLE_EQ(timeout, 0.25);
  EXPECT_EQ(seq, 1);
  EXPECT_NE(guid, 0u);
  const json j = json::parse(p.out());
  ASSERT_TRUE(j["ok"].get<bool>()) << p.out();
  EXPECT_EQ(j["msg"]["request_header"]["guid"].get<uint64_t>(), guid);
  EXPECT_EQ(j["msg"]["request_header"]["seq"], 1);
  EXPECT_EQ(j["msg"]["found"], false);
  EXPECT_DOUBLE_EQ(j["msg"]["translation"][2].get<double>(), 1.5);
  EXPECT_EQ(j["msg"]["error"], error);
}

// Our client against our server: seq counts from 1, replies to other requests are ignored.
TEST_F(Wire, ClientMatchesRepliesBySeq) {
  ServiceServer<msg::DetectRequest, msg::DetectResponse> srv(*pp_, ns_ + "/detect");
  Participant other(domain_);
  ServiceClient<msg::DetectRequest, msg::DetectResponse> client(other, ns_ + "/detect");
  ASSERT_TRUE(client.waitForService(5));
  std::atomic<bool> stop{false};
  std::thread server([&] {
    while (!stop) {
      for (auto& in : srv.take()) {
        msg::DetectResponse rep{};
        rep.found = in.request->header.seq % 2 == 0;
        rep.error = const_cast<char*>("");
        srv.reply(in, rep);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  });
  for (int64_t k = 1; k <= 3; ++k) {
    msg::DetectRequest r{};
    r.object_name = const_cast<char*>("x");
    auto rep = client.call(r, 5);
    ASSERT_TRUE(rep.has_value());
    EXPECT_EQ((*rep)->header.seq, k);
    EXPECT_EQ((*rep)->header.guid, client.guid());
    EXPECT_EQ((*rep)->found, k % 2 == 0);
  }
  stop = true;
  server.join();
}

// The other direction: an image written by the ROS-like probe (hand-made CDR) decodes here.
TEST_F(Wire, ImagesFromARosPublisherDecode) {
  std::mt19937_64 rng(468);
  const cv::Mat gray = refgrasp::testing::noiseImage(rng, 60, 40);
  const std::string pgm = (dir_ / "probe.pgm").string();
  cv::imwrite(pgm, gray);
  for (const std::string enc : {"mono8", "bgr8"}) {
    Reader<msg::Image> img(*pp_, ddsTopicName(ns_ + "/" + enc + "/image_raw"), QosProfile::sensorData());
    Reader<msg::CameraInfo> info(*pp_, ddsTopicName(ns_ + "/" + enc + "/camera_info"),
                                 QosProfile::sensorData());
    Subprocess p({refgrasp::testing::probePath(), "--domain", std::to_string(domain_), "pub-image",
                  ns_ + "/" + enc, pgm, enc, "--count", "20", "--rate", "20", "--f", "300"},
                 dir_, "pubimg");
    Sample<msg::Image> s;
    Sample<msg::CameraInfo> c;
    ASSERT_TRUE(refgrasp::testing::waitUntil([&] { return img.takeNewest(&s) > 0; }, 10)) << p.err();
    ASSERT_TRUE(refgrasp::testing::waitUntil([&] { return info.takeNewest(&c) > 0 || c->width > 0; }, 5));
    const GrayImage g = toGray(*s);
    ASSERT_TRUE(g.ok()) << g.error;
    EXPECT_EQ(cv::norm(g.gray, gray, cv::NORM_INF), 0) << enc;
    EXPECT_EQ(std::string(s->header.frame_id), "camera_optical_frame");
    std::string err;
    const auto cam = toIntrinsics(*c, &err);
    ASSERT_TRUE(cam.has_value()) << err;
    EXPECT_EQ(cam->width, 60);
    EXPECT_DOUBLE_EQ(cam->fx, 300);
    EXPECT_DOUBLE_EQ(cam->cx, 29.5);
    p.wait(5);
  }
}
