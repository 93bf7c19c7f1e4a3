// Stereo rendering throughput: table_clutter.yaml through the BB2 rig (lens distortion on), with the
// scenario's degradations and motion blur from a moving camera. Target: faster than 48 stereo fps.
// Then the cost of enon_grasp's two other video panels per video frame: the external view (the
// world and the robot from the follow camera) and the top-down map (with a belief grid, looks
// and a path, as a long search draws it).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <cstdio>
#include <vector>

#include "bench_util.h"
#include "grasp/grasp_map.h"
#include "robot/enon_model.h"
#include "robot/sim/robot_view.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"
#include "robot/sim/synthetic_camera.h"

using namespace refgrasp;

namespace {

using bench::median;

struct Cost {
  double wall_ms, cpu_ms;  ///< medians: wall clock, CPU time of the process
};

// Median cost of f(k) over `frames` calls after `warmup` calls.
template <class F>
Cost medianCost(int frames, int warmup, F&& f) {
  std::vector<double> ms, cpu_ms;
  for (int k = 0; k < frames + warmup; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::clock_t c0 = std::clock();
    f(k);
    const std::clock_t c1 = std::clock();
    const auto t1 = std::chrono::steady_clock::now();
    if (k < warmup) continue;
    ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    cpu_ms.push_back(1000.0 * static_cast<double>(c1 - c0) / CLOCKS_PER_SEC);
  }
  return {median(ms), median(cpu_ms)};
}

// The external view and the map panel on table_clutter, the robot at its start with the arm
// raised towards the table (its parts in view), the follow camera turning with the base.
void outsidePanels(const sim::Scenario& s, int frames, int warmup) {
  const std::string src = REFGRASP_SOURCE_DIR;
  const robot::EnonModel model = robot::loadEnonModel(src + "/config/enon.yaml");
  sim::SimEnon enon(model, s);
  Eigen::VectorXd q(model.arm.dof());
  q.setZero();
  q.head(std::min<Eigen::Index>(q.size(), 4)) << 1.2, 0.2, 0.0, 0.9;
  enon.setJointPositions(q);
  const std::vector<sim::RobotPart> parts = sim::robotParts(model, enon.shapes(), enon.wMb(), enon.wMc());
  sim::FollowCamera follow;
  const robot::PlanarPose b = enon.trueBasePose();
  const Cost ext = medianCost(frames, warmup, [&](int k) {
    const Pose wMc = follow.update({b.x_m, b.y_m, b.theta_rad + 0.01 * k}, 0.02 * k);
    const cv::Mat img = sim::renderExternalView(follow.options().camera, enon.world(), wMc, parts);
    if (img.empty()) std::abort();
  });
  const Cost parts_only = medianCost(frames, warmup, [&](int k) {
    const Pose wMc = follow.update({b.x_m, b.y_m, b.theta_rad + 0.01 * k}, 0.02 * k);
    cv::Mat img(480, 640, CV_8UC3, cv::Scalar(128, 128, 128)), inv_depth(480, 640, CV_32F, cv::Scalar(0));
    sim::drawRobotParts(img, inv_depth, follow.options().camera.K(), wMc, parts, sim::viewLight(wMc));
  });

  // A belief over the whole room (50 x 50 cells of 0.2 m, all non-zero), 12 looks, 500 path points.
  const grasp_app::TopDownMap map(enon.world(), robot::PlanarPose{});
  servo::SearchBelief belief;
  belief.origin = Eigen::Vector2d(-3.5, -4.5);
  belief.cols = belief.rows = 50;
  for (int i = 0; i < 2500; ++i) belief.p.push_back(1e-4f * static_cast<float>(1 + i % 97));
  grasp_app::MapFrame f;
  f.base_w = b;
  f.belief = &belief;
  for (int i = 0; i < 12; ++i) {
    servo::SearchLook l;
    l.index = i + 1;
    l.bearing_rad = 0.5 * i;
    l.half_fov_rad = 0.57;
    l.range_m = 3;
    f.looks.push_back(l);
  }
  for (int i = 0; i < 500; ++i) f.path_w.emplace_back(0.004 * i, std::sin(0.01 * i));
  const Cost map_ms = medianCost(frames, warmup, [&](int) {
    if (map.draw(enon.world(), f).empty()) std::abort();
  });
  std::printf("\nenon_grasp --video panels (640x480 each, table_clutter, medians of %d frames after %d warm-up;\n"
              "one thread each)%*s %9s %9s\n",
              frames, warmup, 21, "", "wall", "CPU");
  const auto row = [](const char* name, const Cost& c) { std::printf("%-58s %7.2fms %7.2fms\n", name, c.wall_ms, c.cpu_ms); };
  row("external view: world + robot (follow camera)", ext);
  row("  of which the robot's 8 parts alone (ray cast)", parts_only);
  row("map panel: room, belief 50x50, 12 looks, 500-point path", map_ms);
}

}  // namespace

