// The detector's accuracy on rendered scenes with ground truth by construction: the tables of
// docs/results.md "Accuracy" (pose accuracy of both pose methods, jitter, stereo fusion, hard
// cases, false positives). The runs are eval/detector_accuracy.h's, the ones tests/detector
// asserts on; this prints their figures.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "bench_util.h"
#include "detector/detector.h"
#include "eval/detector_accuracy.h"

using namespace refgrasp;

namespace {

constexpr double kDeg = M_PI / 180;
const char* const kTool = "bench_accuracy";
const char* const kParts[] = {"pose", "jitter", "stereo", "hard-cases", "false-positives"};

void usage() {
  std::printf(
      "bench_accuracy: the detector's accuracy on seeded rendered scenes with ground truth\n"
      "(docs/results.md \"Accuracy\"; the same runs as ctest -R 'Detector|HardCases|FalsePositives'):\n"
      "  pose             both pose methods on the same matches, and Detector::detect, on random\n"
      "                   poses of a 20 cm poster at 0.3-1.2 m, tilt 0-50 deg, noise 2, blur 0-1.5 px\n"
      "                   (ok = rotation < 1 deg and translation < 1 %% of the distance; t/d =\n"
      "                   translation error / distance); then the refined poses outside the bars\n"
      "  jitter           std of Z over 50 noisy renders at 0.5 m\n"
      "  stereo           position std of each eye and of the fused pose, 30 stereo frames at 0.8 m\n"
      "  hard-cases       paper matcher vs ratio baseline, 10 scenes per category (found = corners\n"
      "                   within 3 px)\n"
      "  false-positives  detections over clutter frames with the five targets registered\n"
      "Usage: bench_accuracy [--only pose|jitter|stereo|hard-cases|false-positives]\n"
      "                      [--poses N (default 48)] [--clutter-frames N (default 500)] [--help]\n"
      "All parts by default (about a minute of CPU, most of it the 500 clutter frames).\n"
      "Environment: REFGRASP_SIFT=opencv runs cv::SIFT instead of the fast extractor.\n");
}

void printPoseErrors(const char* name, const eval::PoseErrors& e) {
  using eval::quantile;
  std::printf("| %-8s | %5.1f%% (%d/%d) | %6.3f | %6.3f | %6.3f | %7.4f | %7.4f | %7.4f |\n", name, 100 * e.rate(),
              e.ok, e.n, quantile(e.rot_deg, 0.5), quantile(e.rot_deg, 0.95), quantile(e.rot_deg, 1.0),
              quantile(e.rel_t, 0.5), quantile(e.rel_t, 0.95), quantile(e.rel_t, 1.0));
}

void pose(int poses) {
  const eval::PoseAccuracy a = eval::poseAccuracy(poses);
  std::printf("Pose accuracy, %d random poses (0.3-1.2 m, tilt 0-50 deg, noise 2, blur 0-1.5 px)\n"
              "| method   | ok (<1deg,<1%%) | rot med | rot 95%% | rot max | t/d med | t/d 95%% | t/d max |\n",
              poses);
  printPoseErrors("paper", a.paper);
  printPoseErrors("refined", a.refined);
  printPoseErrors("detect()", a.detected);
  std::printf("default: %s\n", detector::poseMethodName(detector::DetectorOptions{}.pose));
  for (size_t i = 0; i < a.frames.size(); ++i) {
    const eval::PoseAccuracyFrame& f = a.frames[i];
    const double d = f.truth.t.norm();
    if (!f.refined || (rotationError(*f.refined, f.truth) <= kDeg && translationError(*f.refined, f.truth) <= 0.01 * d))
      continue;
    std::printf("  outside 1 deg / 1%%: pose %zu at %.2f m, tilt %.1f deg, %d inliers: refined %.2f deg %.2f%%, "
                "paper %.2f deg %.2f%%\n",
                i, d, f.tilt_deg, f.inliers, rotationError(*f.refined, f.truth) / kDeg,
                100 * translationError(*f.refined, f.truth) / d, f.paper ? rotationError(*f.paper, f.truth) / kDeg : NAN,
                f.paper ? 100 * translationError(*f.paper, f.truth) / d : NAN);
  }
}

void jitter() {
  const std::vector<std::optional<double>> depths = eval::jitterDepths(50);
  std::vector<double> z;
  for (const auto& d : depths)
    if (d) z.push_back(*d);
  std::printf("Jitter: %zu noisy renders at 0.5 m, std(Z) = %.3f mm", depths.size(), eval::sampleStd(z) * 1e3);
  if (z.size() < depths.size()) std::printf(" (%zu without a pose)", depths.size() - z.size());
  std::printf("\n");
}

void stereo() {
  const eval::StereoJitter::Summary j = eval::stereoJitter(30).summary();
  std::printf("Stereo jitter at 0.8 m over %d frames (position std, mm): left %.3f, right %.3f, "
              "fused %.3f (%.0f%% of the better eye)\n",
              j.both, j.left_m * 1e3, j.right_m * 1e3, j.fused_m * 1e3, 100 * j.fused_m / std::min(j.left_m, j.right_m));
}

void hardCases() {
  const std::vector<eval::HardCaseRow> rows = eval::hardCases();
  eval::HardCaseRow all{"overall"};
  std::printf("\n%-20s %12s %12s\n", "category", "paper", "ratio");
  for (const auto& r : rows) {
    std::printf("%-20s %8d/%-3d %8d/%-3d\n", r.category.c_str(), r.paper, r.total, r.ratio, r.total);
    all.paper += r.paper;
    all.ratio += r.ratio;
    all.total += r.total;
  }
  std::printf("%-20s %8d/%-3d %8d/%-3d\n\n", all.category.c_str(), all.paper, all.total, all.ratio, all.total);
}

void falsePositives(int frames) {
  const eval::FalsePositiveRun r = eval::falsePositivesOnClutter(frames);
  for (const std::string& f : r.failed) std::printf("  detect() failed: %s\n", f.c_str());
  for (const std::string& d : r.false_detections) std::printf("  %s\n", d.c_str());
  std::printf("False positives: %d detections over %d clutter frames x %zu objects "
              "(%d matcher candidates rejected by the sanity check), mean %.1f ms/frame\n",
              r.detections, r.frames, r.objects, r.sanity_rejected, r.total_ms / r.frames);
}

}  // namespace

