// refgrasp vs the classic OpenCV pipeline on photo pairs (issue 7, src/eval/pairs_eval.h): a
// reference photo and a scene photo of a planar picture, 2D only, in seven families (viewpoint,
// zoom+rotation, blur, light, JPEG, and near-identity pairs at full resolution under other light
// or JPEG) at five levels each; scored by the reference's corners mapped
// by the reported homography. Prints a markdown table per family and level.
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <cstdio>
#include <fstream>
#include <string>

#include "bench_util.h"
#include "detector/detector.h"
#include "detector/detector_config.h"
#include "detector/detector_internal.h"
#include "detector/homography.h"
#include "detector/object.h"
#include "eval/classic.h"
#include "eval/pairs_eval.h"

using namespace refgrasp;

namespace {

void usage() {
  std::printf(
      "bench_pairs: refgrasp vs the classic OpenCV pipeline (cv::SIFT, ratio 0.8, RANSAC 3 px,\n"
      ">= 10 inliers) on photo pairs of planar pictures (10 pictures x 7 families x 5 levels per\n"
      "seed), each reference registered 2D-only; scored by the worst of its 4 corners mapped by\n"
      "the reported homography. One thread each (cv::setNumThreads(1)); times are thread CPU time.\n"
      "Usage: bench_pairs [--seeds N (1)] [--first-seed S (1001 = the report split; develop on 1)]\n"
      "       [--family viewpoint|zoom+rotation|blur|light|jpeg|near-light|near-jpeg (that one\n"
      "       alone)] [--verbose (one\n"
      "       line per pair)] [--tolerance PX (3)] [--detector-config FILE] [--csv FILE] [--dump DIR (write the\n"
      "       pairs of the first seed as DIR/<family>_<level>_<picture>_{ref,scene}.png, no\n"
      "       evaluation)] [--diagnose (per pair of the first seed: the matcher's candidate, its\n"
      "       inliers' residuals under the true homography, beside the classic pipeline's)] [--help]\n");
}

}  // namespace

