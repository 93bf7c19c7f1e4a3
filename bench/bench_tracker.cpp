// Timer harness for tracking (servo/tracker.h) and the robot's per-frame pipeline
// (servo/target_tracker.h) on a rendered 640x480 sequence: a camera orbiting a 25 cm target at
// 0.4-1.8 m, tilts to 50 deg, roll, motion blur, noise (robot/sim/synthetic_sequence.h).
// Rows: the tracking step of each tracker (wall and thread CPU medians, frames per second,
// accuracy against the ground truth, frames followed before a loss), then the whole pipeline
// per frame (tracking plus the detections it needs) with and without periodic re-detection,
// against detection on every frame. Bar: tracking step >= 200 frames per second (median).
// Then a 2D-only object (no reference pose: the homography tracker, servo/homography_tracker.h)
// at 640x480 and 1280x720 on a slow sway: the tracking step and the pipeline per frame. Bar:
// 2D-only tracking step >= 30 frames per second at 1280x720 on one core (thread CPU median).
// Last, detection with a prior region (the re-detection servo::TargetTracker runs) against
// whole-frame detection, on the same scene at 640x480 and 1280x720. Bar: prior-region detection
// at 1280x720 within 1.3x of 640x480 (thread CPU median).
#include <array>
#include <opencv2/core.hpp>
#include <cstdio>
#include <string>

#include "bench_util.h"
#include "detector/detector.h"
#include "detector/homography.h"
#include "robot/sim/synthetic_scene.h"
#include "robot/sim/synthetic_sequence.h"
#include "servo/homography_tracker.h"
#include "servo/target_tracker.h"
#include "servo/tracker.h"

using namespace refgrasp;

namespace {

using bench::median;

void usage() {
  std::printf(
      "bench_tracker: the tracking step and the per-frame pipeline on a rendered 640x480 sequence\n"
      "(a camera orbiting a 25 cm target at 0.4-1.8 m, tilts to 50 deg, roll, motion blur, noise).\n"
      "Rows, tracking step: KLT + reference alignment (the default), KLT alone, vpMbGenericTracker\n"
      "(KLT) and vpMbGenericTracker (KLT + moving edges), each started on the first frame's ground\n"
      "truth: wall and thread CPU medians per frame, frames per second from the wall median, frames\n"
      "followed before the first loss (and why it was lost), rotation / translation error median\n"
      "and max. \"fps\" is 1000 / wall median, \"cpu fps\" 1000 / thread CPU median (what one core\n"
      "sustains; the wall figure is only meaningful on a quiet machine).\n"
      "Rows, pipeline per frame (servo::TargetTracker: detect, confirm, track, re-detect): tracking,\n"
      "tracking with a re-detection in the predicted region every 10 frames, and detection on\n"
      "every frame (--no-track): median, 95th percentile and max wall time, median thread CPU,\n"
      "detector calls.\n"
      "Bar: tracking step >= 200 frames per second (wall median).\n"
      "Rows, 2D-only object (registered without reference pose: the homography tracker, KLT +\n"
      "alignment with the reference every frame), at 640x480 (f 550 px) and 1280x720 (f 1100 px)\n"
      "on a slow sway (0.55-0.95 m, tilt to 20 deg, roll): the tracking step started on frame 0's\n"
      "detection (wall and thread CPU medians, fps, cpu fps, frames followed, corner error median /\n"
      "90th percentile px) and the pipeline per frame (track, detect every frame).\n"
      "Bar: 2D-only tracking step >= 30 fps at 1280x720 on one core (thread CPU median).\n"
      "Rows, detection with a prior region, at 640x480 (f 550 px) and 1280x720 (f 1100 px), the\n"
      "same scene (one period of the sway, --prior-frames frames), for the target registered with\n"
      "its pose (3D) and 2D-only: whole-frame detection and detection with the prior the pipeline\n"
      "gives a re-detection, with ObjectPrior::max_scale --prior-max-scale (3D: the previous\n"
      "frame's true pose, TargetTrackerOptions' margins;\n"
      "2D-only: the homography of the previous frame's true pose), each frame: thread CPU median,\n"
      "the stages (extraction / matching / pose + checks: the frame's CPU split as the detector's\n"
      "wall times split it, medians), detections, the largest corner error median / p90 (px) and,\n"
      "3D, the rotation (deg) and translation (%% of the distance) errors median / max; then the\n"
      "1280/640 ratio of the CPU medians.\n"
      "Bar: prior-region detection at 1280x720 within 1.3x of 640x480 (3D and 2D-only).\n"
      "Usage: bench_tracker [--frames N (default 120)] [--texture media/relative.png]\n"
      "                     [--prior-frames N (default 40; 0: skip)] [--prior-max-scale S]\n"
      "                     [--threads N (default 1)] [--help]\n"
      "--prior-max-scale S: ObjectPrior::max_scale of the prior-region rows (default 0.4; 0: the\n"
      "region is never downsampled), for the ablation.\n"
      "--threads N: OpenCV's thread pool size (cv::setNumThreads). With 1 everything runs on the\n"
      "calling thread, so the thread CPU column is the whole cost and holds on a loaded machine.\n");
}

struct Row {
  std::vector<double> wall, cpu, rot_deg, trans_pct;
  int followed = 0;
  int calls = 0;
  template <class F>
  void time(F&& f) {
    double w = 0;
    cpu.push_back(bench::threadCpuMs([&] { w = bench::timeMs(f); }));
    wall.push_back(w);
  }
};

double maxOf(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = std::max(m, x);
  return m;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5))];
}

