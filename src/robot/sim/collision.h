#pragma once
// Collision geometry of the simulated enon: oriented boxes and cylinders (the world's solids),
// capsules (arm links, palm, fingers) and a vertical cylinder (the base body), with exact signed
// distances.
// All shapes are given in one frame (the world frame w in the simulator). Metres.
// Signed distance: > 0 the gap between the shapes, < 0 minus the penetration depth.
#include <Eigen/Core>

#include "core/pose.h"

namespace refgrasp::sim {

/// A solid box: wMb holds its centre and axes, half_m its half extents along those axes.
struct OrientedBox {
  Pose wMb;
  Eigen::Vector3d half_m = Eigen::Vector3d::Zero();
};

/// The points within radius_m of the segment a-b.
struct Capsule {
  Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();
  double radius_m = 0;
};

/// A solid cylinder of any orientation: wMc holds its centre and axes, its axis along z_c; it spans
/// z_c in [-half_height_m, half_height_m] (a can standing upright has z_c vertical).
struct OrientedCylinder {
  Pose wMc;
  double radius_m = 0, half_height_m = 0;
};

/// A cylinder with a vertical (world z) axis through `centre`, from z = z0_m up to z0_m + height_m.
struct VerticalCylinder {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  double z0_m = 0, height_m = 0, radius_m = 0;
};

/// Signed distance from a point to the box: the Euclidean distance outside, minus the distance
/// to the nearest face inside.
double signedDistance(const OrientedBox& box, const Eigen::Vector3d& p);

/// Minimum over the segment a-b of the point-to-box signed distance. The signed distance to a
/// convex set is convex, so its restriction to the segment is a convex function of the segment
/// parameter and a golden-section search bracketing the minimum is exact to `tolerance_m` (the
/// function is 1-Lipschitz in the position along the segment). `s` (optional) receives the
/// segment parameter in [0, 1] of the minimum.
double segmentSignedDistance(const OrientedBox& box, const Eigen::Vector3d& a,
                             const Eigen::Vector3d& b, double* s = nullptr,
                             double tolerance_m = 1e-9);

/// Capsule to box (segment distance minus the radius).
double signedDistance(const OrientedBox& box, const Capsule& c);

/// Vertical cylinder to box. Exact for a box with a vertical axis (tables, walls, upright objects):
/// both shapes are then prisms, and the distance combines the vertical gap with the disc-to-
/// rectangle distance in the horizontal plane. A tilted box is replaced by its world-axis-aligned
/// bounding box (never reports less contact than there is).
double signedDistance(const OrientedBox& box, const VerticalCylinder& c);

/// Length of the box's projection on the unit direction u (metres).
double extentAlong(const OrientedBox& box, const Eigen::Vector3d& u);

/// Signed distance from a point to the cylinder: outside, the Euclidean distance to the solid
/// (side, rim or cap); inside, minus the distance to the nearest of side and caps.
double signedDistance(const OrientedCylinder& c, const Eigen::Vector3d& p);

/// Minimum over the segment a-b of the point-to-cylinder signed distance: the same bracketed
/// convex minimisation as for a box (the signed distance to a convex set is convex), exact to
/// `tolerance_m`; `s` (optional) receives the segment parameter of the minimum.
double segmentSignedDistance(const OrientedCylinder& c, const Eigen::Vector3d& a,
                             const Eigen::Vector3d& b, double* s = nullptr,
                             double tolerance_m = 1e-9);

/// Capsule to cylinder (segment distance minus the radius).
double signedDistance(const OrientedCylinder& c, const Capsule& cap);

/// Vertical cylinder to cylinder. Exact when c's axis is vertical (an upright can): both are then
/// prisms over discs, and the distance combines the vertical gap with the gap between the discs.
/// Any other c is bounded by its world-axis-aligned box and by an upright cylinder about its
/// centre (the larger of the two distances: never reports less contact than there is, and
/// within max(half_height_m, radius_m) sin(tilt) of exact for a nearly upright c).
double signedDistance(const OrientedCylinder& c, const VerticalCylinder& v);

/// Length of the cylinder's projection on the unit direction u (metres): its diameter across
/// the axis, its height along it.
double extentAlong(const OrientedCylinder& c, const Eigen::Vector3d& u);

}  // namespace refgrasp::sim
