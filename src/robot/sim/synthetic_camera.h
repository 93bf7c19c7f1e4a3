#pragma once
// A simulated stereo camera: renders a World from a camera pose with the rig's intrinsics
// (distortion included), motion blur from the camera's own velocity, and the configured
// degradations. Deterministic: the same seed and the same sequence of calls give bit-identical images.
#include <cstdint>
#include <random>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"
#include "core/types.h"
#include "robot/sim/degrade.h"
#include "robot/sim/render.h"
#include "robot/sim/scenario.h"

namespace refgrasp::sim {

struct SyntheticFrame {
  cv::Mat left, right;  ///< CV_8UC1
  Seconds stamp = 0;
  std::vector<Pose> left_cMo, right_cMo;  ///< ground truth, one per world object, same order
};

/// Planes of every object face as seen from camera pose wMc (cMp = cMw * wMo * oMp).
std::vector<TexturedPlane> worldPlanes(const World& world, const Pose& wMc);
/// Cylinders of every object as seen from camera pose wMc (cMo = cMw * wMo * oMc).
std::vector<TexturedCylinder> worldCylinders(const World& world, const Pose& wMc);
/// The world as seen by `cam` at wMc: renderView of its planes and cylinders over its background.
cv::Mat renderWorld(const Intrinsics& cam, const World& world, const Pose& wMc, const RenderOptions& opt = {});

class SyntheticStereoCamera {
 public:
  /// deg: static degradations (its motion blur adds to the blur from the camera's motion).
  SyntheticStereoCamera(const StereoRig& rig, const Degradation& deg, uint64_t seed,
                        double exposure_s = 0.01, const RenderOptions& render = {});

  /// wMl: left camera pose in the world; the right eye is at wMl * rig.lMr. lVl: camera velocity
  /// in the left camera frame (m/s, rad/s); the blur of each eye is its image motion at the
  /// principal point (depth of the nearest object in view) during the exposure.
  SyntheticFrame render(const World& world, const Pose& wMl, const Twist& lVl, Seconds stamp);
  /// The same frame without images (left and right empty): the ground-truth poses, bit-identical
  /// to render()'s, for a fraction of the cost. Draws from the noise stream as render() does, so
  /// the images of later frames do not depend on which frames were rendered.
  SyntheticFrame poses(const World& world, const Pose& wMl, Seconds stamp);

  const StereoRig& rig() const { return rig_; }

 private:
  cv::Mat renderEye(const Intrinsics& cam, const World& world, const Pose& wMc, const Twist& cVc,
                    std::mt19937_64& rng, std::vector<Pose>* cMo) const;

  StereoRig rig_;
  Degradation deg_;
  double exposure_s_;
  RenderOptions render_;
  std::mt19937_64 rng_;
};

}  // namespace refgrasp::sim
