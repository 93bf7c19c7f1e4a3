// What each check of the detector's verification stage pays: every rule switched off in turn on
// the development data (realistic sets 3D and 2D-only, photo pairs, photo clutter), every frame
// rendered once and given to every variant (eval/ablation.h). Prints docs/detector.md's
// ablation table.
#include <opencv2/core.hpp>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "bench_util.h"
#include "eval/ablation.h"

using namespace refgrasp;

namespace {

void usage() {
  std::printf(
      "bench_ablation: each rule of the detector's verification stage switched off in turn on the\n"
      "development data; one table row per rule (found, pose ok, wrong, corners, clutter, time).\n"
      "Usage: bench_ablation [--seeds S,S,... (realistic splits; 1,3,5,9,11,13,19,21)]\n"
      "       [--frames N per set (160)] [--no-2d] [--pair-seeds N (1)] [--first-pair-seed S (1)]\n"
      "       [--clutter N frames (100)] [--threads N (2)] [--only I,J,... (rows to run besides\n"
      "       row 0; --list shows them)] [--list] [--help]\n"
      "Times are thread CPU time, one OpenCV thread per worker.\n");
}

std::vector<long long> intList(const char* option, const std::string& text, long long min_value) {
  std::vector<long long> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ','))
    out.push_back(bench::intArg("bench_ablation", option, item.c_str(), min_value));
  if (out.empty()) {
    std::fprintf(stderr, "bench_ablation: %s: expected a comma-separated list, got '%s'\n", option, text.c_str());
    std::exit(2);
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) try {
  eval::AblationData data;
  data.seeds = {1, 3, 5, 9, 11, 13, 19, 21};
  int threads = 2;
  std::vector<long long> only;
  const std::vector<eval::AblationVariant> all = eval::verificationAblation();
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else if (a == "--list") {
      for (size_t v = 0; v < all.size(); ++v)
        std::printf("%zu  %s  (%s)\n", v, all[v].name.c_str(), all[v].off.c_str());
      return 0;
    } else if (a == "--seeds" && i + 1 < argc) {
      data.seeds.clear();
      for (const long long s : intList("--seeds", argv[++i], 0)) data.seeds.push_back(static_cast<uint64_t>(s));
    } else if (a == "--frames" && i + 1 < argc) {
      data.frames_per_set = static_cast<int>(bench::intArg("bench_ablation", "--frames", argv[++i], 1));
    } else if (a == "--no-2d") {
      data.two_d = false;
    } else if (a == "--pair-seeds" && i + 1 < argc) {
      data.pair_seeds = static_cast<int>(bench::intArg("bench_ablation", "--pair-seeds", argv[++i], 0));
    } else if (a == "--first-pair-seed" && i + 1 < argc) {
      data.pair_first_seed = static_cast<uint64_t>(bench::intArg("bench_ablation", "--first-pair-seed", argv[++i], 0));
    } else if (a == "--clutter" && i + 1 < argc) {
      data.clutter_frames = static_cast<int>(bench::intArg("bench_ablation", "--clutter", argv[++i], 0));
    } else if (a == "--threads" && i + 1 < argc) {
      threads = static_cast<int>(bench::intArg("bench_ablation", "--threads", argv[++i], 1));
    } else if (a == "--only" && i + 1 < argc) {
      only = intList("--only", argv[++i], 1);
      for (const long long v : only)
        if (v >= static_cast<long long>(all.size())) {
          std::fprintf(stderr, "bench_ablation: --only: expected rows 1-%zu (see --list), got %lld\n", all.size() - 1, v);
          return 2;
        }
    } else {
      bench::rejectArgument("bench_ablation", a,
                            {"--seeds", "--frames", "--pair-seeds", "--first-pair-seed", "--clutter", "--threads", "--only"});
    }
  }
  std::vector<eval::AblationVariant> variants = {all[0]};
  for (size_t v = 1; v < all.size(); ++v)
    if (only.empty() || std::find(only.begin(), only.end(), static_cast<long long>(v)) != only.end())
      variants.push_back(all[v]);
  cv::setNumThreads(1);
  const auto counts = eval::runAblation(variants, data, threads, [](int done, int total) {
    std::fprintf(stderr, "\rbench_ablation: %d/%d frames and pairs", done, total);
  });
  std::fprintf(stderr, "\n");
  std::string seeds;
  for (const uint64_t s : data.seeds) seeds += (seeds.empty() ? "" : ",") + std::to_string(s);
  std::printf("Realistic seeds %s (%d frames per set%s), photo-pair seeds %llu-%llu, clutter %d frames (seed %s).\n\n",
              seeds.c_str(), data.frames_per_set, data.two_d ? ", 3D and 2D-only" : "",
              static_cast<unsigned long long>(data.pair_first_seed),
              static_cast<unsigned long long>(data.pair_first_seed + data.pair_seeds - 1), data.clutter_frames,
              data.seeds.empty() ? "-" : std::to_string(data.seeds.front()).c_str());
  std::printf("%s", eval::formatAblation(variants, counts).c_str());
  return 0;
}
catch (const std::exception& e) {  // bad data options, a missing media file: one line, not an abort
  std::fprintf(stderr, "bench_ablation: %s\n", e.what());
  return 1;
}
