#include "component/cli.h"

#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>
#include <thread>

#include "component/vision_component.h"
#include "core/error.h"
#include "detector/detector.h"
#include "detector/detector_config.h"
#include "servo/target_tracker.h"
#include "robot/dds/transport.h"
#include "tool/tool.h"

namespace refgrasp::component {

namespace {

const char* kDescription = R"(The interoperable vision component: refgrasp's object detector on DDS (Eclipse Cyclone DDS),
speaking ROS 2's wire types so ROS 2 nodes (rmw_cyclonedds, Humble/Jazzy) use it with no bridge.
Topics (ROS names; on DDS "rt" + name):
  in   <ns>/image_raw, <ns>/camera_info          (--stereo: <ns>/left/... and <ns>/right/...)
       sensor_msgs/Image (mono8, rgb8, bgr8, rgba8, bgra8, bayer_*8) and sensor_msgs/CameraInfo
  out  <ns>/object_pose  geometry_msgs/PoseStamped of the first --object (cMo, optical frame)
       <ns>/detections   vision_msgs/Detection3DArray (vision_msgs 4.x, ROS 2 Humble)
       <ns>/object_info  refgrasp_msgs/ObjectInfo: name, found, R (3x3), t (m), inliers, stamp
       <ns>/object_corners  refgrasp_msgs/ObjectCorners: name, found, tracked, pattern corners
                         (px), homography (2D-only objects), inliers: the result of an object
                         without reference_pose (2D-only: no pose; mono only)
  srv  <ns>/detect       refgrasp_msgs/srv/Detect {object_name, timeout_s} -> {found, rotation,
                         translation, error}; timeout_s 0: the latest result, > 0: the next frame's
The detector works on the newest frame; frames arriving meanwhile are dropped (counted).
--track: the robot's pipeline instead (servo::TargetTracker): a detection is published once the
next one confirms it, then the target is tracked frame to frame (a few ms) and re-detected only
when the tracker loses it, so poses come out at the camera's rate. --prior-max-scale S (with
--track; default 0: off): a predicted region whose pattern is larger than S scene px per reference
px is searched downsampled (0.4: a 1280x720 frame's re-detection costs about a 640x480 one's).
Bad frames give one warning (rate-limited) on stderr and found = false; serving goes on.
Detector options: --detector-config FILE (config/detector.yaml lists every field).
Stops on SIGINT/SIGTERM and prints {"frames_received",...} as one JSON line on stdout.
Cyclone DDS reads its configuration from CYCLONEDDS_URI (config/dds/cyclonedds_loopback.xml
for one machine). Exit status: 0 clean shutdown; 2 bad options or files; 3 DDS failure;
4 stdout could not be written.)";

std::atomic<bool> g_stop{false};
extern "C" void onSignal(int) { g_stop = true; }

}  // namespace

int runVisionComponent(int argc, char** argv) {
  CLI::App app(kDescription, "vision_component");
  std::vector<std::string> object_files;
  std::string ns = "/refgrasp", rig_file, detector_config;
  int domain = 0;
  app.add_option("--object", object_files, "object definition YAML (repeat for several objects)")
      ->required()
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  app.add_option("--ns", ns, "ROS namespace of the topics and the service")->capture_default_str();
  // Range checked below (dds::domainOrNamespaceProblem); CLI11 refuses what an int cannot hold.
  auto* domain_opt = app.add_option("--domain", domain, "DDS domain id, 0..232 (default: $ROS_DOMAIN_ID, else 0)");
  app.add_option("--stereo", rig_file,
                 "stereo rig YAML: pair <ns>/left and <ns>/right by stamp and fuse (the rig gives "
                 "right_in_left; intrinsics come from camera_info)");
  app.add_option("--detector-config", detector_config,
                 "detector options YAML (every field: config/detector.yaml); default: built-in");
  bool track = false;
  app.add_flag("--track", track,
               "the robot's pipeline: a detection confirmed by the next one, then tracked between "
               "detections, so poses come out at the camera's rate");
  double prior_max_scale = 0;
  auto* prior_opt = app.add_option("--prior-max-scale", prior_max_scale,
                                   "with --track: a predicted region whose pattern is larger than this "
                                   "(scene px per reference px) is searched downsampled; 0: never (default)")
                        ->check(tool::Finite(0, 100));
  tool::parse(app, argc, argv);
  if (*prior_opt && !track) {
    std::fprintf(stderr, "vision_component: --prior-max-scale: needs --track (it sets the tracker's re-detection)\n");
    return 2;
  }
  const int env_domain = tool::checkDdsEnvironment();
  if (!*domain_opt) domain = env_domain;
  // Until the component serves (objects loaded, participant created), a signal ends it at once.
  tool::exitOnSignal();
  if (const std::string p = dds::domainOrNamespaceProblem(domain, ns); !p.empty()) {
    std::fprintf(stderr, "vision_component: %s\n", p.c_str());
    return 2;
  }
  VisionComponentOptions opt;
  opt.domain = domain;
  opt.ns = ns;
  opt.track = track;
  opt.tracking.prior_max_scale = prior_max_scale;
  detector::Detector det;
  try {
    if (!detector_config.empty()) det = detector::Detector(detector::loadDetectorOptions(detector_config));
    if (!rig_file.empty()) opt.stereo = loadStereoRig(rig_file);
    std::set<std::string> names;
    for (const auto& f : object_files) {
      detector::ObjectModel m = detector::loadObjectDefinition(f);
      if (!m.hasPose() && opt.stereo)
        throw ConfigError(f, "reference_pose", "required with --stereo (stereo fuses 3D poses)");
      if (!names.insert(m.name).second)
        throw ConfigError(f, "name", "object name '" + m.name + "' used twice");
      det.addObject(m);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vision_component: %s\n", e.what());
    return 2;
  }
  std::unique_ptr<VisionComponent> c;
  try {
    c = std::make_unique<VisionComponent>(std::move(det), opt);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vision_component: %s\n", tool::withDdsError(e.what()).c_str());
    return 3;
  }
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  std::fprintf(stderr, "vision_component: serving %s on DDS domain %d (%zu object%s, %s%s)\n",
               dds::joinRosName(ns, "detect").c_str(), domain, object_files.size(),
               object_files.size() == 1 ? "" : "s", opt.stereo ? "stereo" : "mono", track ? ", tracking" : "");
  while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  c->stop();
  const ComponentStats s = c->stats();
  nlohmann::ordered_json j;
  j["frames_received"] = s.received;
  j["frames_processed"] = s.processed;
  if (track) j["frames_tracked"] = s.tracked;
  j["frames_dropped"] = s.dropped;
  j["frames_rejected"] = s.rejected;
  j["frames_unpaired"] = s.unpaired;
  j["detect_requests"] = s.requests;
  j["detect_ms_median"] = s.detect_ms_median;
  j["queue_ms_median"] = s.queue_ms_median;
  j["overhead_ms_median"] = s.overhead_ms_median;
  std::printf("%s\n", j.dump().c_str());
  return 0;
}

}  // namespace refgrasp::component
