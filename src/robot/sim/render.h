#pragma once
// Exact-perspective renderer of textured rectangles, for the synthetic camera and for tests.
//
// Planar-object convention (DEVELOPERS.md): the plane frame p has its origin at the texture centre,
// x along texture columns, y along rows, z = 0 on the plane; the texture is visible from the -z
// side. Texture pixel (u,v) (pixel centres, 0-based) sits at ((u-(W-1)/2)*sx, (v-(H-1)/2)*sy, 0)
// with sx = width_m / W, sy = height_m / H; the outer texture edges are at x = ±width_m/2,
// y = ±height_m/2. Images are CV_8UC1; pixel centre of the top-left pixel is (0,0).
#include <Eigen/Core>
#include <array>
#include <opencv2/core.hpp>
#include <vector>

#include "core/camera.h"
#include "core/cylinder.h"
#include "core/pose.h"

namespace refgrasp::sim {

struct TexturedPlane {
  cv::Mat texture;  ///< CV_8UC1; treated as immutable once rendered (its pyramid is cached)
  double width_m = 0, height_m = 0;
  Pose cMp;  ///< plane frame in the camera frame (an object's faces hold oMp here instead)
};

/// A cylinder with a label wrapped on it (a can, a bottle), in its object frame o
/// (core/cylinder.h: origin at the label's centre on the surface, y along the axis, z into the
/// object, the axis the line x = 0, z = r). The side spans y in [-height_m/2, height_m/2]; the caps
/// are the discs at its two ends.
struct TexturedCylinder {
  cv::Mat label;  ///< CV_8UC1, wrapped as core/cylinder.h describes (immutable once rendered)
  double radius_m = 0, label_width_m = 0, label_height_m = 0, height_m = 0;
  /// The side where the label does not cover it, wrapped once round the whole side: columns
  /// from theta = -pi to pi (theta = 0 at the label's centre), rows from y = -height_m/2 to
  /// height_m/2. Empty: uniform side_gray.
  cv::Mat side_texture;
  /// Both caps: the disc inscribed in it, columns along x, rows along z. Empty: cap_gray.
  cv::Mat cap_texture;
  int side_gray = 200, cap_gray = 170;
  Pose cMo;  ///< object frame in the camera frame (metres, radians)

  /// The label's geometry on this cylinder (core/cylinder.h).
  CylinderLabel geometry() const { return {radius_m, label_width_m, label_height_m, label.cols, label.rows}; }
};

struct RenderOptions {
  bool antialias_edges = true;  ///< alpha-blend a sub-pixel coverage mask at plane edges
  bool mipmap = true;           ///< sample a cv::pyrDown level (chosen per row) so minified textures do not alias
  double near_m = 0.01;         ///< near clipping plane (camera z, metres); parts closer are cut
  int background_gray = 128;    ///< fill when no background image is given
  void check() const;
};

/// Renders `planes` over `background` as seen by `cam` (cam.width x cam.height, CV_8UC1).
/// background: CV_8UC1 (or 3-channel, converted), resized to the output when its size differs;
/// empty -> constant background_gray. Planes seen from their +z side are culled; planes crossing
/// the near plane are clipped. Occlusion: a per-pixel depth test, with planes drawn far to near by
/// the distance of their centres so that anti-aliased edges blend over what lies behind them
/// (an edge pixel of a far plane drawn after a nearer one is skipped, not blended).
/// With lens distortion the ideal pinhole image is rendered, then remapped so that the output
/// obeys Intrinsics::project.
cv::Mat renderView(const Intrinsics& cam, const std::vector<TexturedPlane>& planes,
                   const cv::Mat& background, const RenderOptions& opt = {});
/// The same with cylinders among the planes (one depth test for all; a cylinder's silhouette is
/// anti-aliased by 4 x 4 supersampling, its texture mipmapped like a plane's). Throws
/// std::invalid_argument on a cylinder with an empty label or non-positive sizes.
cv::Mat renderView(const Intrinsics& cam, const std::vector<TexturedPlane>& planes,
                   const std::vector<TexturedCylinder>& cylinders, const cv::Mat& background,
                   const RenderOptions& opt = {});

/// renderView of a camera without lens distortion that also returns, in *inv_depth (CV_32F, the
/// image's size), 1 / camera z (1/m) of the surface each pixel shows, 0 where the background
/// shows: for drawing more over the image with a depth test. The image is the same bits as
/// renderView's. Throws std::invalid_argument for a camera with distortion.
cv::Mat renderViewWithDepth(const Intrinsics& cam, const std::vector<TexturedPlane>& planes,
                            const std::vector<TexturedCylinder>& cylinders, const cv::Mat& background,
                            const RenderOptions& opt, cv::Mat* inv_depth);

/// Homography from level-0 texture pixels to ideal (undistorted) image pixels, x_img ~ H x_tex.
Eigen::Matrix3d textureToImage(const Intrinsics& cam, const TexturedPlane& plane);

/// Outer corners of the texture (pixel-edge corners, (±width/2, ±height/2, 0)) projected with
/// Intrinsics::project (distortion included), order TL, TR, BR, BL. Requires the corners at z > 0.
std::array<Eigen::Vector2d, 4> projectPlaneCorners(const Intrinsics& cam, const TexturedPlane& plane);

}  // namespace refgrasp::sim