int main(int argc, char** argv) try {
  int poses = 48, clutter_frames = 500;
  std::string only;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else if (a == "--poses" && i + 1 < argc) {
      poses = static_cast<int>(bench::intArg(kTool, "--poses", argv[++i], 1));
    } else if (a == "--clutter-frames" && i + 1 < argc) {
      clutter_frames = static_cast<int>(bench::intArg(kTool, "--clutter-frames", argv[++i], 1));
    } else if (a == "--only" && i + 1 < argc) {
      only = argv[++i];
      if (std::find(std::begin(kParts), std::end(kParts), only) == std::end(kParts)) {
        std::fprintf(stderr, "%s: --only: expected pose, jitter, stereo, hard-cases or false-positives, got '%s'\n",
                     kTool, only.c_str());
        return 2;
      }
    } else {
      bench::rejectArgument(kTool, a, {"--poses", "--clutter-frames", "--only"});
    }
  }
  const auto part = [&](const char* name) { return only.empty() || only == name; };
  if (part("pose")) pose(poses);
  if (part("jitter")) jitter();
  if (part("stereo")) stereo();
  if (part("hard-cases")) hardCases();
  if (part("false-positives")) falsePositives(clutter_frames);
  return 0;
}
catch (const std::exception& e) {  // a missing or unreadable input: one line, not an abort
  std::fprintf(stderr, "%s: %s\n", kTool, e.what());
  return 1;
}
