// The oracle's visibility of a label on a cylinder (servo/target_estimator.h visibleLabel): the
// part of the label a camera sees on the surface, against the extents computed in closed form
// for a camera looking square at the axis (silhouette tangents, the label's edge).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <opencv2/core.hpp>

#include "detector/object.h"
#include "servo/target_estimator.h"

using namespace refgrasp;

namespace {

constexpr double kDeg = M_PI / 180;
constexpr double kF = 500;

Intrinsics pinhole() { return Intrinsics::pinhole(640, 480, kF, 319.5, 239.5); }

/// A camera `distance_m` from the axis of a cylinder of radius r, at mid-height of the label,
/// looking square at the axis from the direction of label angle theta_c (0: the label's centre
/// faces the camera); the label's y (its rows) along the camera's y.
Pose cameraFacing(double r, double theta_c, double distance_m) {
  const Eigen::Vector3d n(std::sin(theta_c), 0, -std::cos(theta_c));  // outward normal at theta_c
  const Eigen::Vector3d centre_o = Eigen::Vector3d(0, 0, r) + distance_m * n;
  Eigen::Matrix3d oRc;
  oRc.col(2) = -n;
  oRc.col(1) = Eigen::Vector3d::UnitY();
  oRc.col(0) = oRc.col(1).cross(oRc.col(2));
  return Pose(oRc, centre_o).inverse();
}

std::vector<Eigen::Vector2d> wholeLabel(const CylinderLabel& L) {
  const double W = L.image_width, H = L.image_height;
  return {{-0.5, -0.5}, {W - 0.5, -0.5}, {W - 0.5, H - 0.5}, {-0.5, H - 0.5}};
}

detector::ObjectModel can(double r, double label_w, double label_h) {
  cv::Mat label(120, 360, CV_8UC1);
  cv::randu(label, 0, 255);
  return detector::cylinderObject("can", label, r, label_w, label_h);
}

}  // namespace

TEST(OracleCylinder, ALabelAllRoundIsSeenBetweenTheSilhouettesNotLaidFlat) {
  const double r = 0.033, h = 0.10, D = 0.8;
  const CylinderLabel L{r, 2 * M_PI * r, h, 360, 120};
  const std::vector<Eigen::Vector2d> samples = servo::labelSamples(L, wholeLabel(L));
  const Pose cMo = cameraFacing(r, 0, D);
  const servo::VisibleLabel v = servo::visibleLabel(L, samples, cMo, pinhole(), 0, 0);
  // Across: between the silhouette's tangent rays, sin(alpha) = r / D either side.
  const double alpha = std::asin(r / D);
  EXPECT_NEAR(v.width_px, 2 * kF * std::tan(alpha), 0.5);
  // Along: the label's full height at the front, D - r from the camera.
  EXPECT_NEAR(v.height_px, kF * h / (D - r), 0.5);
  EXPECT_GT(v.points, 100);
  // The front half's outline: a little less than the box of its extents (the top and bottom
  // edges curve away towards the silhouettes).
  EXPECT_LT(v.area_px2, v.width_px * v.height_px);
  EXPECT_GT(v.area_px2, 0.9 * v.width_px * v.height_px);
  // Its corners: the seen columns (the front half) at the label's top and bottom rows.
  EXPECT_LT(v.corners[0].x(), v.corners[1].x());
  EXPECT_LT(v.corners[1].y(), v.corners[2].y());
}

TEST(OracleCylinder, ATurnedLabelIsSeenFromItsEdgeToTheSilhouette) {
  // The bottle of bottle_fruits_far: 60 % of the round, its centre turned 50 deg away.
  const double r = 0.045, w = 0.6 * 2 * M_PI * r, h = 0.16, D = 1.2, turn = 50 * kDeg;
  const CylinderLabel L{r, w, h, 400, 200};
  const std::vector<Eigen::Vector2d> samples = servo::labelSamples(L, wholeLabel(L));
  const servo::VisibleLabel v = servo::visibleLabel(L, samples, cameraFacing(r, -turn, D), pinhole(), 0, 0);
  // One side the silhouette, the other the label's edge, phi = half the label's arc - the turn
  // from the line of sight.
  const double alpha = std::asin(r / D);
  const double phi = 0.5 * w / r - turn;
  const double expected = kF * std::tan(alpha) + kF * r * std::sin(phi) / (D - r * std::cos(phi));
  EXPECT_NEAR(v.width_px, expected, 0.5);
  // The same label turned the other way: the mirror image.
  const servo::VisibleLabel m = servo::visibleLabel(L, samples, cameraFacing(r, turn, D), pinhole(), 0, 0);
  EXPECT_NEAR(m.width_px, v.width_px, 1e-6);
  // A margin on the viewing angle keeps the grazing part near the silhouette out.
  const servo::VisibleLabel g =
      servo::visibleLabel(L, samples, cameraFacing(r, -turn, D), pinhole(), 0, std::cos(1.2));
  EXPECT_LT(g.width_px, v.width_px - 0.5);
}

