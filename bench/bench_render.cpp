// Stereo rendering throughput: table_clutter.yaml through the BB2 rig (lens distortion on), with the
// scenario's degradations and motion blur from a moving camera. Target: faster than 48 stereo fps.
#include <algorithm>
#include <chrono>
#include <ctime>
#include <cstdio>
#include <vector>

#include "robot/sim/scenario.h"
#include "bench_util.h"
#include "robot/sim/synthetic_camera.h"

using namespace refgrasp;

namespace {

using bench::median;

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
  return 0;
}
catch (const std::exception& e) {  // a missing or unreadable input: one line, not an abort
  std::fprintf(stderr, "bench_render: %s\n", e.what());
  return 1;
}