int main() try {
  const std::string src = REFGRASP_SOURCE_DIR;
  const sim::Scenario s = sim::loadScenario(src + "/config/scenarios/table_clutter.yaml");
  const StereoRig rig = loadStereoRig(src + "/config/cameras/bb2_rig.yaml");
  Eigen::Matrix3d optical;  // camera z forward along world x, x right, y down
  optical << 0, 0, 1, -1, 0, 0, 0, -1, 0;

  struct Case {
    const char* name;
    sim::Degradation deg;
    Twist velocity;
  };
  sim::Degradation none;
  none.noise_sigma = 0;
  const std::vector<Case> cases = {
      {"scenario degradations, camera moving", s.camera, Twist{{0.3, 0, 0.2}, {0, 0.4, 0}}},
      {"scenario degradations, camera still", s.camera, Twist()},
      {"no degradation, camera still", none, Twist()},
  };
  constexpr int kFrames = 60, kWarmup = 3;
  std::printf("%-40s %9s %9s %9s %10s %12s\n", "case (640x480 stereo, table_clutter)", "median", "min",
              "max", "stereo fps", "CPU/frame");
  for (const Case& c : cases) {
    sim::SyntheticStereoCamera cam(rig, c.deg, s.seed, s.exposure_s);
    std::vector<double> ms, cpu_ms;  // wall clock; CPU time of all threads
    for (int k = 0; k < kFrames + kWarmup; ++k) {
      const double t = 0.02 * k;
      const Pose wMl(axisAngle(Eigen::Vector3d::UnitZ(), 0.2 * std::sin(t)) * optical *
                         axisAngle(Eigen::Vector3d::UnitX(), -0.3),
                     {0.3 * t, 0.1 * std::sin(t), 1.2});
      const auto t0 = std::chrono::steady_clock::now();
      const std::clock_t c0 = std::clock();
      const sim::SyntheticFrame f = cam.render(s.world, wMl, c.velocity, t);
      const std::clock_t c1 = std::clock();
      const auto t1 = std::chrono::steady_clock::now();
      if (f.left.empty() || f.right.empty()) return 1;
      if (k < kWarmup) continue;
      ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
      cpu_ms.push_back(1000.0 * static_cast<double>(c1 - c0) / CLOCKS_PER_SEC);
    }
    const double med = median(ms);
    std::printf("%-40s %7.2fms %7.2fms %7.2fms %10.1f %10.2fms\n", c.name, med,
                *std::min_element(ms.begin(), ms.end()), *std::max_element(ms.begin(), ms.end()),
                1000.0 / med, median(cpu_ms));
  }
  std::printf("(medians of %d frames per case after %d warm-up frames; the eyes render on two threads;\n"
              " target: > 48 stereo fps)\n", kFrames, kWarmup);
  outsidePanels(s, kFrames, kWarmup);
  return 0;
}
catch (const std::exception& e) {  // a missing or unreadable input: one line, not an abort
  std::fprintf(stderr, "bench_render: %s\n", e.what());
  return 1;
}
