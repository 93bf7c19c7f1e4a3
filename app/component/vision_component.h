#pragma once
// The interoperable vision component (the paper's RT component, on DDS): refgrasp's detector
// behind ROS 2 topics and a service, so a ROS 2 node (rmw_cyclonedds) talks to it with no bridge.
// ROS names under the namespace `ns` (DDS topic "rt" + name; robot/dds/transport.h):
//
//   in   <ns>/image_raw, <ns>/camera_info        sensor_msgs Image / CameraInfo (best effort,
//        (stereo: <ns>/left/..., <ns>/right/...)  keep last 1); the pair of a stereo frame has
//                                                 equal stamps
//   out  <ns>/object_pose   geometry_msgs/PoseStamped: cMo of the FIRST object, when found
//        <ns>/detections    vision_msgs/Detection3DArray (4.x), every instance found
//        <ns>/object_info   refgrasp_msgs/ObjectInfo, one per object per frame (found or not;
//                           a 2D-only object, without reference_pose, has no pose: found = false)
//        <ns>/object_corners refgrasp_msgs/ObjectCorners, one per object per frame: the pattern's
//                           corners in the image (px), a 2D-only object's homography; the result
//                           of a 2D-only object (mono only)
//                           all reliable, keep last 10; header = the image's (stamp, optical frame)
//   srv  <ns>/detect        refgrasp_msgs/srv/Detect: timeout_s = 0 gives the latest result,
//                           > 0 waits up to that long for the result of the next frame
//
// Throughput: the detector always works on the newest frame; frames that arrive while it works
// replace each other and are dropped, never queued (ComponentStats::dropped counts them).
// With `track`, every frame goes through the robot's pipeline (servo/target_tracker.h): a
// detection confirmed by the next one, then the tracker between detections (a few ms a frame),
// so poses come out at the camera's rate; only confirmed poses are published (found = true).
// Bad input (unsupported encoding, data size != height x step, step < width x bytes per pixel,
// no camera_info, camera_info of another size or frame) never stops it: one rate-limited
// warning per kind, found = false for that frame on object_info and in the service, and it
// keeps serving. Poses are cMo (object frame in the camera's optical frame, REP 103: x right,
// y down, z forward), metres; in stereo mode in the LEFT camera frame.
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "detector/detector.h"
#include "servo/target_tracker.h"

namespace refgrasp::component {

struct VisionComponentOptions {
  int domain = 0;              ///< DDS domain id, [0, 232]
  std::string ns = "/refgrasp";
  /// Stereo mode: pair <ns>/left and <ns>/right by stamp and fuse; the intrinsics still come from
  /// camera_info, the right eye's pose in the left frame (lMr) from this rig.
  std::optional<StereoRig> stereo;
  double warning_period_s = 5.0;  ///< at most one warning per kind of problem per period
  bool track = false;  ///< run the robot's detect-confirm-track pipeline instead of detection alone
  servo::TargetTrackerOptions tracking;  ///< with track
  /// Throws std::invalid_argument "VisionComponentOptions.<field>: <problem>".
  void check() const;
};

/// A snapshot of what the component did.
struct ComponentStats {
  long received = 0;   ///< frames taken from DDS (stereo: pairs formed)
  long processed = 0;  ///< frames the detector (with track: the pipeline) ran on
  long tracked = 0;    ///< with track: processed frames that needed no detection (tracked only)
  long dropped = 0;    ///< frames a newer one replaced before the detector got to them
  long rejected = 0;   ///< frames that could not be used (bad input): found = false
  long unpaired = 0;   ///< stereo: images whose partner (same stamp) never came
  long requests = 0;   ///< detect calls received
  double detect_ms_median = 0;    ///< the detector alone (with track: the pipeline), per processed frame
  /// Waiting for the detector to finish the previous frame (0 when frames come slower than it).
  double queue_ms_median = 0;
  /// The component's own work per frame: taking it from DDS, checks and conversion, writing the
  /// results (frame taken from DDS -> results written, minus the wait and the detector).
  double overhead_ms_median = 0;
  /// The same three for the last processed frame (ms).
  double last_detect_ms = 0, last_queue_ms = 0, last_overhead_ms = 0;
};

class VisionComponent {
 public:
  using WarningSink = std::function<void(const std::string&)>;
  /// Takes a detector with its objects added (in stereo all with a reference pose). Creates the DDS
  /// endpoints (throws dds::DdsError, std::invalid_argument) and starts serving at once.
  VisionComponent(detector::Detector detector, const VisionComponentOptions& options,
                  WarningSink warn = {});
  ~VisionComponent();
  VisionComponent(const VisionComponent&) = delete;
  VisionComponent& operator=(const VisionComponent&) = delete;

  /// Stops the threads and deletes the endpoints' activity (idempotent; the destructor calls it).
  void stop();
  ComponentStats stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> p_;
};

}  // namespace refgrasp::component