/// The 2D-only rows at one resolution: the homography tracker's step, then the pipeline.
void twoDRows(const std::string& texture, int frames, int width, int height, double f) {
  testing::TrackingSequenceSpec spec;
  spec.frames = frames;
  spec.texture = texture;
  spec.camera = Intrinsics::pinhole(width, height, f, 0.5 * (width - 1), 0.5 * (height - 1));
  const double cycles = frames / 200.0;
  spec.path = [cycles](double t) { return testing::swayPath(t, cycles); };
  const testing::TrackingSequence seq = testing::renderTrackingSequence(spec);
  const detector::ObjectModel truth_model = detector::textureObject("target", testing::loadMedia(texture), spec.width_m);
  detector::Detector det;
  det.addObject(detector::makeObjectModel("target", testing::loadMedia(texture), std::nullopt, std::nullopt));
  auto cornerError = [&](const std::array<Eigen::Vector2d, 4>& c, size_t k) {
    double e = 0;
    for (size_t i = 0; i < 4; ++i)
      e = std::max(e, (c[i] - seq.camera.project(seq.truth[k] * truth_model.target->corners_o[i])).norm());
    return e;
  };
  Row row;
  std::vector<double> err;
  std::string lost;
  const auto d0 = det.detect(seq.mono[0].image, seq.camera).find(0);
  auto tracker = servo::makeHomographyTracker(det, 0);
  servo::HomographyStep s;
  if (d0) s = tracker->start(seq.mono[0].image, seq.camera, d0->H);
  if (!s.ok) lost = d0 ? "not started: " + s.lost_reason : "not detected in frame 0";
  for (size_t k = 1; k < seq.mono.size() && s.ok; ++k) {
    row.time([&] { s = tracker->track(seq.mono[k].image, seq.camera); });
    if (!s.ok) {
      lost = "lost at frame " + std::to_string(k) + ": " + s.lost_reason;
      break;
    }
    ++row.followed;
    err.push_back(cornerError(s.corners, k));
  }
  const double wall = median(row.wall), cpu = median(row.cpu);
  std::printf("%-34s %9.2f %9.2f %7.0f %7.0f %5d/%-3d %10.3f / %-9.3f\n",
              (std::to_string(width) + "x" + std::to_string(height) + " tracking step").c_str(), wall, cpu,
              1e3 / wall, 1e3 / cpu, row.followed, frames - 1, median(err), percentile(err, 0.9));
  if (!lost.empty()) std::printf("%-34s %s\n", "", lost.c_str());
  for (const bool track : {true, false}) {
    servo::TargetTrackerOptions o;
    o.track = track;
    servo::TargetTracker pipeline(det, o);
    Row p;
    int tracked = 0;
    for (size_t k = 0; k < seq.mono.size(); ++k) {
      servo::TargetFrame fr;
      p.time([&] { fr = pipeline.process(seq.mono[k], seq.camera); });
      p.calls += fr.detector_calls;
      tracked += fr.objects[0].mode == servo::TrackMode::kTrack;
    }
    std::printf("%-34s %9.2f %9.2f %7.0f %7.0f %9s %10s calls %d, tracked %d\n",
                (std::string("  pipeline, ") + (track ? "track" : "detect every frame")).c_str(), median(p.wall),
                median(p.cpu), 1e3 / median(p.wall), 1e3 / median(p.cpu), "", "", p.calls, tracked);
  }
}

