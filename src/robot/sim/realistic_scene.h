#pragma once
// Test data that looks like the world, for detector evaluation: a reference that is a PHOTOGRAPH
// of the pattern (another camera, oblique, other distance and light, its own blur, noise and
// JPEG, the pattern region traced on it as a polygon) and scenes with what real cameras add
// (lighting, specular highlight, defocus and motion blur, vignetting, noise, Bayer demosaicing,
// JPEG, partial occlusion, real photographs in the background). Ground truth by construction;
// everything is deterministic given the seeds. Images are CV_8UC1.
//
// Frames: the object frame of a reference photo is the texture plane's frame (render.h: origin at
// the texture centre, x along columns, y along rows, z away from the viewer), so a scene's true
// cMo is the cMp the plane was rendered at.
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

/// What a real camera and the light add to an ideal render, in the order applied: lighting
/// (gain, gamma, a linear gradient, a specular highlight), optics (defocus, motion blur,
/// vignetting), sensor (Gaussian noise, Bayer mosaic + demosaicing), JPEG compression.
struct CameraLook {
  double gain = 1;                  ///< out = 255 (gain in / 255)^gamma before the gradient
  double gamma = 1;
  double gradient = 0;              ///< relative brightness change from one image side to the other
  double gradient_angle_rad = 0;    ///< direction of the gradient (0: along +u)
  double highlight = 0;             ///< specular highlight peak, gray levels added (0: none)
  Eigen::Vector2d highlight_px = Eigen::Vector2d::Zero();  ///< its centre
  double highlight_radius_px = 30;  ///< its Gaussian radius (sigma)
  double defocus_sigma_px = 0;      ///< Gaussian blur
  double motion_blur_px = 0;
  double motion_blur_angle_rad = 0;
  double vignetting = 0;            ///< relative darkening at the image corners (cos^4-like)
  double noise_sigma = 0;           ///< gray levels
  bool bayer = false;               ///< RGGB mosaic then OpenCV's bilinear demosaicing, to gray
  int jpeg_quality = 0;             ///< 1-100; 0: no compression
};

/// Applies the look to a CV_8UC1 image in place; rng draws the noise.
void applyCameraLook(cv::Mat& img, const CameraLook& look, std::mt19937_64& rng);

/// A look drawn at random: `strength` 0 (ideal) .. 1 (the harshest of the realistic ranges:
/// gain 0.55-1.45, gamma 0.65-1.5, gradient up to 45 %, highlight up to 110 gray levels, defocus
/// up to 1.4 px, motion blur up to 4 px, vignetting up to 40 %, noise 1-4, JPEG 45-90).
/// `highlight_near` centres a highlight (if any) near that image point.
CameraLook randomCameraLook(std::mt19937_64& rng, double strength, const Eigen::Vector2d& highlight_near);

/// A photograph of a planar pattern taken to define the object (what make_reference is given).
struct ReferencePhoto {
  cv::Mat image;                           ///< cropped around the pattern, CV_8UC1
  Intrinsics camera;                       ///< of the cropped photo (another camera than the scenes')
  Pose cMo;                                ///< texture plane (object frame) in that camera
  std::vector<Eigen::Vector2d> polygon_px; ///< pattern region traced on the photo (4-8 vertices)
  std::array<Eigen::Vector2d, 4> corners_px;  ///< true texture corners in the photo, TL TR BR BL
  double tilt_rad = 0;                     ///< angle between the plane normal and the viewing ray
  double width_px = 0;                     ///< pattern width in the photo (mean of top and bottom edges)
};

struct ReferencePhotoSpec {
  double tilt_rad = 0;         ///< 0: fronto-parallel
  double width_px = 300;       ///< about this wide in the photo (sets the distance)
  double look_strength = 0.6;  ///< randomCameraLook strength
  uint64_t seed = 0;           ///< camera, tilt direction, background, look, tracing
};

/// Renders the pattern (width_m x height_m) with a 800x600 or 1024x768 camera (by seed) over a
/// cluttered background, applies a look, crops the photo to the pattern plus a margin and traces
/// the pattern's outline (corners within ~0.5 px, sometimes with extra vertices on the edges).
ReferencePhoto photographReference(const cv::Mat& texture, double width_m, double height_m,
                                   const ReferencePhotoSpec& spec);

/// Clutter background (clutterBackground) with 2-4 real photographs of media/photos/ pasted in
/// (never those listed in `exclude`, relative media paths), seeded.
cv::Mat photoClutterBackground(uint64_t seed, int width, int height,
                               const std::vector<std::string>& exclude);

/// The real photographs in media/photos/ used as textures (relative paths for loadMedia).
const std::vector<std::string>& photoTextures();

struct RealisticSceneSpec {
  Pose cMo;                    ///< the target plane in the scene camera
  CameraLook look;
  double occlusion = 0;        ///< fraction of the target's bounding box covered from one side
  uint64_t seed = 0;           ///< background, occluder, noise
  std::vector<std::string> exclude_from_background;  ///< e.g. the target's own photo
};

struct RealisticScene {
  cv::Mat image;
  Pose cMo;
  std::array<Eigen::Vector2d, 4> corners;  ///< outer texture corners in the image, TL TR BR BL
};

/// Photo clutter background, the target and `others` (distractor planes, each at its cMp),
/// an occluder over the target, then the camera look. texture empty: no target (a clutter frame).
RealisticScene renderRealisticScene(const Intrinsics& cam, const cv::Mat& texture, double width_m,
                                    double height_m, const RealisticSceneSpec& spec,
                                    const std::vector<sim::TexturedPlane>& others = {});

}  // namespace refgrasp::testing
