// pose_replay: the robot's detection and tracking frame by frame on a
// recording, a video or an image folder; poses, trajectory, overlay video, summary and plot.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <iostream>

#include "core/camera.h"
#include "core/error.h"
#include "detector/detector.h"
#include "detector_cli.h"
#include "robot/sources.h"
#include "servo/replay.h"
#include "servo/replay_report.h"
#include "tool/tool.h"

using namespace refgrasp;

namespace {

const char* kDescription = R"(Replays recorded or file input through the robot's detection and tracking, frame by frame,
and writes into OUTDIR: poses.jsonl (one line per frame: the detect_object fields plus "frame"
(0-based), "index", "stamp" and "mode": detect, track or lost; with ground truth "truth" and
"error"), trajectory.tum (TUM: stamp tx ty tz qx qy qz qw of cMo; truth.tum with ground truth),
poses.csv, overlay.mp4 (or frames/*.png with --frames: outline, axes x red y green z blue, mode,
frame number), summary.json and plot.png. The same input and options give the same poses.jsonl,
byte for byte (timings only in summary.json "timing_ms"). Detector options: --detector-config
FILE (every field: config/detector.yaml), --matcher and --pose override it.
Tracking (the robot's pipeline, servo/target_tracker.h): a detection is confirmed by the next
one, then the target is tracked frame to frame (KLT features on the object's surfaces, aligned
with the reference image for a planar object; a 2D-only object, without reference_pose, by its
homography, aligned with the reference every frame); when the tracker loses it the frame is detected
again, in the predicted region first, then in the whole frame. --no-track detects every frame.
--prior-max-scale S (default 0: off): a predicted region whose pattern is larger than S scene px
per reference px is searched downsampled (0.4: a 1280x720 frame's re-detection costs about what
a 640x480 one's does; for references sharper than the frames).
--input: a recording folder, a video file, an image folder (sorted; optional stamps.txt), a
folder with left/ and right/ image folders (with --stereo), or any source spec:
)";

const char* kExit = R"(
Exit status: 0 every frame processed; 1 some frames could not be processed (a one-line error each
on stderr; the outputs hold every other frame); 2 bad options, object, camera or input, or an
input without a frame ("nothing to do": an empty recording, folder or video); 3 the outputs could
not be written (disk full?).)";

std::string clock(double s) {
  if (!std::isfinite(s) || s < 0) return "--:--";
  const long t = std::lround(s);
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%ld:%02ld", t / 60, t % 60);
  return buf;
}

// "[#####-----] 120/480 frames  11.8 fps  0:30 left" on stderr (in place on a terminal).
class ProgressBar {
 public:
  explicit ProgressBar(std::optional<int64_t> total) : total_(total), tty_(isatty(STDERR_FILENO)) {}
  void update(int64_t done, bool last = false) {
    const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
    if (!last && el - printed_ < (tty_ ? 0.2 : 5.0)) return;
    printed_ = el;
    const double fps = el > 0 ? done / el : 0;
    char line[200];
    if (total_ && *total_ > 0) {
      const int width = 24, fill = static_cast<int>(width * std::min<double>(1.0, double(done) / *total_));
      const std::string bar = std::string(fill, '#') + std::string(width - fill, '-');
      std::snprintf(line, sizeof(line), "pose_replay [%s] %lld/%lld frames  %.1f fps  %s left",
                    bar.c_str(), static_cast<long long>(done), static_cast<long long>(*total_), fps,
                    clock(fps > 0 ? (*total_ - done) / fps : -1).c_str());
    } else {
      std::snprintf(line, sizeof(line), "pose_replay %lld frames  %.1f fps  %s elapsed",
                    static_cast<long long>(done), fps, clock(el).c_str());
    }
    std::cerr << (tty_ ? "\r" : "") << line << (tty_ && !last ? "" : "\n") << std::flush;
    open_ = tty_ && !last;
  }
  // Before another message on stderr.
  void breakLine() {
    if (open_) std::cerr << "\n";
    open_ = false;
  }

 private:
  std::optional<int64_t> total_;
  bool tty_, open_ = false;
  double printed_ = -1e9;
  std::chrono::steady_clock::time_point t0_ = std::chrono::steady_clock::now();
};

int poseReplay(int argc, char** argv) {
  CLI::App app(std::string(kDescription) + robot::sourceSpecHelp() + kExit, "pose_replay");
  std::vector<std::string> object_files;
  std::string camera_file, input, outdir, rig_file;
  DetectorCli detector_cli;
  bool no_track = false, png_frames = false;
  double prior_max_scale = 0;
  app.add_option("--object", object_files, "object definition YAML (repeat for several objects)")
      ->required()
      ->expected(1)
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  app.add_option("--camera", camera_file,
                 "intrinsics of the frames (ROS yaml / ViSP xml); default: a recording's own");
  app.add_option("--input", input, "recording, video, image folder or source spec")->required();
  app.add_option("--output", outdir, "output folder (created; its files are replaced)")->required();
  app.add_option("--stereo", rig_file, "stereo rig YAML: replay both eyes (fused poses, left camera frame)");
  app.add_flag("--no-track", no_track, "detect on every frame (no tracking between detections)");
  app.add_flag("--frames", png_frames, "overlay as OUTDIR/frames/NNNNNN.png instead of overlay.mp4");
  app.add_option("--prior-max-scale", prior_max_scale,
                 "re-detection in a predicted region: downsampled where the pattern is larger than "
                 "this (scene px per reference px); 0: never (default)")
      ->check(tool::Finite(0, 100));
  detector_cli.add(app);
  tool::parse(app, argc, argv);
  const bool stereo = !rig_file.empty();
  tool::Paths paths;
  for (const std::string& f : object_files) paths.input("--object", f);
  paths.input("--camera", camera_file);
  paths.input("--stereo", rig_file);
  paths.inputSpec("--input", input);
  paths.outputFolder("--output", outdir);
  paths.check();

  std::unique_ptr<detector::Detector> det;
  robot::OpenedSource src;
  std::optional<Intrinsics> camera;
  std::optional<StereoRig> rig;
  try {
    det = std::make_unique<detector::Detector>(detector_cli.options());
    for (const std::string& f : object_files) det->addObject(detector::loadObjectDefinition(f));
    if (!camera_file.empty()) camera = loadCameraFile(camera_file);
    if (stereo) rig = loadStereoRig(rig_file);
    robot::SourceRequest req;
    req.spec = input;
    req.eyes = stereo ? robot::Eyes::kStereo : robot::Eyes::kMono;
    req.camera = camera;
    req.rig = rig;
    src = robot::openSource(req);
  } catch (const std::exception& e) {
    std::cerr << "pose_replay: " << e.what() << "\n";
    return 2;
  }
  if (!src.warning.empty()) std::cerr << "pose_replay: warning: " << src.warning << "\n";
  // The calibration the poses use: the given one, else the source's own.
  const Intrinsics cam = camera ? *camera : src.mono ? src.mono->camera() : src.stereo->rig().left;
  const StereoRig stereo_rig = rig ? *rig : StereoRig{};

  servo::ReplayOptions ropt;
  ropt.track = !no_track;
  ropt.pipeline.prior_max_scale = prior_max_scale;
  servo::PoseReplay replay(*det, ropt, servo::planarTrackerFactory(ropt.pipeline.tracker, det.get()));
  std::unique_ptr<servo::ReplayReport> report;
  try {
    servo::ReplayReportOptions o;
    o.png_frames = png_frames;
    o.input = src.description;
    o.stereo = stereo;
    o.tracking = replay.tracking();
    report = std::make_unique<servo::ReplayReport>(outdir, *det, o);
  } catch (const std::exception& e) {
    std::cerr << "pose_replay: " << e.what() << "\n";
    return 2;
  }

  ProgressBar bar(src.frames);
  const servo::ReplayRunResult run = servo::replaySource(
      src, replay, *report, cam, stereo_rig,
      [&](const std::string& e) {
        bar.breakLine();
        std::cerr << e << "\n";
      },
      [&](int64_t done) { bar.update(done); });
  std::string error = run.write_error;
  if (!error.empty()) {
    bar.breakLine();
    std::cerr << "pose_replay: " << error << "\n";
    return 3;
  }
  bar.update(run.frames, true);
  if (run.frames == 0) {  // a source that ended before its first frame: no output is a result
    std::cerr << "pose_replay: " << src.description << ": no frames: nothing to do\n";
    return tool::kBadInput;
  }
  if (!report->finish(&error)) {
    std::cerr << "pose_replay: " << error << "\n";
    return 3;
  }
  for (const std::string& n : report->notes()) std::cerr << "pose_replay: " << n << "\n";
  std::cerr << "pose_replay: " << run.frames << " frames"
            << (run.failed ? " (" + std::to_string(run.failed) + " failed)" : "") << " -> " << outdir
            << "\n";
  return run.failed > 0 ? 1 : 0;
}

}  // namespace

// FFmpeg's and OpenCV's own diagnostics are silenced by tool::run: ours is the one-line error.
int main(int argc, char** argv) { return tool::run("pose_replay", argc, argv, poseReplay); }