/// Detection costs and errors of one kind of registration (3D or 2D-only) at one resolution.
struct PriorStats {
  std::vector<double> cpu, extract, match, pose, corner_px, rot_deg, trans_pct;
  int found = 0, frames = 0;
};

/// Medians of one row of the prior-region table.
void printPriorRow(const std::string& name, const PriorStats& s, bool pose) {
  std::printf("%-30s %8.2f %8.2f %7.2f %7.2f %5d/%-3d %7.3f / %-7.3f", name.c_str(), median(s.cpu),
              median(s.extract), median(s.match), median(s.pose), s.found, s.frames, median(s.corner_px),
              percentile(s.corner_px, 0.9));
  if (pose)
    std::printf(" %6.3f / %-6.3f %6.3f / %-6.3f", median(s.rot_deg), maxOf(s.rot_deg), median(s.trans_pct),
                maxOf(s.trans_pct));
  std::printf("\n");
}

/// Whole-frame and prior-region detection of the target (3D: whole, prior; 2D-only: whole, prior)
/// on one period of the sway at one resolution. Returns the four rows' stats in that order.
std::array<PriorStats, 4> priorRows(const std::string& texture, int frames, int width, int height, double f,
                                    double max_scale) {
  testing::TrackingSequenceSpec spec;
  spec.frames = frames;
  spec.texture = texture;
  spec.camera = Intrinsics::pinhole(width, height, f, 0.5 * (width - 1), 0.5 * (height - 1));
  spec.path = [](double t) { return testing::swayPath(t, 1.0); };
  const testing::TrackingSequence seq = testing::renderTrackingSequence(spec);
  const cv::Mat tex = testing::loadMedia(texture);
  const detector::ObjectModel model3d = detector::textureObject("target", tex, spec.width_m);
  detector::Detector det3, det2;
  det3.addObject(model3d);
  det2.addObject(detector::makeObjectModel("target", tex, std::nullopt, std::nullopt));
  const servo::TargetTrackerOptions pipeline;  // the margins of a re-detection
  auto corners = [&](const Pose& cMo) {
    std::array<Eigen::Vector2d, 4> c;
    for (size_t i = 0; i < 4; ++i) c[i] = seq.camera.project(cMo * model3d.target->corners_o[i]);
    return c;
  };
  std::array<PriorStats, 4> rows;
  for (size_t k = 1; k < seq.mono.size(); ++k) {
    const cv::Mat& img = seq.mono[k].image;
    const std::array<Eigen::Vector2d, 4> truth = corners(seq.truth[k]);
    for (int r = 0; r < 4; ++r) {
      const bool is3d = r < 2, prior = r % 2 == 1;
      const detector::Detector& det = is3d ? det3 : det2;
      detector::DetectionQuery q;
      if (prior) {
        detector::ObjectPrior p;
        p.object = 0;
        p.roi_margin = pipeline.prior_roi_margin;
        p.scale_margin = pipeline.prior_scale_margin;
        p.max_scale = max_scale;
        if (is3d) {
          p.cMo = seq.truth[k - 1];
        } else {  // the homography the previous frame's pose gives (reference px -> image px)
          const std::array<Eigen::Vector2d, 4> c = corners(seq.truth[k - 1]);
          p.H = detector::fitHomographyLeastSquares({model3d.corners_px.begin(), model3d.corners_px.end()},
                                                    {c.begin(), c.end()});
        }
        q.only_priors = true;
        q.priors.push_back(p);
      }
      detector::DetectionResult res;
      PriorStats& s = rows[static_cast<size_t>(r)];
      s.cpu.push_back(bench::threadCpuMs([&] { res = det.detect(img, seq.camera, {}, q); }));
      // The stages' CPU: the frame's CPU split in the proportions of the detector's wall times.
      const double to_cpu = res.time_ms.total > 0 ? s.cpu.back() / res.time_ms.total : 0;
      s.extract.push_back(res.time_ms.extract * to_cpu);
      s.match.push_back(res.time_ms.match * to_cpu);
      s.pose.push_back(res.time_ms.pose * to_cpu);
      ++s.frames;
      const std::optional<detector::Detection> d = res.find(0);
      if (!d) continue;
      ++s.found;
      double e = 0;
      for (size_t i = 0; i < 4; ++i) e = std::max(e, (d->corners[i] - truth[i]).norm());
      s.corner_px.push_back(e);
      if (d->cMo) {
        s.rot_deg.push_back(rotationError(*d->cMo, seq.truth[k]) * 180 / M_PI);
        s.trans_pct.push_back(100 * translationError(*d->cMo, seq.truth[k]) / seq.truth[k].t.norm());
      }
    }
  }
  const std::string res_name = std::to_string(width) + "x" + std::to_string(height);
  const char* names[4] = {" 3D, whole frame", " 3D, prior region", " 2D-only, whole frame", " 2D-only, prior region"};
  for (int r = 0; r < 4; ++r) printPriorRow(res_name + names[r], rows[static_cast<size_t>(r)], r < 2);
  return rows;
}

}  // namespace

