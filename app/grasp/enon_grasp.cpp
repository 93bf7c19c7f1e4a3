#include "grasp/enon_grasp.h"

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <csignal>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <thread>

#include "core/error.h"
#include "core/json.h"
#include "detector/detector.h"
#include "detector/detector_config.h"
#include "detector/object.h"
#include "grasp/grasp_log.h"
#include "robot/backend.h"
#include "robot/backends.h"
#include "robot/enon_model.h"
#include "robot/sources.h"
#include "grasp/room_map.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"
#include "tool/tool.h"
#include "servo/target_estimator.h"
#include "servo/vision_estimator.h"

namespace refgrasp::grasp_app {

namespace {

constexpr const char* kPhaseOrder[] = {"search", "approach", "align", "grasp"};

/// x to `decimals` places, as the double nearest that decimal (prints as "15.54", not
/// "15.540000000000001").
double rounded(double x, int decimals) {
  const double scale = std::pow(10.0, decimals);
  return std::round(x * scale) / scale;
}

std::string summaryLine(const EnonGraspResult& r) {
  Json phases = Json::object();
  for (const char* name : kPhaseOrder) {
    const auto it = r.report.phases.find(name);
    if (it == r.report.phases.end()) continue;
    phases[name] = {{"time_s", rounded(it->second.time_s, 3)},
                    {"outcome", it->second.outcome.empty() ? "stopped" : it->second.outcome}};
  }
  Json err = {{"position_mm", nullptr}, {"rotation_deg", nullptr}};
  if (r.final_position_mm >= 0) {
    err["position_mm"] = rounded(r.final_position_mm, 2);
    err["rotation_deg"] = rounded(r.final_rotation_deg, 3);
  }
  Json j;
  j["success"] = r.exit_code == kExitGrasped;
  j["sim_time_s"] = rounded(r.sim_time_s, 3);
  j["phases"] = phases;
  j["final_error"] = err;
  j["collisions"] = r.collisions;
  return j.dump();
}

void printProgress(std::FILE* out, const servo::GraspIteration& it) {
  char err[64] = "";
  if (it.error_position_m >= 0)
    std::snprintf(err, sizeof(err), "  error %.1f mm %.2f deg", 1000 * it.error_position_m,
                  it.error_rotation_rad * 180 / M_PI);
  char dist[48] = "";
  if (it.distance_m >= 0) std::snprintf(dist, sizeof(dist), "  distance %.3f m", it.distance_m);
  std::fprintf(out, "\r\033[Kenon_grasp: %-8s %-12s t=%6.2f s%s%s", toString(it.phase),
               it.detail.c_str(), it.t, dist, err);
  std::fflush(out);
}

}  // namespace

EnonGraspResult runEnonGraspSession(const EnonGraspOptions& o, std::FILE* progress) {
  robot::registerBuiltinBackends();
  const robot::EnonModel model = robot::loadEnonModel(o.enon);
  if (o.scenario.empty()) throw ConfigError("command line", "--scenario", "required");
  sim::Scenario scenario = sim::loadScenario(o.scenario);
  if (o.seed) scenario.seed = *o.seed;
  int target = -1;
  for (size_t i = 0; i < scenario.world.objects.size(); ++i)
    if (scenario.world.objects[i].is_target) target = static_cast<int>(i);
  if (target < 0) throw ConfigError(o.scenario, "objects", "no object with target: true");
  const sim::SimObject& goal = scenario.world.objects[static_cast<size_t>(target)];
  const detector::ObjectModel object = detector::loadObjectDefinition(goal.definition);
  if (!object.hasPose())
    throw ConfigError(goal.definition, "reference_pose", "required to grasp the object (a 3D pose)");
  const servo::ObjectExtent extent = servo::objectExtent(object);

  o.grasp.check();
  // Cheap checks first (files, options, output folders), then what takes time.
  const detector::DetectorOptions det_options = o.detector_config.empty()
                                                    ? detector::DetectorOptions()
                                                    : detector::loadDetectorOptions(o.detector_config);
  if (o.oracle && o.backend != "sim")
    throw ConfigError("command line", "--oracle",
                      "needs --backend sim (the ground truth is the simulator's)");

  if (!o.camera.empty() && o.backend == "sim")
    throw ConfigError("command line", "--camera",
                      "needs a robot backend other than sim (the simulator renders its own camera)");
  // The log and the video never write over an object definition the scenario names (the command
  // line's own paths are checked by the caller).
  tool::Paths paths;
  for (const sim::SimObject& obj : scenario.world.objects) paths.input("the scenario's object", obj.definition);
  paths.outputFolder("--log", o.log_dir);
  paths.output("--video", o.video);
  paths.check();
  // The camera first: "no camera found" before anything moves.
  std::unique_ptr<robot::StereoSource> camera;
  if (!o.camera.empty()) {
    robot::SourceRequest req;
    req.spec = o.camera;
    req.eyes = robot::Eyes::kStereo;
    req.rig = model.head.rig;
    req.settings = o.camera_settings;
    camera = robot::onCallerClock(robot::openSource(req));
  }

  std::unique_ptr<robot::Robot> robot;
  sim::SimEnon* sim = nullptr;
  if (o.backend == "sim") {
    robot = sim::makeSimRobot(model, scenario);
    sim = dynamic_cast<sim::SimEnon*>(&robot->hardware());
    // The oracle needs no pictures unless they are logged or filmed.
    sim->setRenderImages(!o.oracle || !o.log_dir.empty() || !o.video.empty());
  } else {
    robot::BackendConfig c;
    c.backend = o.backend;
    c.params = o.backend_params;
    c.source = "command line";
    robot = robot::makeRobot(model, c);
    if (camera) robot->replaceCamera(std::move(camera));
  }
  std::unique_ptr<GraspLog> log;
  if (!o.log_dir.empty())
    log = std::make_unique<GraspLog>(o.log_dir, robot->camera().rig(),
                                     o.backend == "sim" ? "sim:" + o.scenario : o.backend,
                                     object.name);
  std::unique_ptr<GraspVideo> video;
  if (!o.video.empty())
    video = std::make_unique<GraspVideo>(o.video, object, robot->camera().rig().left,
                                         o.grasp.frame_period_s > 0 ? 1.0 / o.grasp.frame_period_s
                                                                    : model.head.frame_rate_hz);
  if (video && sim) video->showOutside(*sim, model);
  detector::Detector det(det_options);
  std::unique_ptr<servo::TargetEstimator> est;
  if (o.oracle) {
    est = std::make_unique<servo::OracleEstimator>(object);
  } else {
    est = std::make_unique<servo::VisionEstimator>(det, det.addObject(object));
  }

  EnonGraspResult r;
  if (robot->configure() != robot::ReturnType::kOk || robot->activate() != robot::ReturnType::kOk) {
    r.exit_code = kExitRobotError;
    const std::string why = robot->hardware().lastError();
    // The backend's own line names the cause (no state from the driver, a bad participant).
    r.error = tool::withDdsError(why.empty() ? "could not start the robot (backend " + o.backend + ")" : why);
    r.summary = summaryLine(r);
    return r;
  }
  const tool::StopOnError stop_on_error([&] { robot->stop(); });  // an exception in the loop
  if (o.interruptible) tool::flagOnSignal();
  servo::GraspController ctl(*robot, *est, goal.oMg, extent, withRoom(o.grasp, scenario, extent));
  const double dt = model.control_period_s;
  const double max_time = o.max_time_s > 0 ? o.max_time_s : scenario.max_duration_s;
  const bool realtime = o.backend != "sim";
  const auto start = std::chrono::steady_clock::now();
  Seconds t = 0;
  std::string output_error;
  int interrupted_by = 0;  // SIGINT or SIGTERM received mid-run (0: none)
  for (int64_t k = 0; !ctl.finished(); ++k) {
    t = static_cast<double>(k) * dt;
    if (o.interruptible && tool::interruptedBy()) {
      interrupted_by = tool::interruptedBy();
      break;
    }
    if (t > max_time) {
      ctl.abort(t, "timeout", "the run took longer than " + std::to_string(max_time) + " s");
      break;
    }
    if (realtime) std::this_thread::sleep_until(start + std::chrono::duration<double>(t));
    const servo::GraspStep s = ctl.step(t, dt);
    ++r.iterations;
    if (s.it.frame) ++r.frames_used;
    if (s.status != robot::ReturnType::kOk) r.error = s.error;
    Json extra = Json::object();
    if (sim) {
      if (const auto e = sim->graspError(target))
        extra["truth_grasp_error"] = {{"position_m", e->position_m}, {"rotation_rad", e->rotation_rad}};
    }
    if (log && !log->add(s.it, extra, &output_error)) break;
    if (video && !video->add(s.it, &output_error)) break;
    if (progress && (k % 5 == 0 || ctl.finished())) printProgress(progress, s.it);
    if (s.status != robot::ReturnType::kOk) break;
  }
  robot->stop();
  robot->deactivate();
  if (progress) std::fprintf(progress, "\n");

  r.report = ctl.report();
  r.sim_time_s = t;
  if (sim) {
    r.collisions = static_cast<int>(sim->collisions().size());
    if (const auto e = sim->graspError(target)) {
      r.final_position_mm = 1000 * e->position_m;
      r.final_rotation_deg = e->rotation_rad * 180 / M_PI;
    }
  } else if (r.report.close_position_error_m >= 0) {
    r.final_position_mm = 1000 * r.report.close_position_error_m;
    r.final_rotation_deg = r.report.close_rotation_error_rad * 180 / M_PI;
  }
  if (interrupted_by) {
    r.exit_code = tool::interruptedCode(interrupted_by);
    r.error = std::string("interrupted by ") + (interrupted_by == SIGINT ? "SIGINT" : "SIGTERM") +
              " (robot stopped)";
  } else if (!output_error.empty()) {
    r.exit_code = kExitOutput;
    r.error = output_error;
  } else if (!r.error.empty()) {
    r.exit_code = kExitRobotError;
  } else if (r.report.success) {
    r.exit_code = kExitGrasped;
  } else {
    r.exit_code = kExitNoGrasp;
    r.error = r.report.failure;
  }
  r.summary = summaryLine(r);
  return r;
}

namespace {

int enonGraspMain(int argc, char** argv) {
  CLI::App app(
      "Search-approach-grasp on the enon: finds the scenario's target (stop-and-look head sweeps,\n"
      "base turns, other viewpoints), drives the base to it and aligns the gripper by visual\n"
      "servoing (vpServo), grasps and lifts it. Prints one updating progress line on a terminal\n"
      "(stderr), then one JSON line on stdout:\n"
      "  {\"success\",\"sim_time_s\",\"phases\":{<phase>:{\"time_s\",\"outcome\"}},\n"
      "   \"final_error\":{\"position_mm\",\"rotation_deg\"},\"collisions\"}\n"
      "Exit status: 0 grasped; 1 no grasp (a phase failed); 2 bad options or files; 3 the robot,\n"
      "its camera or a collision stopped the run; 4 the log or video could not be written.",
      "enon_grasp");
  EnonGraspOptions o;
  uint64_t seed = 0;
  app.add_option("--backend", o.backend, "robot backend: sim (the simulated enon) or dds")
      ->capture_default_str();
  app.add_option("--scenario", o.scenario,
                 "scenario YAML: the world (sim) and the target's definition and grasp frame")
      ->required();
  app.add_option("--enon", o.enon, "robot model YAML")->capture_default_str();
  auto* seed_opt = app.add_option("--seed", seed, "overrides the scenario's seed (0 to 2^64-1)")
                       ->check(tool::Unsigned());
  app.add_flag("--oracle", o.oracle,
               "feed the controller the simulator's ground-truth pose instead of vision");
  app.add_option("--log", o.log_dir,
                 "write a recording of the frames used and control.jsonl (one line per control "
                 "iteration) to this new folder");
  app.add_option("--video", o.video,
                 "write the annotated camera view to this video file (sim: beside it the robot seen\n"
                 "from a following camera and a top-down map, 1920x480)");
  std::string search = "belief";
  app.add_option("--search", search,
                 "belief: each look where the belief over the target's place says it pays most,\n"
                 "over the scenario's tables (docs/grasp.md \"Search\"); sweep: each direction once")
      ->check(CLI::IsMember({"belief", "sweep"}))
      ->capture_default_str();
  app.add_option("--max-time", o.max_time_s,
                 "give up after this many seconds (default: the scenario's max_duration_s)")
      ->check(tool::Finite(1e-3, 86400));
  app.add_option("--detector-config", o.detector_config,
                 "detector options YAML (every field: config/detector.yaml)");
  app.add_option("--camera", o.camera,
                 "not sim: the stereo camera from this source instead of the backend's, with the\n"
                 "robot model's rig: bb2 or bb2:GUID (the Bumblebee2 on this computer's FireWire\n"
                 "bus: the on-robot line), recording:DIR or folders:LEFT,RIGHT (played as if\n"
                 "captured live)");
  std::string camera_config;
  app.add_option("--camera-config", camera_config,
                 "bb2: the camera's YAML (guid, frame_rate_hz, shutter_s, gain_db, dma_buffers)");
  std::string ns = "/enon";
  int domain = 0;
  app.add_option("--ns", ns, "dds: ROS namespace of the robot's topics")->capture_default_str();
  auto* domain_opt =
      app.add_option("--domain", domain, "dds: DDS domain id (default: $ROS_DOMAIN_ID, else 0)")
          ->check(tool::Integer(0, 232));
  tool::parse(app, argc, argv);
  if (*seed_opt) o.seed = seed;
  o.grasp.belief_search = search == "belief";
  if (!camera_config.empty()) {
    if (o.camera.empty()) throw std::invalid_argument("--camera-config: only with --camera");
    o.camera_settings["config"] = camera_config;
  }
  tool::Paths paths;
  paths.input("--scenario", o.scenario);
  paths.input("--enon", o.enon);
  paths.input("--detector-config", o.detector_config);
  paths.input("--camera-config", camera_config);
  paths.inputSpec("--camera", o.camera);
  paths.outputFolder("--log", o.log_dir);
  paths.output("--video", o.video);
  paths.check();
  // Checked now: FFmpeg, opening the video at the first frame, would blame a missing encoder.
  if (!o.video.empty())
    if (const std::string p = tool::outputFileProblem(o.video); !p.empty())
      throw std::invalid_argument("--video " + o.video + ": " + p);
  if (o.backend != "sim") {
    const int env_domain = tool::checkDdsEnvironment();
    if (!*domain_opt) domain = env_domain;
    o.backend_params["ns"] = ns;
    o.backend_params["domain"] = std::to_string(domain);
  } else if (*domain_opt) {
    throw std::invalid_argument("--domain: only for a DDS backend (--backend dds)");
  }
  // Until the robot is active (a DDS robot's first state may take seconds), a signal ends the
  // tool at once: nothing has been commanded yet.
  tool::exitOnSignal();
  o.interruptible = true;
  std::FILE* progress = isatty(fileno(stderr)) ? stderr : nullptr;
  const EnonGraspResult r = runEnonGraspSession(o, progress);
  std::printf("%s\n", r.summary.c_str());
  if (r.exit_code != kExitGrasped) std::fprintf(stderr, "enon_grasp: %s\n", r.error.c_str());
  return r.exit_code;
}

}  // namespace

int runEnonGrasp(int argc, char** argv) {
  // One top-level handler (app/tool/tool.h): start-up problems (files, options) are one line and
  // exit 2; a failed write of the summary line (stdout) is exit 4 like the log's; anything else
  // unexpected exits 3 (the robot stopped first: the controller stops it on its own errors, the
  // session's StopOnError on an exception around it).
  tool::RunOptions codes;
  codes.bad_input = kExitBadInput;
  codes.output_failed = kExitOutput;
  codes.failure = kExitRobotError;
  return tool::run("enon_grasp", argc, argv, enonGraspMain, codes);
}

}  // namespace refgrasp::grasp_app
