// record: any frame source to a refgrasp recording (docs/formats.md "Recording").
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>
#include <iostream>

#include "core/camera.h"
#include "core/error.h"
#include "robot/files/record.h"
#include "robot/files/recording.h"
#include "robot/sources.h"
#include "tool/tool.h"

using namespace refgrasp;

namespace {

const char* kDescription = R"(Records frames from any source into a refgrasp recording: a folder with recording.json,
calib/ (the calibration used), frames/ (lossless PNG) and index.jsonl (one JSON line per frame,
appended only once the frame's images are on disk). A recorder killed at any instant or a disk
that fills leaves a recording that reads up to its last complete frame.
Exit status: 0 done; 1 some frames could not be read and were skipped, or a live camera failed
(one-line error each; the recording holds the rest); 2 bad options, source or output folder, or
a source without a frame ("nothing to do"); 3 a write failed (disk full, I/O error): the recording is valid up to the frame before.)";

std::atomic<bool> g_stop{false};

void onSignal(int) { g_stop = true; }

int record(int argc, char** argv) {
  CLI::App app(kDescription, "record");
  std::string spec, out, camera_file, rig_file;
  std::vector<std::string> sets;
  bool mono = false, no_fsync = false;
  files::RecordLimits limits;
  files::RecordingOptions ro;
  app.add_option("--source", spec, std::string("frame source: ") + robot::sourceSpecHelp())->required();
  app.add_option("--output", out, "recording folder to create (must not exist or be empty)")->required();
  app.add_option("--camera", camera_file, "calibration of a mono source without one (ROS yaml / ViSP xml)");
  app.add_option("--stereo", rig_file, "stereo rig of a stereo source without one (rig YAML)");
  app.add_flag("--mono", mono, "record only the left eye of a stereo source");
  app.add_option("--set", sets, "source setting KEY=VALUE (repeat), e.g. fps_hz=30, config=bb2.yaml")
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  app.add_option("--frames", limits.max_frames, "stop after N frames (0 = until the source ends)")
      ->check(tool::Integer(0, INT64_MAX));
  app.add_option("--seconds", limits.max_seconds, "stop after S seconds of wall-clock time (0 = no limit)")
      ->check(tool::Finite(0, 1e9));
  app.add_option("--png-compression", ro.png_compression, "PNG level 0-9 (lossless at every level)")
      ->check(tool::Integer(0, 9));
  app.add_flag("--no-fsync", no_fsync, "do not fsync each frame (survives a killed recorder, not a power loss)");
  tool::parse(app, argc, argv);

  tool::Paths paths;
  paths.inputSpec("--source", spec);
  paths.input("--camera", camera_file);
  paths.input("--stereo", rig_file);
  for (const std::string& kv : sets)
    if (kv.rfind("config=", 0) == 0) paths.input("--set config", kv.substr(7));
  paths.outputFolder("--output", out);
  paths.check();

  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);

  robot::SourceRequest req;
  req.spec = spec;
  req.eyes = mono ? robot::Eyes::kMono : robot::Eyes::kAuto;
  std::unique_ptr<files::RecordingWriter> writer;
  robot::OpenedSource src;
  try {
    for (const std::string& kv : sets) {
      const size_t eq = kv.find('=');
      if (eq == std::string::npos || eq == 0)
        throw ConfigError("--set " + kv, "expected KEY=VALUE");
      req.settings[kv.substr(0, eq)] = kv.substr(eq + 1);
    }
    if (!camera_file.empty()) req.camera = loadCameraFile(camera_file);
    if (!rig_file.empty()) req.rig = loadStereoRig(rig_file);
    src = robot::openSource(req);
    if (!src.warning.empty()) std::cerr << "record: warning: " << src.warning << "\n";
    ro.source = src.description;
    ro.created_by = "record";
    ro.fsync = !no_fsync;
    writer = src.stereo ? files::RecordingWriter::createStereo(out, src.stereo->rig(), ro)
                        : files::RecordingWriter::createMono(out, src.mono->camera(), ro);
  } catch (const std::exception& e) {
    std::cerr << "record: " << e.what() << "\n";
    return 2;
  }

  const bool tty = isatty(STDERR_FILENO);
  double last_print = -1;
  const auto progress = [&](const files::RecordProgress& p) {
    if (p.elapsed_s - last_print < 0.5 && p.frames != p.total) return;
    last_print = p.elapsed_s;
    char line[160];
    std::snprintf(line, sizeof(line), "record: %lld%s frames, %.1f fps, %.1f s",
                  static_cast<long long>(p.frames),
                  p.total > 0 ? (" / " + std::to_string(p.total)).c_str() : "",
                  p.elapsed_s > 0 ? p.frames / p.elapsed_s : 0.0, p.elapsed_s);
    std::cerr << (tty ? "\r" : "") << line << (tty ? "" : "\n") << std::flush;
  };
  const auto error = [&](const std::string& e) {
    std::cerr << (tty && last_print >= 0 ? "\n" : "") << e << "\n";
  };
  const files::RecordResult r = files::recordFrames(src, *writer, limits, g_stop, error, progress);
  if (tty && last_print >= 0) std::cerr << "\n";
  // A failed write is its one line (the recording reads up to the frame before, as documented).
  if (!r.write_error.empty()) {
    std::cerr << "record: " << r.write_error << "\n";
    return 3;
  }
  std::cerr << "record: " << r.frames << " frames in " << out << (r.stopped ? " (interrupted)" : "")
            << "\n";
  return r.frame_errors > 0 || r.source_failed ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) { return tool::run("record", argc, argv, record); }
