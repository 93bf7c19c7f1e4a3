// The grasp controller's control step (servo::GraspController::step: tracking + servo) on the
// simulated enon with vision, per kind of step, against the 48 fps camera period (20.8 ms).
// The simulator's own work inside a step (integrating the robot in read(), rendering the stereo
// pair in grab()) is timed by wrappers around the backend and subtracted: what is left is what
// the controller costs on a robot. Wall clock and the calling thread's CPU time (the figure that
// holds on a shared machine), medians over the steps of whole grasps on several scenarios.
//   build/bench/bench_grasp_step [--runs N]   (N grasps per scenario, default 1)
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <vector>

#include "bench_util.h"
#include "detector/detector.h"
#include "detector/object.h"
#include "robot/enon_model.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"
#include "servo/grasp_controller.h"
#include "servo/vision_estimator.h"

using namespace refgrasp;
using bench::median;

namespace {

struct Cost {
  double wall_ms = 0, cpu_ms = 0;
};

double threadCpuNowMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}
double wallNowMs() {
  return std::chrono::duration<double, std::milli>(bench::Clock::now().time_since_epoch()).count();
}

/// Adds the time spent inside the wrapped call to `cost`.
template <class F>
auto timed(Cost* cost, F&& f) {
  const double w = wallNowMs(), c = threadCpuNowMs();
  auto r = f();
  cost->wall_ms += wallNowMs() - w;
  cost->cpu_ms += threadCpuNowMs() - c;
  return r;
}

struct TimedHardware : robot::RobotHardware {
  std::unique_ptr<sim::SimEnon> inner;
  Cost* cost = nullptr;
  robot::ReturnType configure() override { return inner->configure(); }
  robot::ReturnType activate() override { return inner->activate(); }
  robot::ReturnType deactivate() override { return inner->deactivate(); }
  robot::ReturnType read(Seconds t, Seconds p, robot::RobotState* s) override {
    return timed(cost, [&] { return inner->read(t, p, s); });
  }
  robot::ReturnType write(Seconds t, Seconds p, const robot::RobotCommand& c, Seconds v) override {
    return timed(cost, [&] { return inner->write(t, p, c, v); });
  }
};

struct TimedCamera : robot::StereoSource {
  std::unique_ptr<robot::StereoSource> inner;
  Cost* cost = nullptr;
  const StereoRig& rig() const override { return inner->rig(); }
  robot::ReturnType grab(Seconds t, std::optional<robot::StereoFrame>* f) override {
    return timed(cost, [&] { return inner->grab(t, f); });
  }
};

struct Samples {
  std::vector<double> wall, cpu;
};

}  // namespace

int main(int argc, char** argv) try {
  int runs = 1;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--runs") == 0 && i + 1 < argc) {
      runs = static_cast<int>(bench::intArg("bench_grasp_step", "--runs", argv[++i], 1));
    } else {
      std::fprintf(stderr, "usage: bench_grasp_step [--runs N]\n");
      return 2;
    }
  }
  const std::string src = REFGRASP_SOURCE_DIR;
  const robot::EnonModel model = robot::loadEnonModel(src + "/config/enon.yaml");
  std::map<std::string, Samples> by_kind;
  int grasps = 0, attempts = 0;
  for (const char* name : {"table_single", "table_clutter", "faults"}) {
    for (int run = 0; run < runs; ++run) {
      sim::Scenario sc = sim::loadScenario(src + "/config/scenarios/" + name + ".yaml");
      sc.seed += static_cast<uint64_t>(run);
      int target = -1;
      for (size_t i = 0; i < sc.world.objects.size(); ++i)
        if (sc.world.objects[i].is_target) target = static_cast<int>(i);
      const sim::SimObject& obj = sc.world.objects[static_cast<size_t>(target)];
      const detector::ObjectModel object = detector::loadObjectDefinition(obj.definition);
      detector::Detector det;
      const int id = det.addObject(object);
      servo::VisionEstimator est(det, id);
      Cost backend;
      auto hw = std::make_unique<TimedHardware>();
      hw->inner = std::make_unique<sim::SimEnon>(model, sc);
      hw->cost = &backend;
      auto cam = std::make_unique<TimedCamera>();
      cam->inner = hw->inner->makeCamera();
      cam->cost = &backend;
      robot::Robot robot(model, std::move(hw), std::move(cam));
      robot.configure();
      robot.activate();
      servo::GraspController ctl(robot, est, obj.oMg, servo::objectExtent(object));
      const double dt = model.control_period_s;
      ++attempts;
      for (double t = 0; t < 90 && !ctl.finished(); t += dt) {
        backend = Cost();
        const double w0 = wallNowMs(), c0 = threadCpuNowMs();
        const servo::GraspStep s = ctl.step(t, dt);
        const double wall = wallNowMs() - w0 - backend.wall_ms;
        const double cpu = threadCpuNowMs() - c0 - backend.cpu_ms;
        std::string kind = "no frame";
        if (s.it.frame) {
          const servo::TargetFrame& f = est.last();
          const servo::TargetState* o = f.find(id);
          kind = f.detector_calls > 0 ? "frame, detector ran"
                                      : (o && o->mode == servo::TrackMode::kTrack ? "frame, tracked"
                                                                                  : "frame, other");
          by_kind["every frame"].wall.push_back(wall);
          by_kind["every frame"].cpu.push_back(cpu);
        }
        by_kind[kind].wall.push_back(wall);
        by_kind[kind].cpu.push_back(cpu);
        by_kind["every step"].wall.push_back(wall);
        by_kind["every step"].cpu.push_back(cpu);
      }
      grasps += ctl.report().success;
    }
  }
  std::printf("grasp controller step (tracking + servo, simulator excluded), %d/%d grasps,\n"
              "table_single, table_clutter, faults:\n", grasps, attempts);
  std::printf("%-22s %7s %12s %12s %12s %12s\n", "steps", "count", "wall median", "wall p95",
              "CPU median", "CPU p95");
  for (const auto& [kind, s] : by_kind) {
    std::vector<double> w = s.wall, c = s.cpu;
    std::sort(w.begin(), w.end());
    std::sort(c.begin(), c.end());
    const auto p95 = [](const std::vector<double>& v) { return v[static_cast<size_t>(0.95 * (v.size() - 1))]; };
    std::printf("%-22s %7zu %10.2fms %10.2fms %10.2fms %10.2fms\n", kind.c_str(), s.wall.size(),
                median(w), p95(w), median(c), p95(c));
  }
  std::printf("(camera period at 48 fps: 20.83 ms; control period %.0f ms; frames are looked at\n"
              " every %.0f ms at most; the detector runs when nothing is tracked: the search's\n"
              " looks, confirmations and re-detections)\n",
              1e3 * model.control_period_s, 1e3 * servo::GraspOptions().frame_period_s);
  return 0;
}
catch (const std::exception& e) {  // a missing or unreadable input: one line, not an abort
  std::fprintf(stderr, "bench_grasp_step: %s\n", e.what());
  return 1;
}
