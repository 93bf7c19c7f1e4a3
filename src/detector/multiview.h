#pragma once
// Several-view objects (ObjectModel::views, the faces of a box): each view is detected as an
// object of its own, then the views' instances are fused into instances of the object.
//
// Frames: o = the several-view object's frame, v = a view's object frame, c = the scene camera.
// A view's instance gives cMv; oMv comes from the definition, so cMo = cMv * oMv^-1.
//
// Fusion, per frame: the view instances are taken by decreasing inliers; each joins the first
// group whose first member (its seed) agrees with it (translation and rotation gaps within
// MultiViewOptions) and holds no instance of the same view, or starts a group. A group of two
// views or more gets a joint pose: Huber-robust LM (refinePoseLM) over every member's
// correspondences, started from the seed's cMo and kept when it still agrees with the seed (the
// seed's pose otherwise). Views that disagree are never averaged: each
// disagreeing group is an instance of its own, best (most inliers) first, so a wrong oMv or two
// boxes give two instances, not one pose between them.
//
// A member's measurement enters the joint fit as its own verified pose seen through a grid:
// pose_grid x pose_grid points over its pattern (a cylinder's: over the label, the half facing
// the camera), each paired with its projection under cMv, sigma the view's pose RMS (at least
// 0.1 px). Each view thus weighs with the precision of its own method (a dense alignment's grid
// fits to a fraction of a pixel, a fit to features to ~1 px), in the image where it was
// measured; refitting the views' SIFT inliers instead gave a joint pose several times less
// accurate than the better face's dense pose (docs/results.md "Several-view objects").
// Internal to the detector library.
#include <string>
#include <vector>

#include "detector/detector.h"
#include "detector/registered_object.h"

namespace refgrasp::detector {

/// One view's 3D-2D pairs: points in the several-view object's frame o (metres), undistorted
/// scene px, and each point's sigma (px).
struct ViewCorrespondences {
  std::vector<Eigen::Vector3d> points_o;
  std::vector<Eigen::Vector2d> points_px;
  std::vector<double> sigma_px;
  int size() const { return static_cast<int>(points_o.size()); }
};

/// One instance of one view in a frame.
struct ViewInstance {
  int view = -1;        ///< index into ObjectModel::views
  Detection detection;  ///< as the view's own detection: H, corners, cMo = cMv
  Pose cMo;             ///< the several-view object's frame in the camera frame
  ViewCorrespondences pairs;
};

/// The pairs of a view's instance (see the header comment): points in the object's frame o,
/// their projections under instance.cMo (undistorted px). oMv: the view's frame in o; detector:
/// the pose method (a cylinder view lies on the cylinder with the refined method, on its flat
/// label with the paper's) and dense.pose_grid. Empty when the view faces away.
ViewCorrespondences viewCorrespondences(const RegisteredObject& view, const Pose& oMv, const Detection& instance,
                                        const Intrinsics& camera, const DetectorOptions& detector);

/// True when two poses of the object agree within opt (translation gap <= max_gap_m +
/// max_gap_fraction x the nearer one's distance, rotation gap <= max_rotation_gap_rad).
bool posesAgree(const Pose& a, const Pose& b, const MultiViewOptions& opt);

/// The fused instances of one object, best first (instance numbers set, found = true): cMo the
/// joint pose (or the single view's), H and corners those of the member with the most inliers,
/// `view` its name, `views` every member's name in order of inliers, inliers the members' sum.
/// names[k]: the name of view k. K: the scene camera's pinhole matrix (undistorted px).
std::vector<Detection> fuseViews(std::vector<ViewInstance> instances, const std::vector<std::string>& names,
                                 const Eigen::Matrix3d& K, const PoseOptions& pose_options,
                                 const MultiViewOptions& opt);

}  // namespace refgrasp::detector
