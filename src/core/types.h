#pragma once
// Small value types shared by every module.
#include <Eigen/Core>
#include <cstdint>

namespace refgrasp {

/// Time stamps and periods, seconds. Simulation time starts at 0; hardware uses a steady clock.
using Seconds = double;

/// Identifies a camera frame across tools (detector results, tracker, recordings, DDS):
/// capture time (exposure centre, seconds on the source's clock) and the source's frame counter.
struct FrameStamp {
  Seconds stamp = 0;
  int64_t index = -1;  ///< -1 when unknown
};

/// A velocity screw: linear v (m/s) and angular w (rad/s), expressed in the frame its name says
/// (e.g. eVe: end-effector velocity in the end-effector frame).
struct Twist {
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  Eigen::Vector3d w = Eigen::Vector3d::Zero();
  Eigen::Matrix<double, 6, 1> vector() const {
    Eigen::Matrix<double, 6, 1> x;
    x << v, w;
    return x;
  }
  static Twist fromVector(const Eigen::Matrix<double, 6, 1>& x) {
    Twist tw;
    tw.v = x.head<3>();
    tw.w = x.tail<3>();
    return tw;
  }
};

}  // namespace refgrasp
