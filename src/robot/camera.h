#pragma once
// Frame sources, independent of the robot: a replay tool, a DDS node or a calibration tool needs
// frames, not a Robot. Sources: the simulated enon's synthetic camera (robot/sim/), the Bumblebee2
// over libdc1394 (robot/dc1394/), webcams, video files, image folders and recordings
// (robot/files/); robot/sources.h opens any of them from a text spec.
//
// Every frame carries its capture time (exposure centre, seconds on the source's clock; the
// simulation clock for the simulator) and the device's frame counter, and, when the source knows
// it, the head joint state and the camera pose in the robot base frame AT CAPTURE: once the head
// moves, the servo loop needs the camera pose at exposure, not at the time the frame is read.
// Robot::camera().grab() fills what the device leaves out from the robot's state history.
// Pixels: centre of the top-left pixel is (0, 0). Poses: aMb maps frame-b coordinates to frame a;
// metres, radians.
#include <cstdint>
#include <optional>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"
#include "core/types.h"
#include "robot/status.h"

namespace refgrasp::robot {

/// Pan-tilt head joint positions (rad), as in RobotState.
struct HeadJoints {
  double pan_rad = 0, tilt_rad = 0;
};

/// What is known about the camera at the exposure of a frame.
struct CaptureState {
  std::optional<HeadJoints> head;  ///< head joints at capture (robot cameras)
  std::optional<Pose> bMc;         ///< camera (left eye for stereo) optical frame in the base frame
  std::optional<Pose> wMb_odom;    ///< base pose from odometry at capture
};

/// Ground-truth pose of one object at the exposure of a frame. Only simulators and recordings of
/// them know it; it is for evaluation and logs (pose_replay errors), never for control.
struct ObjectTruth {
  std::string object;         ///< object name (scenario object / object definition name)
  Pose cMo;                   ///< object frame in the (left, for stereo) camera frame
  std::optional<Pose> rMo;    ///< stereo: object frame in the right camera frame
};

struct MonoFrame {
  cv::Mat image;        ///< CV_8UC1 (or CV_8UC3 BGR when the source is colour)
  Seconds stamp = 0;    ///< capture time (exposure centre)
  int64_t index = 0;    ///< frame counter of the device
  CaptureState capture;
  std::vector<ObjectTruth> truth;  ///< empty unless the source knows the ground truth
  FrameStamp frameStamp() const { return {stamp, index}; }
};

struct StereoFrame {
  cv::Mat left, right;  ///< CV_8UC1 (CV_8UC3 BGR when the source is colour), same capture time
  Seconds stamp = 0;    ///< capture time (exposure centre)
  int64_t index = 0;    ///< frame counter of the device
  CaptureState capture; ///< bMc is the LEFT camera's
  std::vector<ObjectTruth> truth;  ///< empty unless the source knows the ground truth
  FrameStamp frameStamp() const { return {stamp, index}; }
};

/// A mono camera.
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  /// Intrinsics of every frame this source delivers.
  virtual const Intrinsics& camera() const = 0;
  /// \param time now, on the source's clock. Live sources return the newest frame captured by
  /// `time` and not returned before; offline sources (files, recordings) the next one, whatever
  /// `time`. std::nullopt in `frame` when there is none yet (not due, dropped). kDeactivate when
  /// an offline source has no frame left; kError when the device fails, or when an offline
  /// source cannot use its next frame (undecodable, wrong size): the next grab() moves on.
  virtual ReturnType grab(Seconds time, std::optional<MonoFrame>* frame) = 0;
  /// One line saying why the last grab() returned kError (or why the source ended early).
  virtual std::string lastError() const { return {}; }
};

/// A calibrated stereo camera (the enon's Bumblebee2).
class StereoSource {
 public:
  virtual ~StereoSource() = default;
  virtual const StereoRig& rig() const = 0;
  /// As FrameSource::grab, for a synchronised pair.
  virtual ReturnType grab(Seconds time, std::optional<StereoFrame>* frame) = 0;
  /// As FrameSource::lastError.
  virtual std::string lastError() const { return {}; }
};

}  // namespace refgrasp::robot
