// Shared plane geometry: shoelace area and centroid, Hartley normalisation.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <array>
#include <cmath>

#include "core/geometry.h"

using namespace refgrasp;
using Vec2 = Eigen::Vector2d;

TEST(Geometry, ShoelaceAreaAndCentroid) {
  // 4 x 3 rectangle: +12 turning from +x towards +y, -12 the other way.
  const std::array<Vec2, 4> rect = {Vec2(1, 1), Vec2(5, 1), Vec2(5, 4), Vec2(1, 4)};
  EXPECT_DOUBLE_EQ(signedArea(rect), 12.0);
  const std::vector<Vec2> reversed = {rect[3], rect[2], rect[1], rect[0]};
  EXPECT_DOUBLE_EQ(signedArea(reversed), -12.0);
  EXPECT_DOUBLE_EQ(shoelace2(rect.data(), rect.size()), 24.0);
  // L shape: 2x2 square at the origin plus a 2x1 bar to its right (areas 4 and 2).
  const std::vector<Vec2> ell = {Vec2(0, 0), Vec2(4, 0), Vec2(4, 1), Vec2(2, 1), Vec2(2, 2), Vec2(0, 2)};
  EXPECT_DOUBLE_EQ(signedArea(ell), 6.0);
  const Vec2 c = polygonCentroid(ell);  // (4 * (1, 1) + 2 * (3, 0.5)) / 6
  EXPECT_NEAR(c.x(), 10.0 / 6, 1e-12);
  EXPECT_NEAR(c.y(), 5.0 / 6, 1e-12);
  EXPECT_FALSE(polygonCentroid({Vec2(0, 0), Vec2(1, 1), Vec2(2, 2)}).allFinite());  // zero area
}

TEST(Geometry, HartleyNormalizationCentresAndScales) {
  const std::vector<Vec2> p = {Vec2(100, 50), Vec2(300, 80), Vec2(250, 400), Vec2(90, 310), Vec2(170, 200)};
  const Eigen::Matrix3d T = hartleyNormalization(p);
  Vec2 mean = Vec2::Zero();
  double dist = 0;
  for (const Vec2& x : p) mean += (T * x.homogeneous()).hnormalized();
  mean /= p.size();
  for (const Vec2& x : p) dist += ((T * x.homogeneous()).hnormalized() - mean).norm();
  EXPECT_LT(mean.norm(), 1e-12);
  EXPECT_NEAR(dist / p.size(), std::sqrt(2.0), 1e-12);
  EXPECT_DOUBLE_EQ(T(0, 0), T(1, 1));  // isotropic
  EXPECT_DOUBLE_EQ(T(0, 1), 0.0);
  // Coincident points: a pure translation (no division by zero).
  const Eigen::Matrix3d U = hartleyNormalization({Vec2(7, 8), Vec2(7, 8)});
  EXPECT_DOUBLE_EQ(U(0, 0), 1.0);
  EXPECT_DOUBLE_EQ(U(0, 2), -7.0);
}

TEST(Geometry, ClipToBoxKeepsTheInsidePart) {
  const Vec2 lo(0, 0), hi(10, 10);
  // A square half outside to the right: 5 x 6 inside.
  EXPECT_NEAR(signedArea(clipToBox({Vec2(5, 2), Vec2(15, 2), Vec2(15, 8), Vec2(5, 8)}, lo, hi)), 30, 1e-12);
  // Covering the box: the box itself, either winding.
  EXPECT_NEAR(signedArea(clipToBox({Vec2(-5, -5), Vec2(20, -5), Vec2(20, 20), Vec2(-5, 20)}, lo, hi)), 100, 1e-12);
  EXPECT_NEAR(signedArea(clipToBox({Vec2(-5, 20), Vec2(20, 20), Vec2(20, -5), Vec2(-5, -5)}, lo, hi)), -100, 1e-12);
  // Concave (a U open at the top, legs 2 wide, base 2 high) cut by the box's top edge at y = 0.
  const std::vector<Vec2> u = {Vec2(1, -4), Vec2(3, -4), Vec2(3, 6), Vec2(7, 6), Vec2(7, -4),
                               Vec2(9, -4), Vec2(9, 8), Vec2(1, 8)};
  EXPECT_NEAR(signedArea(clipToBox(u, lo, hi)), 2 * 2 * 6 + 8 * 2, 1e-12);
  // Entirely outside.
  EXPECT_TRUE(clipToBox({Vec2(11, 0), Vec2(20, 0), Vec2(15, 5)}, lo, hi).empty());
}

TEST(Geometry, ClipToConvexKeepsTheInsidePart) {
  // The triangle x + y <= 10 (x, y >= 0), given in either winding, clips the 10 x 10 square to it.
  const std::vector<Vec2> square = {Vec2(0, 0), Vec2(10, 0), Vec2(10, 10), Vec2(0, 10)};
  const std::vector<Vec2> tri = {Vec2(0, 0), Vec2(10, 0), Vec2(0, 10)}, tri_cw = {Vec2(0, 0), Vec2(0, 10), Vec2(10, 0)};
  EXPECT_NEAR(signedArea(clipToConvex(square, tri)), 50, 1e-12);
  EXPECT_NEAR(signedArea(clipToConvex(square, tri_cw)), 50, 1e-12);
  // A concave subject with a hole reached through a slit (as make_reference's photo minus a tag):
  // the 10 x 10 square minus [4, 6]^2, clipped to the triangle: 50 - 2 (the hole's part below
  // x + y = 10 is the 2 x 2 square minus the half above the diagonal: 4 - 2).
  const std::vector<Vec2> holed = {Vec2(5, 0),  Vec2(10, 0), Vec2(10, 10), Vec2(0, 10), Vec2(0, 0),
                                   Vec2(5, 0),  Vec2(5, 4),  Vec2(4, 4),   Vec2(4, 6),  Vec2(6, 6),
                                   Vec2(6, 4),  Vec2(5, 4)};
  EXPECT_NEAR(std::abs(signedArea(clipToConvex(holed, tri))), 50 - 2, 1e-12);
  // Disjoint: empty; a degenerate clip polygon: empty.
  EXPECT_TRUE(clipToConvex({Vec2(11, 11), Vec2(20, 11), Vec2(15, 15)}, tri).empty());
  EXPECT_TRUE(clipToConvex(square, {Vec2(0, 0), Vec2(1, 1)}).empty());
}
