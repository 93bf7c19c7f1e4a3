// Simulated search demo: the enon looks around (stop-and-look head sweeps, then turns its base)
// until the detector finds the scenario's target in both eyes, reports the fused pose against the
// simulator's ground truth, stops, and writes annotated pictures and a JSON-lines log.
// It is the "search" phase of the search-approach-grasp executable that later issues complete.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/json.h"
#include "detector/detector.h"
#include "detector/draw.h"
#include "robot/hal.h"
#include "servo/search.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"
#include "tool/tool.h"

using namespace refgrasp;

namespace {

struct DemoOptions {
  std::string enon = "config/enon.yaml";
  std::string scenario = "config/scenarios/table_single.yaml";
  std::string out = "out/demo";
  double max_time_s = 60;
  double tilt_rad = 0.16;       // > 0 looks down
  double pan_step_rad = 0.45;   // less than the ~1.15 rad horizontal field of view
  double settle_s = 0.25;       // wait after the head stops, so frames are sharp
  double turn_rad = 1.0;        // base turn once every head position was tried
};

// Poses in looks.jsonl: {"t": [m], "rotation_vector": [rad]}.
Json poseRv(const Pose& p) { return poseJson(p, PoseJsonForm::kRotationVector); }

// Draws the detected pattern outline and the object axes (x red, y green, z blue; 10 cm).
cv::Mat annotate(const cv::Mat& gray, const detector::Detection& d, const Intrinsics& cam,
                 const std::string& text) {
  cv::Mat img;
  cv::cvtColor(gray, img, cv::COLOR_GRAY2BGR);
  if (d.found) {
    std::vector<cv::Point> poly;
    for (const auto& c : d.corners) poly.emplace_back(cvRound(c.x()), cvRound(c.y()));
    cv::polylines(img, poly, true, cv::Scalar(0, 255, 255), 2, cv::LINE_AA);
    if (d.cMo) detector::drawAxes(img, cam, *d.cMo, 0.1);
  }
  cv::putText(img, text, {8, 20}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 255, 255), 1,
              cv::LINE_AA);
  return img;
}

