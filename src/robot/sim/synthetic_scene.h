#pragma once
// Synthetic scenes with ground truth by construction, for detector and pose tests: a textured
// target rendered at a known cMo over a cluttered background, then degraded (noise, blur).
// Everything is deterministic given the seeds. Images are CV_8UC1.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <opencv2/core.hpp>
#include <random>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"
#include "robot/sim/render.h"

namespace refgrasp::testing {

/// 640x480, f = 550 px, c = (319.5, 239.5), no distortion.
Intrinsics sceneCamera();

/// The project's media/ folder: $REFGRASP_MEDIA_DIR when set, else the source tree's media/.
std::string mediaDir();

/// A media texture, e.g. loadMedia("targets/cereal_box.png"), as CV_8UC1 (cached after the first
/// load). Throws std::runtime_error naming the path when it is missing, so the test fails clearly.
cv::Mat loadMedia(const std::string& relpath);

/// The five target textures in media/targets/ (relative paths for loadMedia).
const std::vector<std::string>& targetTextures();

/// A cluttered procedural scene: gradient, shapes, text and patches of media/clutter textures at
/// random scales and rotations (never a target texture), varied brightness. Same seed -> same image.
cv::Mat clutterBackground(uint64_t seed, int width = 640, int height = 480);

/// A pose cMo of a width_m x height_m plane, visible from its -z side: distance of the centre from
/// the camera uniform in [min_dist_m, max_dist_m], tilt (angle between the plane normal and the
/// viewing ray to the centre) uniform in [0, max_tilt_rad], random tilt direction and in-plane
/// rotation, all four corners inside the image with a 10 px margin. Throws std::runtime_error when
/// no such pose is found (e.g. the plane cannot fit in the image at that distance).
Pose randomVisiblePose(std::mt19937_64& rng, const Intrinsics& cam, double width_m, double height_m,
                       double min_dist_m, double max_dist_m, double max_tilt_rad);
/// randomVisiblePose with the tilt drawn in [min_tilt_rad, max_tilt_rad] (the same draws).
Pose randomVisiblePoseIn(std::mt19937_64& rng, const Intrinsics& cam, double width_m, double height_m,
                         double min_dist_m, double max_dist_m, double min_tilt_rad, double max_tilt_rad);

struct SceneSpec {
  Pose cMo;
  double noise_sigma = 2.0;  ///< gray levels
  double motion_blur_px = 0;
  double motion_blur_angle_rad = 0;
  uint64_t seed = 0;  ///< background and noise
};

struct RenderedScene {
  cv::Mat image;
  Pose cMo;                                ///< the (first) target
  std::array<Eigen::Vector2d, 4> corners;  ///< its outer texture corners in the image, TL TR BR BL
  std::vector<Pose> all_cMo;               ///< every target, in the order given
  std::vector<std::array<Eigen::Vector2d, 4>> all_corners;
};

/// Clutter background (seeded) + target at spec.cMo + degradation.
RenderedScene renderTarget(const Intrinsics& cam, const cv::Mat& texture, double width_m,
                           double height_m, const SceneSpec& spec);

/// Several targets or instances (each plane's cMp is its cMo) over one background; spec.cMo is
/// ignored, the rest of spec (noise, blur, seed) applies.
RenderedScene renderTargets(const Intrinsics& cam, const std::vector<sim::TexturedPlane>& targets,
                            const SceneSpec& spec);

}  // namespace refgrasp::testing