int main(int argc, char** argv) try {
  int frames = 120, threads = 1, prior_frames = 40;
  double max_scale = 0.4;  // ObjectPrior::max_scale of the prior-region rows
  std::string texture = "targets/cereal_box.png";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else if (a == "--frames" && i + 1 < argc) {
      frames = static_cast<int>(bench::intArg("bench_tracker", "--frames", argv[++i], 2));
    } else if (a == "--prior-frames" && i + 1 < argc) {
      prior_frames = static_cast<int>(bench::intArg("bench_tracker", "--prior-frames", argv[++i], 0));
    } else if (a == "--prior-max-scale" && i + 1 < argc) {
      max_scale = bench::numberArg("bench_tracker", "--prior-max-scale", argv[++i], 0);
    } else if (a == "--threads" && i + 1 < argc) {
      threads = static_cast<int>(bench::intArg("bench_tracker", "--threads", argv[++i], 1));
    } else if (a == "--texture" && i + 1 < argc) {
      texture = argv[++i];
    } else {
      bench::rejectArgument("bench_tracker", a, {"--frames", "--prior-frames", "--prior-max-scale", "--threads", "--texture"});
    }
  }
  cv::setNumThreads(threads);
  testing::TrackingSequenceSpec spec;
  spec.frames = frames;
  spec.texture = texture;
  const testing::TrackingSequence seq = testing::renderTrackingSequence(spec);
  detector::Detector det;
  det.addObject(detector::textureObject("target", testing::loadMedia(texture), spec.width_m));
  std::printf("bench_tracker: %d frames 640x480, %s 25 cm, orbit 0.4-1.8 m, tilt <= 50 deg; OpenCV threads %d\n",
              frames, texture.c_str(), threads);

  std::printf("\ntracking step (started on frame 0's ground truth)\n");
  std::printf("%-34s %9s %9s %7s %7s %9s %22s %22s\n", "tracker", "wall ms", "cpu ms", "fps", "cpu fps", "followed",
              "rot deg median/max", "trans % median/max");
  struct Variant {
    const char* name;
    servo::TrackerMethod method;
    bool align, edges;
  };
  for (const Variant& v : {Variant{"KLT + reference alignment", servo::TrackerMethod::kKlt, true, false},
                           Variant{"KLT alone", servo::TrackerMethod::kKlt, false, false},
                           Variant{"vpMbGenericTracker KLT", servo::TrackerMethod::kMbt, false, false},
                           Variant{"vpMbGenericTracker KLT + edges", servo::TrackerMethod::kMbt, false, true}}) {
    servo::TrackerOptions opt;
    opt.method = v.method;
    opt.mbt_edges = v.edges;
    auto tracker = servo::planarTrackerFactory(opt, v.align ? &det : nullptr)(det.object(0));
    Row row;
    std::string lost;
    servo::TrackStep s = tracker->start(seq.mono[0].image, seq.camera, seq.truth[0]);
    if (!s.ok) lost = "not started: " + s.lost_reason;
    std::optional<Pose> last = seq.truth[0], before;
    for (size_t k = 1; k < seq.mono.size() && s.ok; ++k) {
      const Pose predicted = before ? *last * before->inverse() * *last : *last;
      row.time([&] { s = tracker->track(seq.mono[k].image, seq.camera, predicted); });
      if (!s.ok) {
        lost = "lost at frame " + std::to_string(k) + ": " + s.lost_reason;
        break;
      }
      ++row.followed;
      before = last;
      last = s.cMo;
      row.rot_deg.push_back(rotationError(s.cMo, seq.truth[k]) * 180 / M_PI);
      row.trans_pct.push_back(100 * translationError(s.cMo, seq.truth[k]) / seq.truth[k].t.norm());
    }
    const double wall = median(row.wall), cpu = median(row.cpu);
    std::printf("%-34s %9.2f %9.2f %7.0f %7.0f %5d/%-3d %10.3f / %-9.3f %10.3f / %-9.3f\n", v.name, wall, cpu,
                1e3 / wall, 1e3 / cpu, row.followed, frames - 1, median(row.rot_deg), maxOf(row.rot_deg),
                median(row.trans_pct), maxOf(row.trans_pct));
    if (!lost.empty()) std::printf("%-34s %s\n", "", lost.c_str());
  }

  std::printf("\npipeline per frame (servo::TargetTracker)\n");
  std::printf("%-42s %9s %9s %9s %9s %7s\n", "mode", "median ms", "p95 ms", "max ms", "cpu ms", "calls");
  struct Mode {
    const char* name;
    bool track;
    int redetect;
  };
  for (const Mode& m : {Mode{"track (detect, confirm, then track)", true, 0},
                        Mode{"track + prior re-detection every 10", true, 10},
                        Mode{"detect every frame (--no-track)", false, 0}}) {
    servo::TargetTrackerOptions o;
    o.track = m.track;
    o.redetect_every_frames = m.redetect;
    servo::TargetTracker pipeline(det, o);
    Row row;
    for (size_t k = 0; k < seq.mono.size(); ++k) {
      servo::TargetFrame f;
      row.time([&] { f = pipeline.process(seq.mono[k], seq.camera); });
      row.calls += f.detector_calls;
    }
    std::printf("%-42s %9.2f %9.2f %9.2f %9.2f %7d\n", m.name, median(row.wall), percentile(row.wall, 0.95),
                maxOf(row.wall), median(row.cpu), row.calls);
  }

  std::printf("\n2D-only object (homography tracker), slow sway 0.55-0.95 m, %d frames\n", frames);
  std::printf("%-34s %9s %9s %7s %7s %9s %22s\n", "", "wall ms", "cpu ms", "fps", "cpu fps", "followed",
              "corner px median/p90");
  twoDRows(texture, frames, 640, 480, 550);
  twoDRows(texture, frames, 1280, 720, 1100);

  if (prior_frames < 2) return 0;
  std::printf("\ndetection with a prior region, one period of the sway, %d frames (prior: the previous frame's truth)\n",
              prior_frames);
  std::printf("%-30s %8s %8s %7s %7s %9s %17s %15s %15s\n", "", "cpu ms", "extract", "match", "pose", "found",
              "corner px med/p90", "rot deg med/max", "trans % med/max");
  const std::array<PriorStats, 4> small = priorRows(texture, prior_frames, 640, 480, 550, max_scale);
  const std::array<PriorStats, 4> large = priorRows(texture, prior_frames, 1280, 720, 1100, max_scale);
  const char* names[4] = {"3D, whole frame", "3D, prior region", "2D-only, whole frame", "2D-only, prior region"};
  bool met = true;
  for (size_t r = 0; r < 4; ++r) {
    const double ratio = median(large[r].cpu) / median(small[r].cpu);
    std::printf("1280x720 / 640x480 CPU, %-22s %6.2f\n", names[r], ratio);
    if (r % 2 == 1) met = met && ratio <= 1.3;
  }
  std::printf("bar prior-region detection at 1280x720 <= 1.3 x 640x480 (CPU): %s\n", met ? "MET" : "NOT MET");
  return 0;
}
catch (const std::exception& e) {  // a missing or unreadable input: one line, not an abort
  std::fprintf(stderr, "bench_tracker: %s\n", e.what());
  return 1;
}