int run(const DemoOptions& o) {
  const robot::EnonModel model = robot::loadEnonModel(o.enon);
  const sim::Scenario scenario = sim::loadScenario(o.scenario);
  int target = -1;
  for (size_t i = 0; i < scenario.world.objects.size(); ++i)
    if (scenario.world.objects[i].is_target) target = static_cast<int>(i);
  if (target < 0 || scenario.world.objects[target].definition.empty())
    throw ConfigError(o.scenario, "objects", "no object with target: true and a definition");
  const sim::SimObject& object = scenario.world.objects[target];

  detector::Detector det;
  const int id = det.addObject(detector::loadObjectDefinition(object.definition));

  std::unique_ptr<robot::Robot> robot = sim::makeSimRobot(model, scenario);
  const tool::StopOnError stop_on_error([&] { robot->stop(); });
  auto* sim = dynamic_cast<sim::SimEnon*>(&robot->hardware());
  tool::makeOutputDir(o.out);
  const std::string log_path = o.out + "/looks.jsonl";
  std::ofstream log(log_path);
  tool::checkWritten(log, log_path);
  if (robot->configure() != robot::ReturnType::kOk || robot->activate() != robot::ReturnType::kOk) {
    robot->stop();
    std::fprintf(stderr, "sim_search_demo: could not activate the simulated enon\n");
    return 2;
  }
  servo::SearchOptions so;
  so.tilt_rad = o.tilt_rad;
  so.pan_step_rad = o.pan_step_rad;
  so.settle_s = o.settle_s;
  so.turn_rad = o.turn_rad;
  servo::SearchController search(*robot, det, id, so);

  const double dt = model.control_period_s;
  const double max_time = std::min(o.max_time_s, scenario.max_duration_s);
  std::printf("sim_search_demo: looking for '%s' in %s (up to %.0f s simulated)\n",
              object.name.c_str(), o.scenario.c_str(), max_time);
  int exit_code = 1;
  for (double t = 0; t <= max_time && search.phase() != servo::SearchPhase::kFound; t += dt) {
    const servo::SearchStep step = search.step(t, dt);
    if (step.status != robot::ReturnType::kOk) {  // the controller stopped the robot
      std::fprintf(stderr, "sim_search_demo: %s\n", step.error.c_str());
      return 3;
    }
    if (!step.look) continue;
    const servo::SearchLook& look = *step.look;
    const detector::StereoDetection& s = look.detection;
    const robot::StereoFrame& frame = look.frame;
    Json line = {{"t_s", t}, {"frame", frame.index}, {"pan_rad", robot->state().pan_rad},
                 {"tilt_rad", robot->state().tilt_rad}, {"left_found", s.left.found},
                 {"right_found", s.right.found}, {"extract_ms", look.extract_ms},
                 {"total_ms", look.total_ms}};
    std::printf("  t=%5.2f s  pan=%+.2f rad  look %d: %s\n", t, robot->state().pan_rad,
                look.number, look.found() ? "FOUND" : "not found");
    if (look.found()) {
      const Pose& lMo = *s.fused.lMo;
      // Ground truth of the same frame, from the simulator.
      const sim::SyntheticFrame* truth = sim ? sim->lastFrame() : nullptr;
      line["lMo"] = poseRv(lMo);
      line["eyes"] = std::string(s.left.found ? "L" : "") + (s.right.found ? "R" : "");
      std::string summary = "found";
      if (truth && truth->stamp == frame.stamp) {
        const Pose& lMo_true = truth->left_cMo.at(target);
        const double terr = translationError(lMo, lMo_true);
        const double rerr = rotationError(lMo, lMo_true) * 180 / M_PI;
        line["lMo_true"] = poseRv(lMo_true);
        line["translation_error_m"] = terr;
        line["rotation_error_deg"] = rerr;
        char buf[160];
        std::snprintf(buf, sizeof(buf), "dist %.3f m, error %.1f mm / %.2f deg",
                      lMo_true.t.norm(), terr * 1000, rerr);
        summary = buf;
      }
      const Pose wMo = sim ? sim->wMc() * lMo : Pose();
      line["wMo"] = poseRv(wMo);
      std::printf("  fused pose (left camera): t = [%.3f %.3f %.3f] m; %s\n", lMo.t.x(),
                  lMo.t.y(), lMo.t.z(), summary.c_str());
      const Intrinsics& lc = robot->camera().rig().left;
      const Intrinsics& rc = robot->camera().rig().right;
      tool::writeImage(o.out + "/found_left.png", annotate(frame.left, s.left, lc, "left: " + summary));
      tool::writeImage(o.out + "/found_right.png", annotate(frame.right, s.right, rc, "right"));
      tool::writeImage(o.out + "/frame_left.png", frame.left);  // as captured, for other tools
      tool::writeImage(o.out + "/frame_right.png", frame.right);
      exit_code = 0;
    } else {
      char name[64];
      std::snprintf(name, sizeof(name), "/look_%02d_left.png", look.number);
      tool::writeImage(o.out + name, frame.left);
    }
    log << line.dump() << '\n';
  }
  robot->stop();
  robot->deactivate();
  tool::checkWritten(log, log_path);
  if (exit_code != 0)
    std::printf("sim_search_demo: target not found after %d looks (%.0f s simulated)\n",
                search.looks(), max_time);
  std::printf("sim_search_demo: %d looks; pictures and looks.jsonl in %s\n", search.looks(),
              o.out.c_str());
  return exit_code;
}

int simSearchDemo(int argc, char** argv) {
  CLI::App app{
      "Simulated search demo: the simulated enon sweeps its head (then turns its base) until the\n"
      "detector finds the scenario's target in its Bumblebee2 stereo pair; prints the fused pose\n"
      "and its error against the simulator's ground truth; writes found_left.png, found_right.png\n"
      "(annotated), frame_left.png, frame_right.png (the pair as captured), look_NN_left.png and\n"
      "looks.jsonl to --out. Exit 0 when found, 1 when not,\n"
      "2/3 on a robot error (the robot is stopped first), 4 on a bad option or file,\n"
      "5 when an output could not be written."};
  DemoOptions o;
  app.add_option("--enon", o.enon, "robot model YAML")->capture_default_str();
  app.add_option("--scenario", o.scenario, "scenario YAML")->capture_default_str();
  app.add_option("--out", o.out, "output directory")->capture_default_str();
  app.add_option("--max-time", o.max_time_s, "simulated seconds before giving up")
      ->check(tool::Finite(0.1, 3600))
      ->capture_default_str();
  app.add_option("--tilt", o.tilt_rad, "head tilt while searching, rad (> 0 looks down)")
      ->check(tool::Finite(-1.5, 1.5))
      ->capture_default_str();
  app.add_option("--pan-step", o.pan_step_rad, "head pan step between looks, rad")
      ->check(tool::Finite(0.05, 1.5))
      ->capture_default_str();
  tool::parse(app, argc, argv);
  return run(o);
}

}  // namespace

int main(int argc, char** argv) {
  tool::RunOptions codes;
  codes.bad_input = codes.failure = 4;
  codes.output_failed = 5;
  return tool::run("sim_search_demo", argc, argv, simSearchDemo, codes);
}