TEST(OracleCylinder, ALabelOnTheFarSideOrOutsideTheImageIsNotSeen) {
  const double r = 0.04;
  const CylinderLabel L{r, 0.25 * 2 * M_PI * r, 0.1, 200, 100};
  const std::vector<Eigen::Vector2d> samples = servo::labelSamples(L, wholeLabel(L));
  EXPECT_EQ(servo::visibleLabel(L, samples, cameraFacing(r, M_PI, 0.6), pinhole(), 0, 0).points, 0);
  // Facing the camera but to the side of the image: the points past its border are not counted.
  const Pose cMo = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.4, 0, 0)) * cameraFacing(r, 0, 0.6);
  const servo::VisibleLabel v = servo::visibleLabel(L, samples, cMo, pinhole(), 4, 0);
  EXPECT_EQ(v.points, 0);
  const servo::VisibleLabel half =
      servo::visibleLabel(L, samples, Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.355, 0, 0)) *
                                          cameraFacing(r, 0, 0.6), pinhole(), 4, 0);
  EXPECT_GT(half.points, 0);
  EXPECT_LT(half.points, servo::visibleLabel(L, samples, cameraFacing(r, 0, 0.6), pinhole(), 4, 0).points);
}

TEST(OracleCylinder, TheOracleJudgesACanByWhatItSeesOfTheLabel) {
  // A can's label all round: laid flat it is 2 pi r wide (its tangent-plane quadrilateral),
  // about pi times what the camera sees of it.
  const double r = 0.033, h = 0.10;
  const detector::ObjectModel m = can(r, 2 * M_PI * r, h);
  servo::OracleOptions o;
  o.border_px = 4;
  o.min_side_px = 32;
  const servo::OracleEstimator oracle(m, o);
  const Intrinsics cam = pinhole();
  // The seen part, a little under 2 f r / D across and f h / (D - r) along: ~29 x 47 px at 1.1 m
  // (over 32^2 px^2), ~23 x 36 px at 1.4 m (under), where the flat label is 76 x 36 px.
  std::array<Eigen::Vector2d, 4> corners;
  ASSERT_TRUE(oracle.visible(cameraFacing(r, 0, 1.1), cam, &corners));
  EXPECT_LT((corners[1] - corners[0]).norm(), 32);
  const servo::VisibleLabel far =
      servo::visibleLabel(*m.cylinder, servo::labelSamples(*m.cylinder, m.pattern_polygon_px),
                          cameraFacing(r, 0, 1.4), cam, 4, std::cos(o.max_view_angle_rad));
  EXPECT_LT(far.area_px2, 32 * 32);
  EXPECT_GT(std::min(far.width_px, far.height_px), 16);
  EXPECT_FALSE(oracle.visible(cameraFacing(r, 0, 1.4), cam));
  // Partly out of the image: what is left of it counts while it is large enough, but not a
  // sliver along the image's edge.
  const Pose near = cameraFacing(r, 0, 0.3);
  EXPECT_TRUE(oracle.visible(Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.17, 0, 0)) * near, cam));
  const Pose sliver = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.2175, 0, 0)) * near;
  const servo::VisibleLabel s =
      servo::visibleLabel(*m.cylinder, servo::labelSamples(*m.cylinder, m.pattern_polygon_px), sliver,
                          cam, 4, std::cos(o.max_view_angle_rad));
  EXPECT_GT(s.area_px2, 32 * 32);
  EXPECT_LT(s.width_px, 16);
  EXPECT_FALSE(oracle.visible(sliver, cam));
  EXPECT_FALSE(oracle.visible(Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.25, 0, 0)) * near, cam));
}
