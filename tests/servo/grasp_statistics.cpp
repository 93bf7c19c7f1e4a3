// End-to-end grasp statistics on the simulated enon (ctest GraspStatistics.*; docs/results.md
// "enon_grasp statistics").
//
//   grasp_statistics run SCENARIO.yaml vision|oracle FIRST_SEED LAST_SEED OUT.jsonl
//       one grasp per seed with vision (rendered frames, the tracker pipeline) or with the oracle
//       (ground truth, no rendering); one JSON line per run in OUT.jsonl; exit 0.
//   grasp_statistics check DIR NAME REQUIRED MAX_TIME_RATIO [MAX_FIND_RATIO]
//       reads DIR/NAME.vision.jsonl and DIR/NAME.oracle.jsonl (the shards of one scenario) and checks, for vision and for the
//       oracle separately, that the successes reach the REQUIRED fraction ("19/20": at least
//       ceil(19/20 x runs)), where success = the target held at the end, no collision, no joint
//       on a limit, and no motion on an unconfirmed or lost target on any iteration; and that the
//       median simulated time of the vision runs is at most MAX_TIME_RATIO x the oracle's on the
//       same seeds; with MAX_FIND_RATIO, also the median time to find the target (the search
//       phases' time; a run that never found it counts its whole time) on those seeds. Prints
//       the table; exit 0 when every check holds, 1 otherwise.
// The run shards are ctest FIXTURES_SETUP of the check, so -j runs the shards in parallel.
#include <cstdio>
#include <cmath>
#include <cstdlib>
#include <map>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "detector/detector.h"
#include "grasp_run.h"
#include "servo/vision_estimator.h"

using namespace refgrasp;
using nlohmann::json;

