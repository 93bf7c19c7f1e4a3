// refgrasp vs the classic OpenCV pipeline on the realistic sets (issue 7, src/eval/): reference
// photographs (oblique, other camera and light, traced polygon regions) and scenes with real
// camera effects at stratified distances and tilts. Prints one markdown table per set by
// distance, tilt and target size (found, pose ok, false positives, median errors, time), the
// bins where refgrasp finds less than the classic pipeline, and false positives on photo clutter.
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <optional>
#include <random>
#include <string>

#include "bench_util.h"
#include "detector/detector.h"
#include "detector/detector_config.h"
#include "detector/detector_internal.h"
#include "detector/homography.h"
#include <opencv2/imgproc.hpp>
#include "eval/realistic_eval.h"

using namespace refgrasp;

namespace {

void usage() {
  std::printf(
      "bench_realistic: refgrasp vs the classic OpenCV pipeline (cv::SIFT, ratio 0.8, RANSAC 3 px,\n"
      ">= 10 inliers, IPPE + LM) on the realistic sets, the same frames, one thread each\n"
      "(cv::setNumThreads(1)); times are thread CPU time (--wall: wall clock).\n"
      "Usage: bench_realistic [--frames N per set (160)] [--seed S (1001 = the report split;\n"
      "       develop on 1)] [--set photos|procedural|far_oblique] [--clutter N frames (100)]\n"
      "       [--2d (objects without their reference pose: corners only)]\n"
      "       [--pose paper|refined] [--min-inliers N] [--max-log10-nfa X] [--count-rule (no\n"
      "       a-contrario test: min_inliers alone)] [--min-correlation C] [--no-verify] [--no-realign]\n"
      "       [--detector-config FILE (options YAML; the flags after it override it)]\n"
      "       [--min-distance-bin N (only frames of distance bins >= N)]\n"
      "       [--dump DIR (write the references and 12 frames per set, no evaluation)]\n"
      "       [--pose-bounds (what one frame allows, no detection: the pose from the true corners\n"
      "       with noise, the dense alignment started at the true pose and at its mirror)]\n"
      "       [--classic-fast (the classic pipeline reuses the fast SIFT\n"
      "       features: same results, no classic timing, no classic on the clutter)] [--wall]\n"
      "       [--csv FILE] [--help]\n");
}

// The two poses IPPE finds for the frame's four true texture corners (cMo, object frame on the
// texture plane, metres, radians): the truth and, when the view is not degenerate, its mirror.
std::vector<Pose> ippeSolutions(const eval::SetFrame& f, const std::array<Eigen::Vector2d, 4>& corners_px,
                                const std::vector<cv::Point3d>& plane_pts) {
  const Eigen::Matrix3d K = f.camera.K();
  cv::Mat Kcv(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) Kcv.at<double>(r, c) = K(r, c);
  std::vector<cv::Point2d> img;
  for (const auto& c : corners_px) img.emplace_back(c.x(), c.y());
  std::vector<cv::Mat> rv, tv;
  cv::solvePnPGeneric(plane_pts, img, Kcv, cv::noArray(), rv, tv, false, cv::SOLVEPNP_IPPE);
  std::vector<Pose> out;
  for (size_t k = 0; k < rv.size() && k < tv.size(); ++k)
    out.push_back(Pose::fromRotationVector(Eigen::Vector3d(rv[k].at<double>(0), rv[k].at<double>(1), rv[k].at<double>(2)),
                                           Eigen::Vector3d(tv[k].at<double>(0), tv[k].at<double>(1), tv[k].at<double>(2))));
  return out;
}

// --pose-bounds: what one frame allows on the frames of distance bins >= min_bin, without
// detection. (1) The pose (IPPE's better solution) from the four true corners with Gaussian
// noise of sigma px on each coordinate, 200 draws: the pose-ok count expected from a detector
// whose corners are that precise. (2) The dense alignment (Detector::alignPose) started at the
// true pose: the most the refined pose can give a perfect detection. (3) Started at
// IPPE's other solution of the true corners (the mirror): how often it stays there (> 10 deg
// off) and how often the truth's start correlates higher, i.e. whether the correlation could
// choose between the two.
void poseBounds(const eval::RealisticSet& set, int min_bin, const detector::DetectorOptions& base) {
  const auto& spec = set.spec();
  const std::vector<double> sigmas = {0.1, 0.2, 0.3, 0.5};
  std::vector<double> expected(sigmas.size(), 0);
  int frames = 0, aligned = 0, ok = 0, mirrors = 0, stays = 0, truth_higher = 0;
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0, 1);
  const int bins = static_cast<int>(spec.distance_edges_m.size()) - 1;
  std::vector<std::unique_ptr<detector::Detector>> detectors(set.objects().size());
  for (int i = 0; i < set.frames(); ++i) {
    if (i % bins < min_bin) continue;  // frames cycle through the distance bins
    const eval::SetFrame f = set.frame(i);
    ++frames;
    std::fprintf(stderr, "\r%s %d/%d", spec.name.c_str(), i + 1, set.frames());
    // The corners in the object frame: the true pixels back-projected onto the texture plane.
    const Eigen::Matrix3d Ki = f.camera.K().inverse();
    const Eigen::Vector3d n = f.cMo.R.col(2);
    std::vector<cv::Point3d> plane;
    for (const auto& c : f.corners) {
      const Eigen::Vector3d ray = Ki * c.homogeneous();
      const Eigen::Vector3d Xo = f.cMo.R.transpose() * (n.dot(f.cMo.t) / n.dot(ray) * ray - f.cMo.t);
      plane.emplace_back(Xo.x(), Xo.y(), 0.0);
    }
    for (size_t s = 0; s < sigmas.size(); ++s) {
      int good = 0;
      for (int d = 0; d < 200; ++d) {
        std::array<Eigen::Vector2d, 4> noisy = f.corners;
        for (auto& c : noisy) c += sigmas[s] * Eigen::Vector2d(noise(rng), noise(rng));
        const std::vector<Pose> sol = ippeSolutions(f, noisy, plane);
        good += !sol.empty() && eval::poseWithinTolerance(sol.front(), f.cMo);
      }
      expected[s] += good / 200.0;
    }
    // One detector per object: registering computes the reference's features.
    std::unique_ptr<detector::Detector>& det_ptr = detectors[static_cast<size_t>(f.object)];
    if (!det_ptr) {
      det_ptr = std::make_unique<detector::Detector>(base);
      det_ptr->addObject(set.objects()[static_cast<size_t>(f.object)].model);
    }
    const detector::Detector& det = *det_ptr;
    const detector::PoseAlignment from_truth = det.alignPose(f.image, f.camera, 0, f.cMo);
    aligned += from_truth.ok;
    ok += from_truth.ok && eval::poseWithinTolerance(from_truth.cMo, f.cMo);
    std::optional<Pose> mirror;
    for (const Pose& p : ippeSolutions(f, f.corners, plane))
      if (rotationError(p, f.cMo) > 0.5 * M_PI / 180) mirror = p;
    if (!mirror || !from_truth.ok) continue;
    const detector::PoseAlignment m = det.alignPose(f.image, f.camera, 0, *mirror);
    if (!m.ok) continue;
    ++mirrors;
    stays += rotationError(m.cMo, f.cMo) > 10 * M_PI / 180;
    truth_higher += from_truth.correlation > m.correlation;
  }
  std::fprintf(stderr, "\n");
  std::printf("Set %s, %d frames of distance bins >= %d (%.1f m and more):\n", spec.name.c_str(), frames, min_bin,
              spec.distance_edges_m[static_cast<size_t>(std::min<int>(min_bin, static_cast<int>(spec.distance_edges_m.size()) - 1))]);
  std::printf("  pose ok expected from the true corners with noise:");
  for (size_t s = 0; s < sigmas.size(); ++s) std::printf(" sigma %.1f px %.1f%s", sigmas[s], expected[s], s + 1 < sigmas.size() ? "," : "\n");
  std::printf("  dense alignment from the true pose: aligned %d, pose ok %d\n", aligned, ok);
  std::printf("  from the mirror pose (%d aligned from both): stays mirrored %d, the truth's start correlates higher %d\n",
              mirrors, stays, truth_higher);
}

}  // namespace

