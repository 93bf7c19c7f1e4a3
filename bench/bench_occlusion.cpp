// Occlusion by textured occluders (src/eval/occlusion_eval.h): a card cut from a real photograph
// slides over the target (10-60 % of it covered) while the camera sways. Prints, per cover bin,
// single-frame detection (refgrasp with and without the reference pose, the classic pipeline:
// reported / found / wrong) and the tracking pipeline (3D and 2D-only: tracked / lost / wrong).
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <cstdio>
#include <fstream>
#include <string>

#include "bench_util.h"
#include "eval/occlusion_eval.h"

using namespace refgrasp;

namespace {

void usage() {
  std::printf(
      "bench_occlusion: detection and tracking while a card cut from a real photograph slides over\n"
      "the target (10-60 %% covered), one thread.\n"
      "Usage: bench_occlusion [--sequences N (8)] [--frames N per sequence (80)] [--seed S (1001 =\n"
      "       the report split; develop on 1)] [--no-tracking] [--no-detection]\n"
      "       [--dump DIR (write every 10th frame of each sequence, no evaluation)] [--csv FILE] [--help]\n");
}

}  // namespace

int main(int argc, char** argv) try {
  int sequences = 8, frames = 80;
  uint64_t seed = 1001;
  std::string csv, dump;
  eval::OcclusionOptions opt;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else if (a == "--sequences" && i + 1 < argc) {
      sequences = static_cast<int>(bench::intArg("bench_occlusion", "--sequences", argv[++i], 1));
    } else if (a == "--frames" && i + 1 < argc) {
      frames = static_cast<int>(bench::intArg("bench_occlusion", "--frames", argv[++i], 2));
    } else if (a == "--seed" && i + 1 < argc) {
      seed = static_cast<uint64_t>(bench::intArg("bench_occlusion", "--seed", argv[++i], 0));
    } else if (a == "--no-tracking") {
      opt.tracking = false;
    } else if (a == "--no-detection") {
      opt.detection = false;
    } else if (a == "--dump" && i + 1 < argc) {
      dump = argv[++i];
    } else if (a == "--csv" && i + 1 < argc) {
      csv = argv[++i];
    } else {
      bench::rejectArgument("bench_occlusion", a, {"--sequences", "--frames", "--seed", "--dump", "--csv"});
    }
  }
  if (!dump.empty()) bench::requireFolder("bench_occlusion", "--dump", dump);
  cv::setNumThreads(1);
  opt.detector.sift.threads = 1;
  std::ofstream out;  // opened before the run: a path that cannot be written fails at once
  if (!csv.empty()) {
    bench::openOutput("bench_occlusion", csv, out);
    out << "sequence,texture,occluder,frame,covered,r_reported,r_found,r_corner_px,r_inliers,r_correlation,"
           "r2_reported,r2_found,r2_corner_px,c_reported,c_found,c_corner_px,t3_tracked,t3_found,t3_corner_px,"
           "t2_tracked,t2_found,t2_corner_px,r_miss\n";
  }
  std::vector<eval::OcclusionRow> all;
  const auto specs = eval::occlusionSequences(seed, sequences, frames);
  for (size_t k = 0; k < specs.size(); ++k) {
    const eval::OcclusionSequence seq(specs[k]);
    if (!dump.empty()) {
      for (int i = 0; i < seq.frames(); i += 10) {
        const std::string name = dump + "/occlusion_" + std::to_string(k) + "_" + std::to_string(i) + ".png";
        const eval::OcclusionFrame f = seq.frame(i);
        cv::Mat shown = f.frame.image.clone();  // the true pattern outline drawn on it
        std::vector<cv::Point> quad;
        for (const auto& c : f.frame.corners) quad.emplace_back(cvRound(c.x()), cvRound(c.y()));
        cv::polylines(shown, quad, true, cv::Scalar(255), 1);
        if (!cv::imwrite(name, shown)) {
          std::fprintf(stderr, "bench_occlusion: %s: cannot write\n", name.c_str());
          return 1;
        }
      }
      if (!cv::imwrite(dump + "/occlusion_" + std::to_string(k) + "_ref.png", seq.object().photo.image)) return 1;
      continue;
    }
    const auto rows = eval::evaluateOcclusion(seq, static_cast<int>(k), opt);
    std::fprintf(stderr, "sequence %zu/%zu: %s under %s\n", k + 1, specs.size(), specs[k].texture.c_str(),
                 specs[k].occluder.c_str());
    for (const auto& r : rows) {
      if (out.is_open())
        out << k << ',' << specs[k].texture << ',' << specs[k].occluder << ',' << r.frame << ',' << r.covered << ','
            << r.refgrasp.reported << ',' << r.refgrasp.found << ',' << r.refgrasp.corner_px << ','
            << r.refgrasp.inliers << ',' << r.refgrasp.correlation << ',' << r.refgrasp_2d.reported << ','
            << r.refgrasp_2d.found << ',' << r.refgrasp_2d.corner_px << ',' << r.classic.reported << ','
            << r.classic.found << ',' << r.classic.corner_px << ',' << r.tracked_3d.reported << ','
            << r.tracked_3d.found << ',' << r.tracked_3d.corner_px << ',' << r.tracked_2d.reported << ','
            << r.tracked_2d.found << ',' << r.tracked_2d.corner_px << ',' << r.miss << '\n';
      all.push_back(r);
    }
  }
  if (out.is_open() && !out.flush()) {
    std::fprintf(stderr, "bench_occlusion: %s: cannot write\n", csv.c_str());
    return 1;
  }
  if (dump.empty())
    std::printf("%d sequences x %d frames, seed %llu\n\n%s", sequences, frames, static_cast<unsigned long long>(seed),
                eval::formatOcclusionTable(all, opt).c_str());
  return 0;
}
catch (const std::exception& e) {  // a missing or unreadable input: one line, not an abort
  std::fprintf(stderr, "bench_occlusion: %s\n", e.what());
  return 1;
}
