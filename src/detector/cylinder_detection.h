#pragma once
// Cylinder objects (a label on a can, a bottle, a jar; core/cylinder.h) detected on their
// cylinder model: the refined pose method (DetectorOptions::pose kRefined). Under the paper method
// a cylinder is its flat label on the tangent plane at its centre and takes the planar path
// unchanged (the paper's planar approximation). Internal to the detector library; why each step:
// docs/detector.md "Cylinders".
//
//   1. Matching: the paper matcher on the label's reference index finds the band of the label
//      facing the camera, where the surface is planar within ransac_reproj_px (a consensus
//      homography). A full-wrap label is matched a second time rolled by W/2 (its seam in the
//      middle), so that a view centred on the seam is found too.
//   2. Pose: the band's inliers, reference px -> label points on the surface
//      (CylinderLabel::point), robust PnP (SQPnP in RANSAC), then Huber LM on its inliers
//      (refinePoseLM, sigma from the scene keypoint size).
//   3. Guided expansion, twice: every label feature whose surface point faces the camera is
//      projected at the pose and matched to the scene features near the prediction (orientation
//      and size predicted by the local projection's Jacobian, descriptor-nearest, local ratio);
//      the pose is refitted to them robustly.
//   4. Photometric refinement of the pose over the visible label (cylinder_dense.h), kept when the
//      label agrees better with the scene and the expanded features still fit.
//   5. Checks: the matcher's band consensus must agree with the pose; the sanity check on the
//      visible part's projected corners and the distance; the label rendered on the cylinder at
//      the pose compared with the scene over the visible part only (zero-mean NCC overall and
//      over 3 x 3 cells, VerifyOptions' thresholds): the hidden half never counts against it.
//
// Detection of a cylinder: cMo = the cylinder's object frame (core/cylinder.h) in the camera
// frame; H = the matcher's band homography, label px -> undistorted scene px (across a full-wrap
// label's seam: the label's columns continued past its right edge, u + W); corners = the
// projected corners TL, TR, BR, BL of the label's visible part (its columns facing the camera,
// its top and bottom rows), image px.
#include <optional>
#include <utility>
#include <vector>

#include "detector/checks.h"
#include "detector/registered_object.h"

namespace refgrasp::detector {

/// The cylinder model's parts of a registered cylinder object (seam index, label features);
/// sets cylinder_model and turns the dense (homography) refinement off.
void registerCylinder(RegisteredObject* obj, const DetectorOptions& opt);

/// The matcher on a registered object: matchObjectUnchecked on its index, and for a full-wrap
/// cylinder also on its seam index (those candidates' Correspondence::ref count on from
/// index.features.size()); at most match.max_instances candidates, disjoint in the scene, the
/// more inliers first.
MatchResult matchRegistered(const RegisteredObject& obj, const Features& scene, const GridIndex& grid,
                            const MatchOptions& opt);

/// Steps 2-5 on a candidate of matchRegistered for an object with cylinder_model.
Verdict verifyCylinderCandidate(const CandidateContext& ctx, const MatchCandidate& matched);

/// Label px (columns unwrapped around the visible part) of the label's part facing a camera at
/// cMo: columns [u0, u1] and rows [0, H-1]. Empty when no column of the label faces it.
struct VisibleLabel {
  double u0 = 0, u1 = 0;  ///< label columns (may leave [0, W) on a full-wrap label)
  double v0 = 0, v1 = 0;  ///< label rows
};
/// The part of the label whose surface faces the camera by more than cos_margin (see
/// CylinderLabel::facesCamera), clipped to a partial label's columns.
std::optional<VisibleLabel> visibleLabel(const CylinderLabel& label, const Pose& cMo, double cos_margin);

/// Points of the visible part on a grid of n x n label px, projected by `camera` (distortion
/// included) at cMo; those behind the camera are left out. For the search region of a prior.
std::vector<Eigen::Vector2d> projectVisibleLabel(const CylinderLabel& label, const Pose& cMo, const Intrinsics& camera,
                                                 int n);

/// The smallest and largest scene sizes (px) of the label features facing a camera at cMo
/// (their reference size times the local scale of the projection there); empty when none does.
std::optional<std::pair<double, double>> predictedKeypointSizes(const RegisteredObject& obj, const Pose& cMo,
                                                                const Intrinsics& camera);

}  // namespace refgrasp::detector
