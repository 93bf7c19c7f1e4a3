#pragma once
// Opening any frame source from a text spec (command lines, config files). Implemented in
// refgrasp_robot_backends (sources.cpp), which links every camera backend; this header names none.
//
//   recording:DIR            a refgrasp recording (robot/files/recording.h), mono or stereo
//   folder:DIR               sorted images (optional stamps.txt), mono
//   folders:LEFT,RIGHT       two image folders, stereo pairs by position
//   video:FILE               a video file (FFmpeg), mono
//   v4l2:DEVICE              a V4L2/UVC webcam ("/dev/video0" or "0"), mono
//   bb2[:GUID]               the Bumblebee2 over IEEE-1394 (libdc1394), stereo
//   sim:SCENARIO.yaml        the simulated enon's stereo camera, the robot standing still
//   PATH                     guessed: a folder with recording.json is a recording, a folder with
//                            left/ and right/ subfolders is a stereo folder pair, another folder
//                            an image folder, a file a video.
// A mono request on a stereo source gets the left eye; a stereo request on a mono source is an
// error; kAuto takes what the source is.
#include <map>
#include <memory>
#include <optional>
#include <string>

#include "core/camera.h"
#include "robot/camera.h"

namespace refgrasp::robot {

enum class Eyes { kMono, kStereo, kAuto };

struct SourceRequest {
  std::string spec;
  Eyes eyes = Eyes::kMono;           ///< what is wanted: a FrameSource, a StereoSource, or either
  /// Calibration for sources that carry none (folders, videos, webcams, the Bumblebee2):
  std::optional<Intrinsics> camera;  ///< mono
  std::optional<StereoRig> rig;      ///< stereo
  /// Per-kind settings; an unknown key is an error:
  ///   folder, folders: stamps (file), fps_hz, max_stamp_skew_s
  ///   video: fps_hz          v4l2: width, height, fps_hz
  ///   bb2: config (YAML, robot/dc1394/bumblebee2.h), guid, frame_rate_hz, shutter_s, gain_db
  ///   sim: enon (robot model YAML, default config/enon.yaml)
  std::map<std::string, std::string> settings;
};

struct OpenedSource {
  std::unique_ptr<FrameSource> mono;      ///< exactly one of mono and stereo is set
  std::unique_ptr<StereoSource> stereo;
  std::string kind;                       ///< recording, folder, folders, video, v4l2, bb2, sim
  std::string description;                ///< the resolved spec, for logs and recording.json
  std::optional<int64_t> frames;          ///< frame count of offline sources, when known
  std::string warning;                    ///< e.g. a damaged recording read up to its last good frame
  bool live = false;                      ///< frames arrive in real time (v4l2, bb2)
  /// Ground truth comes with the frames (sim, and recordings that hold it).
  bool has_truth = false;
};

/// Throws ConfigError "<spec or file>: <problem>" (start-up): unknown kind, missing path, a
/// source that needs a calibration without one, an unknown setting, a stereo request on a mono
/// source, and whatever the source itself refuses (undecodable video, no camera found, ...).
OpenedSource openSource(const SourceRequest& request);

/// A stereo source whose stamps are on the caller's clock: the clock of grab()'s `time` (a control
/// loop's seconds since its start, say), which must run at the real-time rate. The Bumblebee2
/// stamps on the host's Unix clock: each stamp moves by (Unix time now - `time`) at its grab.
/// Offline and simulated sources (recording, folders, sim) are played as if captured at the
/// grab: stamp = `time`. Throws ConfigError for a mono source (the spec named).
std::unique_ptr<StereoSource> onCallerClock(OpenedSource source);

/// The spec list above, for --help texts.
const char* sourceSpecHelp();

}  // namespace refgrasp::robot
