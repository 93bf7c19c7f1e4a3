#pragma once
// 6-DOF pose of a planar pattern from a homography (the paper, Section III-C) or from all
// inlier correspondences (IPPE + robust refinement).
//
// Frames: o = object frame, p = pattern-plane frame (z = 0 on the textured plane), c = camera.
// Pixels here are UNDISTORTED pixels (what an ideal pinhole with the camera's K sees): callers
// undistort keypoints before matching, so H and every 2D point below live in that space.
#include <Eigen/Core>
#include <array>
#include <optional>
#include <vector>

#include "core/pose.h"

namespace refgrasp::detector {

enum class PoseMethod {
  kPaper,    ///< eq. 7 + SVD orthonormalisation + LM on the four pattern corners
  kRefined,  ///< IPPE over all inliers + robust (Huber) LM over all inliers
};
const char* poseMethodName(PoseMethod m);

/// What pose estimation needs to know about a planar object (built once per object).
struct PlanarTarget {
  Eigen::Matrix3d K_ref = Eigen::Matrix3d::Identity();  ///< reference camera, pixels
  Pose ref_cMo;                                         ///< object frame in reference camera
  Pose oMp;                                             ///< pattern-plane frame in object frame
  std::array<Eigen::Vector2d, 4> corners_ref_px;        ///< pattern corners, undistorted ref px
  std::array<Eigen::Vector3d, 4> corners_o;             ///< same corners on the plane, object frame

  /// Undistorted reference pixel -> point on the pattern plane, object frame (metres).
  /// Empty when the viewing ray does not hit the plane in front of the reference camera.
  std::optional<Eigen::Vector3d> backProject(const Eigen::Vector2d& ref_px) const;
};

/// Builds a PlanarTarget; the plane is {X_o : n.X_o = offset} (n need not be unit).
/// Returns empty when n is zero or a corner's ray misses the plane in front of the camera.
std::optional<PlanarTarget> makePlanarTarget(const Eigen::Matrix3d& K_ref, const Pose& ref_cMo,
                                             const Eigen::Vector3d& plane_normal_o,
                                             double plane_offset_m,
                                             const std::array<Eigen::Vector2d, 4>& corners_ref_px);

struct PoseOptions {
  int paper_lm_iterations = 50;    ///< the paper's fixed count
  int refined_lm_iterations = 30;
  double huber_px = 1.0;           ///< robust loss threshold of the refined method (in sigmas)
  /// Refined method: 2D point sigma = keypoint_sigma_per_size x SIFT keypoint size (scene px),
  /// since SIFT localisation error grows with the keypoint's scale. 0: every point 1 px.
  double keypoint_sigma_per_size = 0.1;
  double min_corner_depth_m = 1e-3;
  void check() const;
};

struct PoseResult {
  bool ok = false;
  Pose cMo;             ///< object frame in scene camera frame (metres, radians)
  double rms_px = 0;    ///< RMS reprojection error of the points the method minimised
  int iterations = 0;
};

/// Eq. 7 applied to the plane: [r1 r2 t]_s = k K_s^-1 H K_ref [r1 r2 t]_ref in the plane frame,
/// k = 2 / (|c1| + |c2|) with the sign putting the pattern in front; r3 = r1 x r2; R <- U V^T.
/// H maps undistorted reference px to undistorted scene px (x_s ~ H x_r).
std::optional<Pose> poseFromHomography(const Eigen::Matrix3d& H, const PlanarTarget& target,
                                       const Eigen::Matrix3d& K_scene);

/// Paper method: poseFromHomography, then LM on the four corners y_i = H x_i (fixed iterations).
PoseResult estimatePosePaper(const Eigen::Matrix3d& H, const PlanarTarget& target,
                             const Eigen::Matrix3d& K_scene, const PoseOptions& opt);

/// Refined method: IPPE (cv::solvePnP) over all 3D-2D pairs (object frame points on the pattern
/// plane, undistorted scene px), then Huber-robust LM over the same pairs. sigma_px: expected
/// localisation error of each 2D point (empty = 1 px each); residuals are divided by it.
PoseResult estimatePoseRefined(const std::vector<Eigen::Vector3d>& points_o,
                               const std::vector<Eigen::Vector2d>& points_px,
                               const PlanarTarget& target, const Eigen::Matrix3d& K_scene,
                               const PoseOptions& opt, const std::vector<double>& sigma_px = {});

/// As estimatePoseRefined (equal sigmas), near a prior pose (tracking): a nearly affine view (a
/// small or far pattern) has two poses that reproject almost equally, IPPE's two solutions (at
/// 3.3 m, a 0.2 m pattern seen at 60 deg: 120 deg apart). Both are refined; of those whose RMS
/// is within ambiguity_margin_px of the best, the one nearest the prior in rotation is returned.
PoseResult estimatePoseRefinedNear(const std::vector<Eigen::Vector3d>& points_o,
                                   const std::vector<Eigen::Vector2d>& points_px,
                                   const PlanarTarget& target, const Eigen::Matrix3d& K_scene,
                                   const PoseOptions& opt, const Pose& prior, double ambiguity_margin_px);

/// Levenberg-Marquardt on reprojection error. Update: R <- exp([dw]x) R, t <- t + dt.
/// Residual i is divided by sigma_px[i] (empty: 1); huber (in those units) <= 0: plain least
/// squares. rms_px is the unweighted RMS. Returns ok=false if a point ends up behind the camera.
PoseResult refinePoseLM(const std::vector<Eigen::Vector3d>& points_o,
                        const std::vector<Eigen::Vector2d>& points_px, const Eigen::Matrix3d& K,
                        const Pose& initial_cMo, int iterations, double huber,
                        const std::vector<double>& sigma_px = {});

/// Residual r = project(K, cMo * X_o) - y (pixels) and its Jacobian with respect to the
/// update (dw, dt) above, columns [dw_x dw_y dw_z dt_x dt_y dt_z].
void reprojectionResidual(const Pose& cMo, const Eigen::Vector3d& X_o, const Eigen::Vector2d& y_px,
                          const Eigen::Matrix3d& K, Eigen::Vector2d* r,
                          Eigen::Matrix<double, 2, 6>* J);

/// Pinhole projection (no distortion) of a camera-frame point, pixels.
Eigen::Vector2d projectPinhole(const Eigen::Matrix3d& K, const Eigen::Vector3d& Xc);

}  // namespace refgrasp::detector
