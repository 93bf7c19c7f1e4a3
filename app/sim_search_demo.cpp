// Simulated search demo: the enon looks around (stop-and-look head sweeps, then turns its base)
// until the detector finds the scenario's target in both eyes, reports the fused pose against the
// simulator's ground truth, stops, and writes annotated pictures and a JSON-lines log.
// It is the "search" phase of the search-approach-grasp executable that later issues complete.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "detector/detector.h"
#include "robot/hal.h"
#include "robot/scenario.h"
#include "robot/sim_enon.h"

using namespace refgrasp;
using json = nlohmann::json;

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

json poseJson(const Pose& p) {
  const Eigen::Vector3d r = p.rotationVector();
  return {{"t", {p.t.x(), p.t.y(), p.t.z()}}, {"rotation_vector", {r.x(), r.y(), r.z()}}};
}

// Draws the detected pattern outline and the object axes (x red, y green, z blue; 10 cm).
cv::Mat annotate(const cv::Mat& gray, const detector::Detection& d, const Intrinsics& cam,
                 const std::string& text) {
  cv::Mat img;
  cv::cvtColor(gray, img, cv::COLOR_GRAY2BGR);
  if (d.found) {
    std::vector<cv::Point> poly;
    for (const auto& c : d.corners) poly.emplace_back(cvRound(c.x()), cvRound(c.y()));
    cv::polylines(img, poly, true, cv::Scalar(0, 255, 255), 2, cv::LINE_AA);
    if (d.cMo) {
      const auto px = [&](const Eigen::Vector3d& Xo) {
        const Eigen::Vector2d p = cam.project(*d.cMo * Xo);
        return cv::Point(cvRound(p.x()), cvRound(p.y()));
      };
      const cv::Point o = px(Eigen::Vector3d::Zero());
      cv::line(img, o, px({0.1, 0, 0}), cv::Scalar(0, 0, 255), 2, cv::LINE_AA);
      cv::line(img, o, px({0, 0.1, 0}), cv::Scalar(0, 255, 0), 2, cv::LINE_AA);
      cv::line(img, o, px({0, 0, 0.1}), cv::Scalar(255, 0, 0), 2, cv::LINE_AA);
    }
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
  det.addObject(detector::loadObjectDefinition(object.definition));

  std::unique_ptr<robot::Robot> robot = robot::makeRobot(model, "sim", &scenario);
  auto* sim = dynamic_cast<sim::SimEnon*>(&robot->hardware());
  std::filesystem::create_directories(o.out);
  std::ofstream log(o.out + "/looks.jsonl");
  if (robot->configure() != robot::ReturnType::kOk || robot->activate() != robot::ReturnType::kOk) {
    std::fprintf(stderr, "sim_search_demo: could not activate the simulated enon\n");
    return 2;
  }

  // Head positions to try from the current base heading: straight, then alternately left/right.
  std::vector<double> pans{0.0};
  for (double p = o.pan_step_rad; p <= model.head.pan.max_rad + 1e-9; p += o.pan_step_rad) {
    pans.push_back(p);
    if (-p >= model.head.pan.min_rad) pans.push_back(-p);
  }

  enum class Phase { kPointHead, kSettle, kLook, kTurnBase, kDone } phase = Phase::kPointHead;
  size_t pan_index = 0;
  double settle_until = 0, turn_start_theta = 0;
  int looks = 0, exit_code = 1;
  const double dt = model.control_period_s;
  const double max_time = std::min(o.max_time_s, scenario.max_duration_s);
  std::printf("sim_search_demo: looking for '%s' in %s (up to %.0f s simulated)\n",
              object.name.c_str(), o.scenario.c_str(), max_time);

  for (double t = 0; t <= max_time && phase != Phase::kDone; t += dt) {
    if (robot->read(t, dt) != robot::ReturnType::kOk) {
      std::fprintf(stderr, "sim_search_demo: robot read failed at t=%.2f s\n", t);
      robot->stop();
      return 3;
    }
    std::optional<robot::StereoFrame> frame;
    if (robot->camera().grab(t, &frame) != robot::ReturnType::kOk) {
      std::fprintf(stderr, "sim_search_demo: camera failed at t=%.2f s\n", t);
      robot->stop();
      return 3;
    }
    const double pan = robot->state().pan_rad, tilt = robot->state().tilt_rad;
    robot->base().setVelocity(0, 0);
    robot->head().setPosition(pans[pan_index], o.tilt_rad);

    switch (phase) {
      case Phase::kPointHead:
        if (std::abs(pan - pans[pan_index]) < 0.01 && std::abs(tilt - o.tilt_rad) < 0.01) {
          settle_until = t + o.settle_s;
          phase = Phase::kSettle;
        }
        break;
      case Phase::kSettle:
        if (t >= settle_until) phase = Phase::kLook;
        break;
      case Phase::kLook: {
        if (!frame || frame->stamp < settle_until) break;  // wait for a frame taken after settling
        const auto r = det.detectStereo(frame->left, frame->right, robot->camera().rig());
        if (!r.ok) {  // frames the detector cannot use: a camera fault, stop
          std::fprintf(stderr, "sim_search_demo: frame %ld: %s\n", frame->index, r.error.c_str());
          robot->stop();
          return 3;
        }
        ++looks;
        const detector::StereoDetection& s = r.objects.at(0);
        json line = {{"t_s", t}, {"frame", frame->index}, {"pan_rad", pan}, {"tilt_rad", tilt},
                     {"left_found", s.left.found}, {"right_found", s.right.found},
                     {"extract_ms", r.left.time_ms.extract + r.right.time_ms.extract},
                     {"total_ms", r.left.time_ms.total + r.right.time_ms.total}};
        const bool found = s.fused.lMo.has_value();
        std::printf("  t=%5.2f s  pan=%+.2f rad  look %d: %s\n", t, pan, looks,
                    found ? "FOUND" : "not found");
        if (found) {
          const Pose& lMo = *s.fused.lMo;
          // Ground truth of the same frame, from the simulator.
          const sim::SyntheticFrame* truth = sim ? sim->lastFrame() : nullptr;
          line["lMo"] = poseJson(lMo);
          line["eyes"] = std::string(s.left.found ? "L" : "") + (s.right.found ? "R" : "");
          std::string summary = "found";
          if (truth && truth->stamp == frame->stamp) {
            const Pose& lMo_true = truth->left_cMo.at(target);
            const double terr = translationError(lMo, lMo_true);
            const double rerr = rotationError(lMo, lMo_true) * 180 / M_PI;
            line["lMo_true"] = poseJson(lMo_true);
            line["translation_error_m"] = terr;
            line["rotation_error_deg"] = rerr;
            char buf[160];
            std::snprintf(buf, sizeof(buf), "dist %.3f m, error %.1f mm / %.2f deg",
                          lMo_true.t.norm(), terr * 1000, rerr);
            summary = buf;
          }
          const Pose wMo = sim ? sim->wMc() * lMo : Pose();
          line["wMo"] = poseJson(wMo);
          std::printf("  fused pose (left camera): t = [%.3f %.3f %.3f] m; %s\n", lMo.t.x(),
                      lMo.t.y(), lMo.t.z(), summary.c_str());
          const Intrinsics& lc = robot->camera().rig().left;
          const Intrinsics& rc = robot->camera().rig().right;
          cv::imwrite(o.out + "/found_left.png", annotate(frame->left, s.left, lc, "left: " + summary));
          cv::imwrite(o.out + "/found_right.png", annotate(frame->right, s.right, rc, "right"));
          phase = Phase::kDone;
          exit_code = 0;
        } else {
          char name[64];
          std::snprintf(name, sizeof(name), "/look_%02d_left.png", looks);
          cv::imwrite(o.out + name, frame->left);
          if (++pan_index >= pans.size()) {
            pan_index = 0;
            turn_start_theta = robot->state().wMb_odom.rotationVector().z();
            phase = Phase::kTurnBase;
          } else {
            phase = Phase::kPointHead;
          }
        }
        log << line.dump() << '\n';
        break;
      }
      case Phase::kTurnBase: {
        const double theta = robot->state().wMb_odom.rotationVector().z();
        const double turned = std::remainder(theta - turn_start_theta, 2 * M_PI);
        if (std::abs(turned) >= o.turn_rad) {
          phase = Phase::kPointHead;
        } else {
          robot->base().setVelocity(0, 0.5);
        }
        break;
      }
      case Phase::kDone:
        break;
    }
    if (robot->write(t, dt) != robot::ReturnType::kOk) {
      std::fprintf(stderr, "sim_search_demo: robot write failed at t=%.2f s\n", t);
      robot->stop();
      return 3;
    }
  }
  robot->stop();
  robot->deactivate();
  if (exit_code != 0)
    std::printf("sim_search_demo: target not found after %d looks (%.0f s simulated)\n", looks,
                max_time);
  std::printf("sim_search_demo: %d looks; pictures and looks.jsonl in %s\n", looks, o.out.c_str());
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Simulated search demo: the simulated enon sweeps its head (then turns its base) until the\n"
      "detector finds the scenario's target in its Bumblebee2 stereo pair; prints the fused pose\n"
      "and its error against the simulator's ground truth; writes found_left.png, found_right.png\n"
      "(annotated), look_NN_left.png and looks.jsonl to --out. Exit 0 when found, 1 when not,\n"
      "2/3 on a robot error (the robot is stopped first), 4 on a bad file."};
  DemoOptions o;
  app.add_option("--enon", o.enon, "robot model YAML")->capture_default_str();
  app.add_option("--scenario", o.scenario, "scenario YAML")->capture_default_str();
  app.add_option("--out", o.out, "output directory")->capture_default_str();
  app.add_option("--max-time", o.max_time_s, "simulated seconds before giving up")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--tilt", o.tilt_rad, "head tilt while searching, rad (> 0 looks down)")
      ->capture_default_str();
  app.add_option("--pan-step", o.pan_step_rad, "head pan step between looks, rad")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    return run(o);
  } catch (const ConfigError& e) {
    std::fprintf(stderr, "sim_search_demo: %s\n", e.what());
    return 4;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sim_search_demo: %s\n", e.what());
    return 4;
  }
}
