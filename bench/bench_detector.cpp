// Timer harness for the detector stages on rendered 640x480 cluttered frames containing the
// target. Prints a table of medians and the bar: whole detection <= 1.25 x SIFT extraction.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>

#include "bench_util.h"
#include "robot/sim/synthetic_scene.h"
#include "detector/detector.h"
#include "detector/detector_internal.h"

using namespace refgrasp;
using namespace refgrasp::detector;
using namespace refgrasp::testing;

namespace {

using bench::Clock;
using bench::median;
using bench::timeMs;

void usage() {
  std::printf(
      "bench_detector: median time of each detector stage on seeded 640x480 cluttered frames\n"
      "with a 20 cm target at 0.3-1.2 m (tilt 0-50 deg, noise 2, mild motion blur).\n"
      "Rows: SIFT extraction alone, paper matcher, ratio matcher, paper pose, refined pose,\n"
      "whole detection (Detector::detect: paper matcher + default pose), and whole / SIFT.\n"
      "Bar: whole / SIFT <= 1.25 (median over frames).\n"
      "Usage: bench_detector [--frames N (default 24)] [--texture media/relative.png]\n"
      "                      [--seed S (default 1)] [--help]\n");
}

}  // namespace

int main(int argc, char** argv) {
  int frames = 24;
  uint64_t seed = 1;
  std::string texture = "targets/poster_concert.png";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else if (a == "--frames" && i + 1 < argc) {
      frames = static_cast<int>(bench::intArg("bench_detector", "--frames", argv[++i], 1));
    } else if (a == "--seed" && i + 1 < argc) {
      seed = static_cast<uint64_t>(bench::intArg("bench_detector", "--seed", argv[++i], 0));
    } else if (a == "--texture" && i + 1 < argc) {
      texture = argv[++i];
    } else {
      std::fprintf(stderr, "bench_detector: unknown argument '%s' (see --help)\n", a.c_str());
      return 2;
    }
  }
  const cv::Mat tex = loadMedia(texture);
  const double w = 0.2, h = w * tex.rows / tex.cols;
  const Intrinsics cam = sceneCamera();
  Detector det;
  const int id = det.addObject(textureObject("target", tex, w));
  MatchOptions ratio_opt = det.options().match;
  ratio_opt.matcher = MatcherType::kRatio;

  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> blur(0.0, 1.5), angle(0, M_PI);
  std::vector<double> t_sift, t_paper, t_ratio, t_ppose, t_rpose, t_whole, ratio_whole;
  int found = 0, n_features = 0;
  for (int i = 0; i < frames; ++i) {
    SceneSpec spec;
    spec.cMo = randomVisiblePose(rng, cam, w, h, 0.3, 1.2, 50 * M_PI / 180);
    spec.motion_blur_px = blur(rng);
    spec.motion_blur_angle_rad = angle(rng);
    spec.seed = seed * 1000 + i;
    const cv::Mat img = renderTarget(cam, tex, w, h, spec).image;

    Features f;
    const double sift = timeMs([&] { f = extractSift(img, det.options().sift); });
    n_features += f.size();
    f.image = img;  // as DetectorInternals::extract keeps it: the refined pose refines H densely (ECC)
    const GridIndex grid(f.keypoints, f.image_size);
    MatchResult mp, mr;
    t_paper.push_back(timeMs([&] { mp = matchObject(DetectorInternals::referenceIndex(det, id), f, grid, det.options().match); }));
    t_ratio.push_back(timeMs([&] { mr = matchObject(DetectorInternals::referenceIndex(det, id), f, grid, ratio_opt); }));
    if (!mp.instances.empty()) {
      t_ppose.push_back(timeMs([&] { DetectorInternals::estimatePose(det, id, mp.instances[0], f, cam, PoseMethod::kPaper); }));
      t_rpose.push_back(timeMs([&] { DetectorInternals::estimatePose(det, id, mp.instances[0], f, cam, PoseMethod::kRefined); }));
    }
    DetectionResult r;
    const double whole = timeMs([&] { r = det.detect(img, cam); });
    if (r.find(id)) ++found;
    t_sift.push_back(sift);
    t_whole.push_back(whole);
    ratio_whole.push_back(whole / sift);
  }
  std::printf("bench_detector: %d frames 640x480, %.0f scene features on average, %d reference "
              "features, found %d/%d\n",
              frames, static_cast<double>(n_features) / frames,
              DetectorInternals::referenceIndex(det, id).features.size(), found, frames);
  std::printf("| stage                              | median ms |\n|---|---|\n");
  std::printf("| SIFT extraction alone              | %9.2f |\n", median(t_sift));
  std::printf("| paper matcher                      | %9.2f |\n", median(t_paper));
  std::printf("| ratio matcher                      | %9.2f |\n", median(t_ratio));
  std::printf("| paper pose (eq. 7 + LM, 4 corners) | %9.3f |\n", median(t_ppose));
  std::printf("| refined pose (ECC H + IPPE + LM)   | %9.3f |\n", median(t_rpose));
  std::printf("| whole detection (detect, %-7s)  | %9.2f |\n", poseMethodName(det.options().pose),
              median(t_whole));
  const double bar = median(ratio_whole);
  std::printf("| whole / SIFT (median of per-frame) | %9.3f |\n", bar);
  std::printf("bar whole <= 1.25 x SIFT: %s\n", bar <= 1.25 ? "MET" : "NOT MET");
  return 0;
}