namespace {

double cpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

json runOne(const std::string& scenario, uint64_t seed, bool oracle) {
  const refgrasp::testing::Target target = refgrasp::testing::loadTarget(scenario, seed);
  detector::Detector det;  // the oracle needs no detector (no reference features to extract)
  std::unique_ptr<servo::TargetEstimator> est;
  if (oracle) {
    est = std::make_unique<servo::OracleEstimator>(target.object);
  } else {
    est = std::make_unique<servo::VisionEstimator>(det, det.addObject(target.object));
  }
  const double c0 = cpuSeconds();
  const refgrasp::testing::GraspRun r =
      refgrasp::testing::runGrasp(target, *est, {}, target.scenario.max_duration_s, /*render=*/!oracle);
  json j;
  j["seed"] = seed;
  j["estimator"] = oracle ? "oracle" : "vision";
  const bool ok = r.report.success && r.holding_target && r.collisions.empty() &&
                  r.violations.empty() && r.min_joint_margin_rad > 1e-3 && r.error.empty();
  j["success"] = ok;
  j["grasped"] = r.report.success;
  j["sim_time_s"] = r.sim_time_s;
  j["cpu_s"] = cpuSeconds() - c0;
  j["collisions"] = r.collisions.size();
  if (!r.collisions.empty()) j["collision"] = r.collisions.front().message();
  j["violations"] = r.violations.size();
  if (!r.violations.empty()) j["violation"] = r.violations.front();
  j["min_joint_margin_rad"] = r.min_joint_margin_rad;
  j["failure"] = r.report.failure.empty() ? r.error : r.report.failure;
  j["searches"] = r.report.searches;
  json phases = json::object();
  for (const auto& [name, p] : r.report.phases) phases[name] = {{"time_s", p.time_s}, {"outcome", p.outcome}};
  j["phases"] = phases;
  if (r.final_grasp_error) {
    j["final_position_mm"] = 1000 * r.final_grasp_error->position_m;
    j["final_rotation_deg"] = r.final_grasp_error->rotation_rad * 180 / M_PI;
  }
  j["frames"] = r.frames_observed;
  return j;
}

/// Time to find the target: the search phases' time when a search found it, else the run's time.
double findTime(const json& r) {
  const json& p = r["phases"];
  if (p.contains("approach") && p.contains("search")) return p["search"]["time_s"].get<double>();
  return r["sim_time_s"].get<double>();
}

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// "19/20" -> 0.95; one line and exit 2 when it is not a fraction in [0, 1].
double fraction(const std::string& text) {
  int num = 0, den = 0;
  char rest = 0;
  if (std::sscanf(text.c_str(), "%d/%d%c", &num, &den, &rest) != 2 || den <= 0 || num < 0 || num > den) {
    std::fprintf(stderr, "grasp_statistics: REQUIRED: expected a fraction like 19/20, got '%s'\n",
                 text.c_str());
    std::exit(2);
  }
  return static_cast<double>(num) / den;
}

int check(const std::string& dir, const std::string& name, const std::string& required,
          double max_ratio, double max_find_ratio) {
  const double need = fraction(required);
  std::vector<json> runs;
  for (const char* estimator : {"vision", "oracle"}) {
    std::ifstream in(std::filesystem::path(dir) / (name + "." + estimator + ".jsonl"));
    for (std::string l; std::getline(in, l);)
      if (!l.empty()) runs.push_back(json::parse(l));
  }
  std::map<int, double> oracle_time, oracle_find;  // by seed
  for (const json& r : runs)
    if (r["estimator"] == "oracle") {
      oracle_time[r["seed"].get<int>()] = r["sim_time_s"].get<double>();
      oracle_find[r["seed"].get<int>()] = findTime(r);
    }
  std::vector<double> fv, fo_same_seeds;
  std::vector<double> tv, to_same_seeds, to;
  int ok_v = 0, ok_o = 0, n_v = 0, n_o = 0;
  double cpu_v = 0, cpu_o = 0;
  bool pass = true;
  for (const json& r : runs) {
    const bool vision = r["estimator"] == "vision";
    (vision ? n_v : n_o) += 1;
    (vision ? ok_v : ok_o) += r["success"].get<bool>();
    (vision ? tv : to).push_back(r["sim_time_s"].get<double>());
    (vision ? cpu_v : cpu_o) += r["cpu_s"].get<double>();
    if (vision) {
      const auto o = oracle_time.find(r["seed"].get<int>());
      if (o == oracle_time.end()) {
        std::printf("%s: vision seed %d has no oracle run\n", name.c_str(), r["seed"].get<int>());
        pass = false;
      } else {
        to_same_seeds.push_back(o->second);
        fv.push_back(findTime(r));
        fo_same_seeds.push_back(oracle_find.at(r["seed"].get<int>()));
      }
    }
    if (!r["success"].get<bool>())
      std::printf("%s seed %d %s failed: %s%s%s\n", name.c_str(), r["seed"].get<int>(),
                  r["estimator"].get<std::string>().c_str(), r["failure"].get<std::string>().c_str(),
                  r.contains("collision") ? (" " + r["collision"].get<std::string>()).c_str() : "",
                  r.contains("violation") ? (" " + r["violation"].get<std::string>()).c_str() : "");
  }
  const double ratio = median(tv) / median(to_same_seeds);
  std::printf("%s: vision %d/%d (median %.2f s, %.1f s CPU per run), oracle %d/%d (median %.2f s, "
              "%.2f s CPU per run), median time ratio on the vision seeds %.3f\n",
              name.c_str(), ok_v, n_v, median(tv), n_v ? cpu_v / n_v : 0.0, ok_o, n_o, median(to),
              n_o ? cpu_o / n_o : 0.0, ratio);
  if (n_v == 0 || n_o == 0) {
    std::printf("%s: expected vision and oracle runs, got %d and %d\n", name.c_str(), n_v, n_o);
    pass = false;
  }
  // A small tolerance so that 19/20 of 20 runs needs 19, not 19.0000001.
  const int need_v = static_cast<int>(std::ceil(need * n_v - 1e-9));
  const int need_o = static_cast<int>(std::ceil(need * n_o - 1e-9));
  if (ok_v < need_v) {
    std::printf("%s: %d of %d vision runs succeeded, at least %d (%s) required\n", name.c_str(), ok_v,
                n_v, need_v, required.c_str());
    pass = false;
  }
  if (ok_o < need_o) {
    std::printf("%s: %d of %d oracle runs succeeded, at least %d (%s) required\n", name.c_str(), ok_o,
                n_o, need_o, required.c_str());
    pass = false;
  }
  if (!(ratio <= max_ratio)) {
    std::printf("%s: vision/oracle median time ratio %.3f > %.2f\n", name.c_str(), ratio, max_ratio);
    pass = false;
  }
  const double find_ratio = median(fv) / median(fo_same_seeds);
  std::printf("%s: median time to find, vision %.2f s, oracle %.2f s on the same seeds, ratio %.3f\n",
              name.c_str(), median(fv), median(fo_same_seeds), find_ratio);
  if (max_find_ratio > 0 && !(find_ratio <= max_find_ratio)) {
    std::printf("%s: vision/oracle median time to find %.3f > %.2f\n", name.c_str(), find_ratio, max_find_ratio);
    pass = false;
  }
  return pass ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string cmd = argc > 1 ? argv[1] : "";
  const std::string estimator = argc > 3 ? argv[3] : "";
  if (cmd == "run" && argc == 7 && (estimator == "vision" || estimator == "oracle")) {
    const uint64_t first = std::strtoull(argv[4], nullptr, 10), last = std::strtoull(argv[5], nullptr, 10);
    const bool oracle = estimator == "oracle";
    std::ofstream out(argv[6]);
    for (uint64_t seed = first; seed <= last; ++seed) {
      const json j = runOne(argv[2], seed, oracle);
      out << j.dump() << '\n';
      out.flush();
      std::printf("seed %llu %-6s %s %.2f s (%.2f s CPU)%s%s\n", static_cast<unsigned long long>(seed),
                  estimator.c_str(), j["success"].get<bool>() ? "ok  " : "FAIL",
                  j["sim_time_s"].get<double>(), j["cpu_s"].get<double>(),
                  j["success"].get<bool>() ? "" : " ", j["failure"].get<std::string>().c_str());
      std::fflush(stdout);
    }
    return out ? 0 : 1;
  }
  if (cmd == "check" && (argc == 6 || argc == 7))
    return check(argv[2], argv[3], argv[4], std::atof(argv[5]), argc == 7 ? std::atof(argv[6]) : 0);
  std::fprintf(stderr,
               "usage: grasp_statistics run SCENARIO.yaml vision|oracle FIRST_SEED LAST_SEED OUT.jsonl\n"
               "       grasp_statistics check DIR NAME REQUIRED(e.g. 19/20) MAX_TIME_RATIO [MAX_FIND_RATIO]\n");
  return 2;
}
