// A several-view box on real footage (eval/box_video_eval.h): OpenCV's hand-held box
// clip, the two-view definition made from its frame 150, the robot's pipeline (detect, confirm,
// track) and each view alone. Prints the pipeline's modes, the labelled frames' corner errors, the
// wrong reports, and the two views' agreement where both are found.
#include <algorithm>
#include <cstdlib>
#include <cstdio>
#include <string>
#include <vector>

#include "bench_util.h"
#include "core/camera.h"
#include "eval/box_video_eval.h"

using namespace refgrasp;

namespace {

const char* kTool = "bench_box_video";

void usage() {
  std::printf(
      "bench_box_video: media/video/box.mp4 (OpenCV's hand-held box, 640x480) with the two-view box\n"
      "config/objects/box_video.yaml and the camera media/video/box_camera.yaml (f estimated, see\n"
      "docs/results.md), against the corners labelled in media/video/box_corners.txt.\n"
      "Usage: bench_box_video [--frames N (default: all)] [--view-stride N (default 1; 0: no views alone)]\n"
      "                       [--wrong-px PX (default 20)] [--no-track] [--video FILE] [--camera CAM]\n"
      "                       [--object OBJ.yaml] [--labels FILE] [--box-size W,H,D (the labels' box,\n"
      "                       default 0.25,0.0775,0.1725)] [--help]\n"
      "       bench_box_video --fit-camera [--fit-frame N (default 150)] [--camera CAM] [--labels FILE]\n"
      "                       [--box-size W,H,D]\n"
      "--fit-camera: for f = 450..1300 px, the box that best explains the labels (its aspect ratios\n"
      "and the corners' RMS); then, with the camera's f and the box size, the fitted box's corners\n"
      "A B C D F E in frame N (the corners scripts/make_box_video.sh gives make_reference).\n");
}

std::string stats(std::vector<double> v, const char* unit) {
  if (v.empty()) return "-";
  char b[96];
  std::snprintf(b, sizeof b, "median %.2f %s, max %.2f %s", bench::median(v), unit,
                *std::max_element(v.begin(), v.end()), unit);
  return b;
}

int fitCamera(const eval::BoxVideoOptions& opt, int fit_frame) {
  const std::vector<eval::BoxLabel> labels = eval::loadBoxLabels(opt.labels);
  const Intrinsics camera = loadCameraFile(opt.camera);
  std::printf("| f (px) | H/W | D/W | corner RMS (px) |\n|---|---|---|---|\n");
  for (double f = 450; f <= 1300; f += 50) {
    const eval::BoxFit fit = eval::fitBoxToLabels(labels, f, camera.width, camera.height);
    std::printf("| %.0f | %.3f | %.3f | %.2f |\n", f, fit.h_over_w, fit.d_over_w, fit.rms_px);
  }
  for (const eval::BoxLabel& label : labels) {
    if (label.frame != fit_frame) continue;
    const std::array<Eigen::Vector2d, 6> c = eval::fittedBoxCorners(label, opt.box_size_m, camera);
    std::printf("\nframe %d, f = %.0f px, box %g x %g x %g m:", fit_frame, camera.fx, opt.box_size_m.x(),
                opt.box_size_m.y(), opt.box_size_m.z());
    for (size_t i = 0; i < c.size(); ++i) std::printf(" %c=%.1f,%.1f", "ABCDFE"[i], c[i].x(), c[i].y());
    std::printf("\n");
    return 0;
  }
  std::fprintf(stderr, "%s: --fit-frame: no label for frame %d\n", kTool, fit_frame);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  ::setenv("OPENCV_FFMPEG_LOGLEVEL", "-8", 0);  // the clip's last frame makes FFmpeg complain
  const std::string root = REFGRASP_SOURCE_DIR;
  eval::BoxVideoOptions opt;
  opt.video = root + "/media/video/box.mp4";
  opt.camera = root + "/media/video/box_camera.yaml";
  opt.object = root + "/config/objects/box_video.yaml";
  opt.labels = root + "/media/video/box_corners.txt";
  bool fit = false;
  int fit_frame = 150;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool more = i + 1 < argc;
    if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else if (a == "--frames" && more) {
      opt.max_frames = static_cast<int>(bench::intArg(kTool, "--frames", argv[++i], 1));
    } else if (a == "--view-stride" && more) {
      opt.view_stride = static_cast<int>(bench::intArg(kTool, "--view-stride", argv[++i], 0));
    } else if (a == "--wrong-px" && more) {
      opt.wrong_px = bench::numberArg(kTool, "--wrong-px", argv[++i], 0.1);
    } else if (a == "--fit-camera") {
      fit = true;
    } else if (a == "--fit-frame" && more) {
      fit_frame = static_cast<int>(bench::intArg(kTool, "--fit-frame", argv[++i], 0));
    } else if (a == "--no-track") {
      opt.track = false;
    } else if (a == "--video" && more) {
      opt.video = argv[++i];
    } else if (a == "--camera" && more) {
      opt.camera = argv[++i];
    } else if (a == "--object" && more) {
      opt.object = argv[++i];
    } else if (a == "--labels" && more) {
      opt.labels = argv[++i];
    } else if (a == "--box-size" && more) {
      double w = 0, h = 0, d = 0;
      char end = 0;
      if (std::sscanf(argv[++i], "%lf,%lf,%lf%c", &w, &h, &d, &end) != 3) {
        std::fprintf(stderr, "%s: --box-size: expected W,H,D (metres), got '%s'\n", kTool, argv[i]);
        return 2;
      }
      opt.box_size_m = {w, h, d};
    } else {
      bench::rejectArgument(kTool, a,
                            {"--frames", "--view-stride", "--wrong-px", "--video", "--camera", "--object", "--labels",
                             "--box-size", "--fit-frame"});
    }
  }
  eval::BoxVideoResult r;
  double ms = 0;
  try {
    if (fit) return fitCamera(opt, fit_frame);
    ms = bench::timeMs([&] { r = eval::runBoxVideo(opt); });
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", kTool, e.what());
    return 2;
  }