int main(int argc, char** argv) try {
  int frames = 160, clutter = 100, min_bin = 0;
  uint64_t seed = 1001;
  std::string only, csv, dump;
  bool diagnose = false, bounds = false;
  eval::EvalOptions opt;
  opt.time_sift = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else if (a == "--frames" && i + 1 < argc) {
      frames = static_cast<int>(bench::intArg("bench_realistic", "--frames", argv[++i], 1));
    } else if (a == "--clutter" && i + 1 < argc) {
      clutter = static_cast<int>(bench::intArg("bench_realistic", "--clutter", argv[++i], 0));
    } else if (a == "--seed" && i + 1 < argc) {
      seed = static_cast<uint64_t>(bench::intArg("bench_realistic", "--seed", argv[++i], 0));
    } else if (a == "--set" && i + 1 < argc) {
      only = argv[++i];
    } else if (a == "--pose" && i + 1 < argc) {
      const std::string p = argv[++i];
      if (p != "paper" && p != "refined") {
        std::fprintf(stderr, "bench_realistic: --pose: expected paper or refined, got '%s'\n", p.c_str());
        return 2;
      }
      opt.detector.pose = p == "paper" ? detector::PoseMethod::kPaper : detector::PoseMethod::kRefined;
    } else if (a == "--min-inliers" && i + 1 < argc) {
      opt.detector.match.min_inliers = static_cast<int>(bench::intArg("bench_realistic", "--min-inliers", argv[++i], 4));
    } else if (a == "--max-log10-nfa" && i + 1 < argc) {
      opt.detector.match.max_log10_nfa = bench::numberArg("bench_realistic", "--max-log10-nfa", argv[++i], -1e9);
    } else if (a == "--count-rule") {
      opt.detector.match.max_log10_nfa = HUGE_VAL;
    } else if (a == "--min-correlation" && i + 1 < argc) {
      opt.detector.verify.min_correlation = bench::numberArg("bench_realistic", "--min-correlation", argv[++i], -1);
    } else if (a == "--2d") {
      opt.two_d = true;
    } else if (a == "--no-verify") {
      opt.detector.verify.enabled = false;
    } else if (a == "--no-realign") {
      opt.detector.verify.realign = false;
    } else if (a == "--classic-fast") {
      opt.classic_own_sift = false;
    } else if (a == "--wall") {
      opt.cpu_time = false;
    } else if (a == "--detector-config" && i + 1 < argc) {
      try {
        opt.detector = detector::loadDetectorOptions(argv[++i]);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "bench_realistic: %s\n", e.what());
        return 2;
      }
    } else if (a == "--min-distance-bin" && i + 1 < argc) {
      min_bin = static_cast<int>(bench::intArg("bench_realistic", "--min-distance-bin", argv[++i], 0));
    } else if (a == "--pose-bounds") {
      bounds = true;
    } else if (a == "--diagnose") {
      diagnose = true;
    } else if (a == "--dump" && i + 1 < argc) {
      dump = argv[++i];
    } else if (a == "--csv" && i + 1 < argc) {
      csv = argv[++i];
    } else {
      bench::rejectArgument("bench_realistic", a, {"--frames", "--clutter", "--seed", "--set", "--pose", "--min-inliers", "--max-log10-nfa", "--min-correlation", "--detector-config", "--min-distance-bin", "--dump", "--csv", "--pose-bounds"});
    }
  }
  if (bounds && (opt.two_d || !csv.empty() || !dump.empty())) {  // it measures poses and writes no rows
    std::fprintf(stderr, "bench_realistic: --pose-bounds: not with --2d, --csv or --dump\n");
    return 2;
  }
  const std::vector<eval::RealisticSetSpec> specs = eval::realisticSets(seed, frames);
  std::string names;  // "photos, procedural or far_oblique"
  for (size_t k = 0; k < specs.size(); ++k)
    names += (k == 0 ? "" : k + 1 == specs.size() ? " or " : ", ") + specs[k].name;
  if (!only.empty() && std::none_of(specs.begin(), specs.end(), [&](const auto& sp) { return sp.name == only; })) {
    std::fprintf(stderr, "bench_realistic: --set: expected %s, got '%s'\n", names.c_str(), only.c_str());
    return 2;
  }
  for (const auto& spec : specs) {
    const int D = static_cast<int>(spec.distance_edges_m.size()) - 1;
    if (min_bin >= D) {
      std::fprintf(stderr, "bench_realistic: --min-distance-bin: expected an integer <= %d, got '%d'\n", D - 1, min_bin);
      return 2;
    }
  }
  if (!dump.empty()) bench::requireFolder("bench_realistic", "--dump", dump);
  cv::setNumThreads(1);
  opt.detector.sift.threads = 1;
  std::ofstream rows;  // opened before the run: a path that cannot be written fails at once
  if (!csv.empty()) {
    bench::openOutput("bench_realistic", csv, rows);
    rows << "set,frame,object,distance_m,tilt_deg,size_px,r_found,r_pose_ok,r_wrong,r_corner_px,r_rot_deg,r_rel_t,"
            "r_inliers,r_miss,c_found,c_pose_ok,c_wrong,c_corner_px,c_rot_deg,c_rel_t,c_inliers,r_ms,c_ms,sift_ms,r_log10_nfa,r_correlation\n";
  }
  std::vector<std::string> losses;
  std::vector<eval::SetObject> all_objects;
  for (const auto& spec : specs) {
    if (!only.empty() && spec.name != only) continue;
    const eval::RealisticSet set(spec);
    if (!dump.empty()) {  // the references and the first frames, to look at
      const auto write = [&](const std::string& name, const cv::Mat& image) {
        if (!cv::imwrite(dump + "/" + name, image)) {
          std::fprintf(stderr, "bench_realistic: %s/%s: cannot write\n", dump.c_str(), name.c_str());
          std::exit(1);
        }
      };
      for (size_t k = 0; k < set.objects().size(); ++k)
        write(spec.name + "_ref_" + std::to_string(k) + ".png", set.objects()[k].photo.image);
      for (int i = 0; i < std::min(frames, 12); ++i) write(spec.name + "_frame_" + std::to_string(i) + ".png", set.frame(i).image);
      continue;
    }
    if (bounds) {
      poseBounds(set, min_bin, opt.detector);
      continue;
    }
    if (diagnose) {  // the upper bound: true correspondences present in the frames
      const int D = static_cast<int>(spec.distance_edges_m.size()) - 1;
      for (int i = 0; i < set.frames(); ++i) {
        if (i % D < min_bin) continue;
        const eval::SetFrame f = set.frame(i);
        detector::Detector det(opt.detector);
        det.addObject(set.objects()[f.object].model);
        const auto& ref = detector::DetectorInternals::referenceIndex(det, 0);
        const detector::Features sc = detector::DetectorInternals::extract(det, f.image, f.camera);
        const auto& o = set.objects()[f.object];
        std::vector<Eigen::Vector2d> a(o.photo.corners_px.begin(), o.photo.corners_px.end()), b(f.corners.begin(), f.corners.end());
        const Eigen::Matrix3d H = detector::fitHomographyLeastSquares(a, b);
        const auto nn = detector::nearestTwo(ref, sc);
        int inside = 0, pairs = 0, nn_ok = 0, ratio_ok = 0, d300 = 0;
        std::vector<cv::Point2f> quad;
        for (const auto& c : f.corners) quad.emplace_back(c.x(), c.y());
        for (int j = 0; j < sc.size(); ++j) {
          if (cv::pointPolygonTest(quad, sc.keypoints[j].pt, false) < 0) continue;
          ++inside;
          int best = -1;
          double bd = 2.0;
          for (int r = 0; r < ref.features.size(); ++r) {
            const auto& k = ref.features.keypoints[r];
            const Eigen::Vector2d p = detector::applyHomography(H, Eigen::Vector2d(k.pt.x, k.pt.y));
            const double d = (p - Eigen::Vector2d(sc.keypoints[j].pt.x, sc.keypoints[j].pt.y)).norm();
            if (d < bd) { bd = d; best = r; }
          }
          if (best < 0) continue;
          ++pairs;
          const double dd = cv::norm(ref.features.descriptors.row(best), sc.descriptors.row(j));
          d300 += dd < 300;
          nn_ok += nn[j].best == best;
          ratio_ok += nn[j].best == best && nn[j].d1 < 0.64 * nn[j].d2;
        }
        std::printf("%s frame %d dist %.2f size %.0f: scene kps in target %d, with a ref kp within 2 px %d, "
                    "desc < 300 %d, global NN right %d, + ratio 0.8 %d (ref %d kps)\n", spec.name.c_str(), i,
                    f.distance_m, f.size_px, inside, pairs, d300, nn_ok, ratio_ok, ref.features.size());
      }
      continue;
    }
    opt.min_distance_bin = min_bin;
    const auto out = eval::evaluateSet(set, opt, 0, set.frames(), [&](int i) {
      std::fprintf(stderr, "\r%s %d/%d", spec.name.c_str(), i + 1, set.frames());
    });
    std::fprintf(stderr, "\n");
    std::printf("%s\n", eval::formatTables(spec, out).c_str());
    for (const auto& l : eval::binsWhereRefgraspLoses(spec, out)) losses.push_back(l);
    if (spec.name != "far_oblique")
      for (const auto& o : set.objects()) all_objects.push_back(o);
    for (const auto& r : out)
      if (rows.is_open())
        rows << spec.name << ',' << r.frame << ',' << set.objects()[r.object].model.name << ',' << r.distance_m << ','
             << r.tilt_rad * 180 / M_PI << ',' << r.size_px << ',' << r.refgrasp.found << ',' << r.refgrasp.pose_ok << ','
             << (r.refgrasp.reported && !r.refgrasp.found) << ',' << r.refgrasp.corner_px << ',' << r.refgrasp.rot_deg
             << ',' << r.refgrasp.rel_t << ',' << r.refgrasp.inliers << ',' << r.miss << ',' << r.classic.found << ','
             << r.classic.pose_ok << ',' << (r.classic.reported && !r.classic.found) << ',' << r.classic.corner_px
             << ',' << r.classic.rot_deg << ',' << r.classic.rel_t << ',' << r.classic.inliers << ','
             << r.refgrasp.ms << ',' << r.classic.ms << ',' << r.sift_ms << ',' << r.refgrasp.log10_nfa << ','
             << r.refgrasp.correlation << '\n';
  }
  if (bounds) return 0;
  if (rows.is_open() && !rows.flush()) {
    std::fprintf(stderr, "bench_realistic: %s: cannot write\n", csv.c_str());
    return 1;
  }
  std::printf("Bins where refgrasp finds less or has fewer poses ok than the classic pipeline: %s\n",
              losses.empty() ? "none" : "");
  for (const auto& l : losses) std::printf("  %s\n", l.c_str());
  if (clutter > 0 && !all_objects.empty()) {
    const eval::ClutterReport c = eval::evaluateClutter(all_objects, opt.detector, clutter, seed, opt.classic_own_sift);
    std::printf("Photo clutter (%d frames, %zu objects registered, siblings sharing a logo or word): "
                "refgrasp %d false detections, classic %d\n",
                c.frames, all_objects.size(), c.detections, c.classic_detections);
    for (const auto& d : c.details) std::printf("  %s\n", d.c_str());
  }
  return 0;
}
catch (const std::exception& e) {  // a missing or unreadable input: one line, not an abort
  std::fprintf(stderr, "bench_realistic: %s\n", e.what());
  return 1;
}