int main(int argc, char** argv) try {
  int seeds = 1;
  uint64_t first = 1001;
  double tol = 3;
  std::string csv, dump;
  int family = -1;
  bool verbose = false, diagnose = false;
  detector::DetectorOptions opt;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else if (a == "--seeds" && i + 1 < argc) {
      seeds = static_cast<int>(bench::intArg("bench_pairs", "--seeds", argv[++i], 1));
    } else if (a == "--first-seed" && i + 1 < argc) {
      first = static_cast<uint64_t>(bench::intArg("bench_pairs", "--first-seed", argv[++i], 0));
    } else if (a == "--tolerance" && i + 1 < argc) {
      tol = bench::numberArg("bench_pairs", "--tolerance", argv[++i], 0.01);
    } else if (a == "--detector-config" && i + 1 < argc) {
      try {
        opt = detector::loadDetectorOptions(argv[++i]);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "bench_pairs: %s\n", e.what());
        return 2;
      }
    } else if (a == "--family" && i + 1 < argc) {
      const std::string name = argv[++i];
      for (int f = 0; f < eval::kPairFamilies; ++f)
        if (name == eval::pairFamilyName(static_cast<eval::PairFamily>(f))) family = f;
      if (family < 0) {
        std::fprintf(stderr, "bench_pairs: --family: expected viewpoint, zoom+rotation, blur, light, jpeg, near-light or near-jpeg, got '%s'\n",
                     name.c_str());
        return 2;
      }
    } else if (a == "--diagnose") {
      diagnose = true;
    } else if (a == "--verbose") {
      verbose = true;
    } else if (a == "--csv" && i + 1 < argc) {
      csv = argv[++i];
    } else if (a == "--dump" && i + 1 < argc) {
      dump = argv[++i];
    } else {
      bench::rejectArgument("bench_pairs", a, {"--seeds", "--first-seed", "--tolerance", "--detector-config", "--family", "--csv", "--dump"});
    }
  }
  std::ofstream csv_out;  // opened before the run: a path that cannot be written fails at once
  if (!csv.empty()) bench::openOutput("bench_pairs", csv, csv_out);
  if (!dump.empty()) bench::requireFolder("bench_pairs", "--dump", dump);
  cv::setNumThreads(1);
  opt.sift.threads = 1;
  if (!dump.empty()) {
    const std::vector<std::string> textures = eval::pairTextures();
    for (int f = 0; f < eval::kPairFamilies; ++f)
      for (int l = 0; l < eval::kPairLevels; ++l)
        for (size_t k = 0; k < textures.size(); ++k) {
          const std::string& t = textures[k];
          const eval::ViewPair p =
              eval::makeViewPair(t, static_cast<eval::PairFamily>(f), l, eval::pairSeed(first, static_cast<int>(k)));
          std::string name = t.substr(t.find('/') + 1);
          name = name.substr(0, name.find('.'));
          const std::string stem = dump + "/" + eval::pairFamilyName(p.family) + "_" + std::to_string(l) + "_" + name;
          if (!cv::imwrite(stem + "_ref.png", p.reference) || !cv::imwrite(stem + "_scene.png", p.scene)) {
            std::fprintf(stderr, "bench_pairs: %s: cannot write (does the folder exist?)\n", (stem + "_ref.png").c_str());
            return 1;
          }
        }
    return 0;
  }
  if (diagnose) {
    const std::vector<std::string> textures = eval::pairTextures();
    for (int f = 0; f < eval::kPairFamilies; ++f) {
      if (family >= 0 && f != family) continue;
      for (int l = 0; l < eval::kPairLevels; ++l)
        for (size_t k = 0; k < textures.size(); ++k) {
          const std::string& t = textures[k];
          const eval::ViewPair p =
              eval::makeViewPair(t, static_cast<eval::PairFamily>(f), l, eval::pairSeed(first, static_cast<int>(k)));
          const auto model = detector::makeObjectModel(t, p.reference, std::nullopt, std::nullopt);
          detector::Detector det(opt);
          det.addObject(model);
          const auto& ref = detector::DetectorInternals::referenceIndex(det, 0);
          const detector::Features sc = detector::DetectorInternals::extract(det, p.scene, p.camera);
          const detector::GridIndex grid(sc.keypoints, sc.image_size);
          const detector::MatchResult m = detector::matchObject(ref, sc, grid, opt.match);
          std::printf("%s %d %s: ref %d kps, scene %d kps, global %d, hyps %d", eval::pairFamilyName(p.family), l,
                      t.c_str(), ref.features.size(), sc.size(), m.global_matches, m.hypotheses_evaluated);
          if (!m.instances.empty()) {
            const auto& c = m.instances[0];
            std::vector<double> res;
            for (const auto& x : c.inliers) {
              const auto& a = ref.features.keypoints[x.ref].pt;
              const auto& b = sc.keypoints[x.scene].pt;
              res.push_back((detector::applyHomography(p.H_true, Eigen::Vector2d(a.x, a.y)) - Eigen::Vector2d(b.x, b.y)).norm());
            }
            std::sort(res.begin(), res.end());
            std::printf(" | match: %zu inliers, corner %.2f px, true residual median %.2f p90 %.2f max %.2f",
                        c.inliers.size(), eval::worstCornerError(p, c.H), res[res.size() / 2], res[res.size() * 9 / 10],
                        res.back());
          } else {
            std::printf(" | match: none (local %d, inliers %d, nfa %d, implausible %d, spread %d)",
                        m.rejected.too_few_local_matches, m.rejected.too_few_inliers, m.rejected.not_significant,
                        m.rejected.implausible_homography, m.rejected.narrow_inlier_spread);
          }
          const auto d = det.detect(p.scene, p.camera);
          if (const auto x = d.find(0))
            std::printf(" | detect: corner %.2f px", eval::worstCornerError(p, x->H));
          else
            std::printf(" | detect: %s", d.stats.empty() ? d.error.c_str() : detector::missReasonName(d.stats[0].miss));
          const eval::ClassicResult c = eval::ClassicPipeline(model).detect(p.scene, p.camera);
          std::printf(" | classic: %d inliers, corner %.2f px\n", c.inliers, c.found ? eval::worstCornerError(p, c.H) : -1.0);
        }
    }
    return 0;
  }
  const auto rows = eval::evaluatePairs(opt, seeds, first, family, [](int i, int n) {
    std::fprintf(stderr, "\rpair %d/%d", i, n);
  });
  std::fprintf(stderr, "\n");
  if (verbose)
    for (const auto& r : rows)
      std::printf("%s %d %s seed %llu: refgrasp %s %.2f px %d inliers %s| classic %s %.2f px %d inliers\n",
                  eval::pairFamilyName(r.family), r.level, r.texture.c_str(), static_cast<unsigned long long>(r.seed),
                  r.r_reported ? "reported" : "missed", r.r_err, r.r_inliers, r.r_miss.c_str(),
                  r.c_reported ? "reported" : "missed", r.c_err, r.c_inliers);
  std::printf("Photo pairs, seeds %llu..%llu\n\n%s", static_cast<unsigned long long>(first),
              static_cast<unsigned long long>(first + seeds - 1), eval::formatPairTables(rows, tol).c_str());
  if (csv_out.is_open()) {
    std::ofstream& o = csv_out;
    o << "family,level,picture,seed,r_reported,r_err_px,r_inliers,r_miss,c_reported,c_err_px,c_inliers,r_ms,c_ms\n";
    for (const auto& r : rows)
      o << eval::pairFamilyName(r.family) << ',' << r.level << ',' << r.texture << ',' << r.seed << ',' << r.r_reported
        << ',' << r.r_err << ',' << r.r_inliers << ',' << r.r_miss << ',' << r.c_reported << ',' << r.c_err << ','
        << r.c_inliers << ',' << r.r_ms << ',' << r.c_ms << '\n';
    o.flush();
    if (!o) {
      std::fprintf(stderr, "bench_pairs: %s: cannot write\n", csv.c_str());
      return 1;
    }
  }
  return 0;
}
catch (const std::exception& e) {  // a missing or unreadable input: one line, not an abort
  std::fprintf(stderr, "bench_pairs: %s\n", e.what());
  return 1;
}
