// The paper's Fig. 7 (detection range on a table) and Fig. 8 (false positives while driving),
// reproduced on the simulated enon (src/eval/paper_figures.h): writes <output>/evaluation.md and
// its plots in <output>/img/, prints the tables, progress on stderr.
#include <opencv2/core.hpp>
#include <chrono>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "bench_util.h"
#include "eval/paper_figures.h"

using namespace refgrasp;

namespace {

constexpr const char* kTool = "paper_figures";

void usage() {
  std::printf(
      "paper_figures: the paper's Fig. 7 and Fig. 8 reproduced on the simulated enon; writes\n"
      "OUTPUT/evaluation.md and OUTPUT/img/fig7_success.png, fig7_pose_std.png, fig8_false_positives.png\n"
      "and prints the tables (progress on stderr).\n"
      "Usage: paper_figures [--output DIR (docs)] [--quick (2 distances, 1 turn, 2 frames per view,\n"
      "       3 s of driving: a smoke test of the pipeline, not the figures)] [--frames N (20)]\n"
      "       [--threads N (2)] [--duration S (73)] [--help]\n");
}

}  // namespace

int main(int argc, char** argv) try {
  std::string output = "docs";
  bool quick = false;
  eval::Fig7Options f7;
  eval::Fig8Options f8;
  f7.config_dir = f8.config_dir = std::string(REFGRASP_SOURCE_DIR) + "/config";
  long long frames = -1, duration = -1;
  std::string command = "build/bench/paper_figures";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else if (a == "--output" && i + 1 < argc) {
      output = argv[++i];
      command += " --output " + output;
    } else if (a == "--quick") {
      quick = true;
      command += " --quick";
    } else if (a == "--frames" && i + 1 < argc) {
      frames = bench::intArg(kTool, "--frames", argv[++i], 1);
      command += " --frames " + std::to_string(frames);
    } else if (a == "--threads" && i + 1 < argc) {
      f7.threads = static_cast<int>(bench::intArg(kTool, "--threads", argv[++i], 1));
    } else if (a == "--duration" && i + 1 < argc) {
      duration = bench::intArg(kTool, "--duration", argv[++i], 1);
      if (duration > 600) {
        std::fprintf(stderr, "%s: --duration: expected an integer in [1, 600], got '%s'\n", kTool, argv[i]);
        return 2;
      }
      command += " --duration " + std::to_string(duration);
    } else {
      bench::rejectArgument(kTool, a, {"--output", "--frames", "--threads", "--duration"});
    }
  }
  if (quick) eval::makeQuick(&f7, &f8);
  if (frames > 0) f7.frames = static_cast<int>(frames);
  if (duration > 0) f8.duration_s = static_cast<double>(duration);
  f7.check();
  f8.check();
  bench::requireFolder(kTool, "--output", output);
  cv::setNumThreads(1);  // parallel over views instead

  const auto t0 = std::chrono::steady_clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  const eval::Fig7Result r7 = eval::runFig7(f7, [&](int done, int total) {
    if (done % 10 == 0 || done == total) std::fprintf(stderr, "fig7: %d/%d views (%.0f s)\n", done, total, elapsed());
  });
  const double t7 = elapsed();
  const eval::Fig8Result r8 = eval::runFig8(f8, [&](int done, int total) {
    if (done % 100 == 0 || done == total) std::fprintf(stderr, "fig8: %d/%d frames (%.0f s)\n", done, total, elapsed());
  });
  const std::vector<std::string> written = eval::writePaperReport(output, r7, r8, command);
  std::printf("## Fig. 7\n\n%s\n## Fig. 8\n\n%s\n", eval::fig7Tables(r7).c_str(), eval::fig8Table(r8).c_str());
  for (const auto& w : written) std::fprintf(stderr, "wrote %s\n", w.c_str());
  std::fprintf(stderr, "fig7 %.0f s, fig8 %.0f s, total %.0f s wall\n", t7, elapsed() - t7, elapsed());
  return 0;
} catch (const std::invalid_argument& e) {  // an option out of range (Fig7Options::check)
  std::fprintf(stderr, "%s: %s\n", kTool, e.what());
  return 2;
} catch (const std::exception& e) {  // a missing input or an output that cannot be written: one line
  std::fprintf(stderr, "%s: %s\n", kTool, e.what());
  return 1;
}