  std::printf("%s: %s, %d frames, %s (%.1f s)\n", kTool, opt.video.c_str(), r.frames,
              opt.track ? "tracking" : "detection on every frame", ms / 1e3);
  std::printf("\npipeline: with a pose %d/%d (detect %d, track %d), lost %d\n", r.detect + r.track, r.frames,
              r.detect, r.track, r.lost);
  std::printf("\n| labelled frame | mode | worst corner (px) | mean corner (px) | A B C D F (px) |\n"
              "|---|---|---|---|---|\n");
  std::vector<double> worst, mean;
  for (const eval::BoxLabelCheck& c : r.labelled) {
    if (c.has_pose) {
      std::printf("| %d | %s | %.1f | %.1f | %.0f %.0f %.0f %.0f %.0f |\n", c.frame, servo::toString(c.mode), c.max_px,
                  c.mean_px, c.corner_px[0], c.corner_px[1], c.corner_px[2], c.corner_px[3], c.corner_px[4]);
      worst.push_back(c.max_px);
      mean.push_back(c.mean_px);
    } else {
      std::printf("| %d | %s | - | - | - |\n", c.frame, servo::toString(c.mode));
    }
  }
  std::printf("\nlabelled frames with a pose: %zu/%zu; worst corner %s; mean corner %s; wrong (mean > %.0f px): %d\n",
              worst.size(), r.labelled.size(), stats(worst, "px").c_str(), stats(mean, "px").c_str(), opt.wrong_px,
              r.wrong);

  if (r.view_frames == 0) return 0;
  std::printf("\nviews alone, on %d frames:", r.view_frames);
  for (size_t v = 0; v < r.view_names.size(); ++v)
    std::printf(" %s found in %d;", r.view_names[v].c_str(), r.view_found[v]);
  std::printf(" both in %zu\n", r.agreement.size());
  std::vector<double> mm, pct, deg, dist;
  for (const eval::BoxViewAgreement& a : r.agreement) {
    mm.push_back(1e3 * a.translation_m);
    pct.push_back(100 * a.translation_m / a.distance_m);
    deg.push_back(a.rotation_deg);
    dist.push_back(a.distance_m);
  }
  std::printf("the object pose each view implies, where both are found (box at %s):\n", stats(dist, "m").c_str());
  std::printf("  translation gap %s; %s of the distance\n  rotation gap %s\n", stats(mm, "mm").c_str(),
              stats(pct, "%").c_str(), stats(deg, "deg").c_str());
  std::vector<double> own_deg, views_deg;
  for (const eval::BoxViewAgreement& a : r.agreement) (a.by_views ? views_deg : own_deg).push_back(a.rotation_deg);
  std::printf("  rotation gap where both views were found by their own features: %s (%zu frames)\n"
              "  where a view needed its view-synthesised features: %s (%zu frames)\n",
              stats(own_deg, "deg").c_str(), own_deg.size(), stats(views_deg, "deg").c_str(), views_deg.size());
  std::string far;
  int n_far = 0;
  for (const eval::BoxViewAgreement& a : r.agreement)
    if (a.rotation_deg > 10) far += (n_far++ < 30 ? " " + std::to_string(a.frame) : std::string());
  std::printf("  frames where they differ by more than 10 deg: %d%s%s\n", n_far, n_far ? ":" : "",
              far.c_str());
  return 0;
}
