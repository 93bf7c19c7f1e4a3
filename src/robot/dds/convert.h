#pragma once
// Conversions between ROS 2 messages (robot/dds/messages.h) and refgrasp's values.
//
// Outgoing messages are built by the *Out classes below: each owns the strings and arrays its C
// struct points to (the pixels of an image are borrowed, never copied: the DDS writer serialises
// them straight from the cv::Mat). They are neither copyable nor movable; msg() is valid while the
// object (and a borrowed image) lives.
// Incoming messages are checked; a bad one gives a one-line reason, never an exception.
#include <array>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/pose.h"
#include "core/types.h"
#include "robot/dds/messages.h"

namespace refgrasp::dds {

// ---- time -----------------------------------------------------------------------------------------

/// builtin_interfaces/Time from seconds (negative times allowed: sec < 0, nanosec in [0, 1e9)).
msg::Time toRosTime(Seconds t);
Seconds fromRosTime(const msg::Time& t);
msg::Duration toRosDuration(Seconds d);
Seconds fromRosDuration(const msg::Duration& d);

// ---- images ---------------------------------------------------------------------------------------

/// The sensor_msgs/image_encodings refgrasp decodes (8 bits per channel): mono8 (and 8UC1),
/// rgb8, bgr8, rgba8, bgra8, bayer_rggb8, bayer_bggr8, bayer_gbrg8, bayer_grbg8.
const std::vector<std::string>& supportedEncodings();
/// Bytes per pixel of a supported encoding, 0 for an unsupported one.
int bytesPerPixel(const std::string& encoding);

struct GrayImage {
  cv::Mat gray;       ///< CV_8UC1 width x height; mono8 points INTO the message (no copy)
  bool copied = false;///< true when the pixels were converted (colour, Bayer) into new memory
  std::string error;  ///< why the message cannot be used (then gray is empty)
  bool ok() const { return error.empty(); }
};

/// 8-bit gray view or conversion of an Image: checks the encoding, a non-empty size,
/// step >= width x bytes per pixel and data size == height x step. Colour and Bayer images are
/// converted in one pass (ROS Bayer names are the 2x2 pattern at the top-left pixel).
GrayImage toGray(const msg::Image& image);

/// A sensor_msgs/Image borrowing `image` (CV_8UC1 -> mono8, CV_8UC3 -> bgr8; continuous).
class ImageOut {
 public:
  ImageOut(const cv::Mat& image, Seconds stamp, const std::string& frame_id);
  ImageOut(const ImageOut&) = delete;
  ImageOut& operator=(const ImageOut&) = delete;
  const msg::Image& msg() const { return m_; }
  msg::Image& msg() { return m_; }

 private:
  cv::Mat image_;
  std::string frame_id_, encoding_;
  msg::Image m_;
};

// ---- camera info ----------------------------------------------------------------------------------

/// Intrinsics of a camera_info: K and plumb_bob D (rational_polynomial with k4..k6 = 0 also).
/// Empty with *error set when the camera is uncalibrated (K[0] = 0), the size is not positive,
/// the distortion model is not supported, or binning / a region of interest is set.
std::optional<Intrinsics> toIntrinsics(const msg::CameraInfo& info, std::string* error);

/// camera_info for `cam`: K, plumb_bob D, R = I, P = [K | (Tx, 0, 0)] with Tx = -fx * baseline_m
/// (0 for a mono camera or the left eye; the right eye of a horizontal rig, ROS's convention).
class CameraInfoOut {
 public:
  CameraInfoOut(const Intrinsics& cam, Seconds stamp, const std::string& frame_id,
                double baseline_m = 0);
  CameraInfoOut(const CameraInfoOut&) = delete;
  CameraInfoOut& operator=(const CameraInfoOut&) = delete;
  const msg::CameraInfo& msg() const { return m_; }
  msg::CameraInfo& msg() { return m_; }

 private:
  std::string frame_id_;
  std::array<double, 5> d_;
  msg::CameraInfo m_;
};

// ---- geometry -------------------------------------------------------------------------------------

/// Pose -> geometry_msgs/Pose (unit quaternion with w >= 0).
msg::Pose toRosPose(const Pose& p);
/// geometry_msgs/Pose -> Pose; the quaternion is normalised (a zero quaternion gives identity).
Pose fromRosPose(const msg::Pose& p);
msg::Vector3 toRosVector(const Eigen::Vector3d& v);

/// A header borrowing `frame_id`.
msg::Header makeHeader(Seconds stamp, const std::string& frame_id);

// ---- joints ---------------------------------------------------------------------------------------

/// sensor_msgs/JointState or trajectory_msgs/JointTrajectory (one point) being built.
class JointStateOut {
 public:
  JointStateOut(Seconds stamp, const std::string& frame_id = "");
  JointStateOut(const JointStateOut&) = delete;
  JointStateOut& operator=(const JointStateOut&) = delete;
  void add(const std::string& name, double position, double velocity, double effort = 0);
  /// The message (pointers refreshed; valid until the next add()).
  const msg::JointState& msg();

 private:
  std::string frame_id_;
  Seconds stamp_;
  std::vector<std::string> names_;
  std::vector<char*> name_ptrs_;
  std::vector<double> pos_, vel_, eff_;
  msg::JointState m_;
};

/// A JointTrajectory with one point: positions or velocities for `joints`, reached / valid at
/// time_from_start.
class TrajectoryOut {
 public:
  enum class Kind { kPositions, kVelocities };
  TrajectoryOut(Seconds stamp, const std::vector<std::string>& joints, Kind kind,
                const std::vector<double>& values, Seconds time_from_start);
  TrajectoryOut(const TrajectoryOut&) = delete;
  TrajectoryOut& operator=(const TrajectoryOut&) = delete;
  const msg::JointTrajectory& msg() const { return m_; }

 private:
  std::vector<std::string> names_;
  std::vector<char*> name_ptrs_;
  std::vector<double> values_;
  msg::JointTrajectoryPoint point_;
  msg::JointTrajectory m_;
};

/// Index of `name` in a received string sequence, -1 when absent.
int indexOf(const dds_sequence_string& names, const std::string& name);
/// Element i of a double sequence, or `fallback` when the sequence is shorter.
double at(const dds_sequence_double& s, int i, double fallback = 0);

}  // namespace refgrasp::dds
