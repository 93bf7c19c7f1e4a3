// The robot and the vision component, each its own process, talking over the bus as on the real
// enon: sim_robot_node serves the simulated enon's stereo camera, vision_component --stereo
// subscribes to it, and this test (the controller, on the "dds" backend) turns the head towards
// the cereal box. The fused pose on object_info is checked against the simulator's ground truth.
#include <gtest/gtest.h>

#include <csignal>
#include <fstream>
#include <nlohmann/json.hpp>

#include "common/subprocess.h"
#include "common/temp_dir.h"
#include "component_test_util.h"
#include "robot/dds/dds_robot.h"
#include "robot/dds/dds_test_util.h"
#include "robot/kinematics.h"

using nlohmann::json;
using namespace refgrasp;
using namespace refgrasp::testing;
using robot::ReturnType;

namespace {
const std::string kSource = REFGRASP_SOURCE_DIR;
double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
Pose poseFrom(const json& j) {
  const auto& t = j["translation"];
  const auto& r = j["rotation_vector"];
  return Pose::fromRotationVector({r[0].get<double>(), r[1].get<double>(), r[2].get<double>()},
                                  {t[0].get<double>(), t[1].get<double>(), t[2].get<double>()});
}
}  // namespace

TEST(RobotVision, StereoComponentOnTheSimulatedRobotsCamera) {
  useLoopbackDds();
  const int domain = privateDomain();
  const std::string ns = privateNamespace("enon");
  const auto dir = tempDir("refgrasp_robot_vision");
  const auto result = dir / "result.json";
  Subprocess node({std::string(REFGRASP_APP_DIR) + "/sim_robot_node", "--scenario",
                   kSource + "/config/scenarios/table_single.yaml", "--enon", kSource + "/config/enon.yaml",
                   "--ns", ns, "--domain", std::to_string(domain), "--camera-rate", "8", "--result",
                   result.string()},
                  dir, "node");
  Subprocess vc({std::string(REFGRASP_APP_DIR) + "/vision_component", "--object",
                 kSource + "/config/objects/cereal_box.yaml", "--stereo", kSource + "/config/cameras/bb2_rig.yaml",
                 "--ns", ns, "--domain", std::to_string(domain)},
                dir, "vc");

  robot::EnonModel model = robot::loadEnonModel(kSource + "/config/enon.yaml");
  model.watchdog_period_s = 1.0;  // this controller is a test on a loaded machine, not the point
  dds::DdsRobotOptions o;
  o.domain = domain;
  o.ns = ns;
  o.connect_timeout_s = 30;
  auto r = dds::makeDdsRobot(model, o);
  ASSERT_EQ(r->configure(), ReturnType::kOk);
  ASSERT_EQ(r->activate(), ReturnType::kOk) << node.err();
  dds::Participant pp(domain);
  InfoListener infos(pp, ns);

  // The box is 40 deg to the left, below the eyes: look at it, hold still, take a result.
  const double pan = 0.70, tilt = 0.20;
  double last = now(), settled = -1;
  std::optional<InfoListener::Info> found;
  size_t seen_at_settle = 0;
  const double t0 = now();
  while (now() - t0 < 90 && !found) {
    const double t = now();
    ASSERT_EQ(r->read(t, t - last), ReturnType::kOk);
    last = t;
    r->head().setPosition(pan, tilt);
    ASSERT_EQ(r->write(t, t - last), ReturnType::kOk);
    if (settled < 0 && std::abs(r->state().pan_rad - pan) < 1e-6 && std::abs(r->state().tilt_rad - tilt) < 1e-6)
      settled = t;
    // Frames captured while the head moved may still be in the detector: wait, then take the
    // first found result that arrives after.
    if (settled > 0 && t - settled > 2.0) {
      if (seen_at_settle == 0) seen_at_settle = infos.count() + 1;
      infos.poll();
      if (infos.count() > seen_at_settle) {
        const auto s = infos.waitFor(static_cast<double>(infos.lastStamp()) * 1e-9, "cereal_box", 0.1);
        if (s && s->found) found = s;
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  const robot::RobotState state = r->state();
  r->deactivate();
  vc.signal(SIGINT);
  node.signal(SIGTERM);
  ASSERT_EQ(vc.wait(20), 0) << vc.err();
  ASSERT_EQ(node.wait(20), 0) << node.err();
  ASSERT_TRUE(found.has_value()) << "the component never found the box\n" << vc.err() << vc.out();
  EXPECT_EQ(found->frame, "left_camera_optical_frame");

  std::ifstream in(result);
  const json truth = json::parse(in);
  Pose wMo;
  for (const auto& ob : truth["objects"])
    if (ob["name"] == "cereal_box") wMo = poseFrom(ob["wMo"]);
  const auto& b = truth["base_true"];
  const Pose wMb = robot::PlanarPose{b["x_m"].get<double>(), b["y_m"].get<double>(), b["theta_rad"].get<double>()}.toPose();
  const Pose lMo_true = (wMb * robot::headCameraPose(model.head, state.pan_rad, state.tilt_rad)).inverse() * wMo;
  const double dist = lMo_true.t.norm();
  std::printf("box at %.2f m: fused pose error %.1f mm, %.2f deg; component %s\n", dist,
              translationError(found->cMo, lMo_true) * 1e3, rotationError(found->cMo, lMo_true) * 180 / M_PI,
              vc.out().c_str());
  EXPECT_GT(dist, 1.5);
  EXPECT_LT(translationError(found->cMo, lMo_true), 0.01 * dist);
  EXPECT_LT(rotationError(found->cMo, lMo_true), 1.0 * M_PI / 180);
}
