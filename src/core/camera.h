#pragma once
// Camera intrinsics and stereo rigs, and the files they come from.
//
// Pixel convention (OpenCV, ROS, ViSP alike): the centre of the top-left pixel is (0, 0),
// u grows to the right, v downwards. Camera frame: x right, y down, z forward (optical axis).
#include <Eigen/Core>
#include <array>
#include <string>

#include "core/pose.h"

namespace refgrasp {

struct Intrinsics {
  int width = 0, height = 0;   ///< pixels
  double fx = 0, fy = 0;       ///< focal lengths, pixels
  double cx = 0, cy = 0;       ///< principal point, pixels
  /// OpenCV "plumb_bob" distortion k1 k2 p1 p2 k3 (all zero: an ideal pinhole).
  std::array<double, 5> dist{0, 0, 0, 0, 0};

  static Intrinsics pinhole(int width, int height, double f, double cx, double cy);
  Eigen::Matrix3d K() const;
  bool hasDistortion() const;
  /// Throws std::invalid_argument on non-positive size or focal length, or non-finite values.
  void check() const;

  /// Camera-frame point (metres, z > 0) -> distorted pixel.
  Eigen::Vector2d project(const Eigen::Vector3d& Xc) const;
  /// Normalised undistorted coordinates (x/z, y/z) -> distorted pixel.
  Eigen::Vector2d distortNormalized(const Eigen::Vector2d& xn) const;
  /// Distorted pixel -> normalised undistorted coordinates (iterative inverse of the model).
  Eigen::Vector2d undistortToNormalized(const Eigen::Vector2d& px) const;
  /// Distorted pixel -> the pixel an ideal pinhole with the same K would have seen.
  Eigen::Vector2d undistortPixel(const Eigen::Vector2d& px) const;
};

/// Reads a camera file: ROS camera_info YAML (.yaml/.yml, as written by camera_calibration)
/// or ViSP's camera XML (.xml, as vpXmlParserCamera writes it; the first <camera>, its
/// perspectiveProjWithDistortion model preferred).
/// Throws ConfigError naming the file and field.
Intrinsics loadCameraFile(const std::string& path);
/// Writes ROS camera_info YAML.
void saveCameraFile(const std::string& path, const Intrinsics& cam, const std::string& name);

/// A calibrated stereo pair. lMr: pose of the right camera frame in the left camera frame
/// (x_in_left = lMr * x_in_right); for a horizontal rig lMr.t ~ (baseline, 0, 0).
struct StereoRig {
  Intrinsics left, right;
  Pose lMr;
  double baseline() const { return lMr.t.norm(); }
};

/// Reads a rig YAML: {left: CAM_FILE, right: CAM_FILE, right_in_left: {translation, rotation_vector}}
/// with camera paths relative to the rig file.
StereoRig loadStereoRig(const std::string& path);
/// Writes a rig YAML that loadStereoRig reads; left_file/right_file are written as given (paths
/// relative to the rig file), the camera files themselves are not written.
void saveStereoRig(const std::string& path, const StereoRig& rig, const std::string& left_file,
                   const std::string& right_file);

}  // namespace refgrasp
