#pragma once
// A registered object: what Detector::addObject() computes once from an object definition, and
// the geometry every stage after matching computes on it (pose, dense alignment, the region a
// candidate is verified on). Internal to the detector library.
//
// Pixels: "und" = undistorted by the reference camera (reference side) or the scene camera
// (scene side). H maps undistorted reference px -> undistorted scene px (x_s ~ H x_r).
#include <Eigen/Core>
#include <array>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "core/camera.h"
#include "detector/dense.h"
#include "detector/detector.h"
#include "detector/matching.h"
#include "detector/object.h"
#include "detector/pose.h"
#include "detector/reference_index.h"

namespace refgrasp::detector {

struct RegisteredObject {
  ObjectModel model;
  ReferenceIndex index;
  /// A 2D-only object's every reference feature inside the pattern (index without its cap), when
  /// the cap left some out: its final feature fit (refitUnderHomography) uses them all.
  std::optional<ReferenceIndex> uncapped_index;
  std::array<Eigen::Vector2d, 4> corners_und_px;  ///< pattern corners TL, TR, BR, BL, und ref px
  std::vector<Eigen::Vector2d> polygon_und_px;    ///< pattern region, und ref px
  std::vector<cv::Mat> pyramid;  ///< reference pyramid (level 0 = the reference image)
  bool dense_usable = false;     ///< dense refinement possible (undistorted reference, exact region)
  bool region_is_rect = true;    ///< the region is its bounding box (no mask needed)
  /// repeatPeriods(index): displacements in the rectified pattern plane that carry many features
  /// onto look-alikes (a facade's windows); empty for most references.
  std::vector<Eigen::Vector2d> periods;
  /// The object is detected on its cylinder model (detector/cylinder_detection.h): a cylinder
  /// object under the refined pose method. false for planar objects and for a cylinder under
  /// the paper method (its flat label on the tangent plane: the planar path).
  bool cylinder_model = false;
  /// A full-wrap label on its cylinder model: the label rolled by W/2 columns (its seam in the
  /// middle), so that a view centred on the seam is matched too. Its features' reference px are
  /// rolled label px (label column = rolled column + W/2, modulo W).
  std::optional<ReferenceIndex> seam_index;
  /// Cylinder model: every label feature once, keypoints in label px (a full-wrap label's
  /// columns within W/4 of its seam from seam_index, the others from index), for the guided
  /// expansion over the visible half.
  Features label_features;
  /// A planar object with match.plane_views: the same object whose index also holds the
  /// reference's view-synthesised features (detector/plane_views.h). Matched only when the
  /// object's own features find nothing in a frame: the views find far and oblique faces, and
  /// where the own features suffice their fit is the more precise (docs/detector.md, step 1).
  std::shared_ptr<const RegisteredObject> with_views;
};

/// Reference features, index, pyramid and periods of `object` (a non-empty 8-bit gray reference).
RegisteredObject registerObject(const ObjectModel& object, const DetectorOptions& opt);

/// Keypoints moved to undistorted px (nothing without distortion).
void undistortKeypoints(std::vector<cv::KeyPoint>* kps, const Intrinsics& cam);
/// Undistorted pixel -> real image pixel.
Eigen::Vector2d distortPixel(const Intrinsics& cam, const Eigen::Vector2d& und);

/// The pattern's diagonal under H (und scene px): the mean of its two corner diagonals.
double patternDiagonal(const RegisteredObject& obj, const Eigen::Matrix3d& H);

/// The size of one pixel of the template `d` was aligned on (its pyramid level), in scene px:
/// 2^level times the pattern's scale under d.H (square root of the area ratio, scene over
/// reference). A dense alignment localises no finer than that. 0 when d has no level.
double densePixelInScene(const RegisteredObject& obj, const DenseRefineResult& d);

/// Fraction of the pattern's projection under H (und scene px) inside the frame; 0 when it is
/// degenerate or crosses the vanishing line.
double inViewFraction(const RegisteredObject& obj, const Eigen::Matrix3d& H, const Intrinsics& camera);

/// The region of the reference (und ref px) a candidate is verified on: the pattern region, or,
/// when that only bounds the pattern (pattern_region_exact false), its part inside the convex
/// hull of the candidate's inliers.
std::vector<Eigen::Vector2d> verificationRegion(const RegisteredObject& obj, const MatchCandidate& cand);

/// Dense (ECC) refinement of H on `image` (the scene camera's raw image). With a distorting
/// camera only the pattern's neighbourhood is resampled to the pinhole grid.
DenseRefineResult refineDense(const RegisteredObject& obj, const Eigen::Matrix3d& H, const cv::Mat& image,
                              const Intrinsics& camera, const DenseRefineOptions& opt);

/// Pose (cMo) from a grid of pattern points mapped by a densely refined H. prior (tracking): of
/// the planar ambiguity's two poses, the one continuing the prior unless the other fits clearly
/// better (estimatePoseRefinedNear).
PoseResult poseFromDenseH(const RegisteredObject& obj, const DetectorOptions& opt, const Eigen::Matrix3d& H,
                          const Intrinsics& camera, const Pose* prior = nullptr);

/// Pose (cMo) of a matched candidate with `method`. dense: the dense refinement of match.H with
/// opt.dense when the caller already ran it. *from_features (when given): true when the pose was
/// fitted to the matched features (refined method without a usable dense alignment), false for
/// the paper pose or the dense grid. ok = false for 2D-only objects.
PoseResult estimatePose(const RegisteredObject& obj, const DetectorOptions& opt, const MatchCandidate& match,
                        const Features& scene, const Intrinsics& camera, PoseMethod method,
                        const DenseRefineResult* dense = nullptr, bool* from_features = nullptr);

}  // namespace refgrasp::detector
