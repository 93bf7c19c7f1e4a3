// The label-on-a-cylinder geometry (core/cylinder.h): the formulas of the object definition,
// their inverse, and the ray intersection, checked against each other and against closed forms.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/cylinder.h"
#include "core/error.h"

namespace refgrasp {
namespace {

CylinderLabel label(double r, double w, double h, int W, int H) {
  return {r, w, h, W, H};
}

TEST(CylinderLabel, PointsFollowTheDefinitionsFormula) {
  const CylinderLabel l = label(0.033, 0.2073, 0.115, 600, 333);
  // The image centre is the object origin, on the surface, its normal -z.
  EXPECT_NEAR(l.point({299.5, 166}).norm(), 0, 1e-12);
  EXPECT_NEAR((l.normal(299.5) - Eigen::Vector3d(0, 0, -1)).norm(), 0, 1e-12);
  // Pixel (u, v): s = (u - (W-1)/2) w / W, theta = s / r, X = (r sin, y, r (1 - cos)).
  const double u = 500, v = 20;
  const double s = (u - 299.5) * 0.2073 / 600, th = s / 0.033, y = (v - 166) * 0.115 / 333;
  const Eigen::Vector3d X = l.point({u, v});
  EXPECT_NEAR(X.x(), 0.033 * std::sin(th), 1e-12);
  EXPECT_NEAR(X.y(), y, 1e-12);
  EXPECT_NEAR(X.z(), 0.033 * (1 - std::cos(th)), 1e-12);
  // Every point is r from the axis; the normal points away from it.
  EXPECT_NEAR((X - l.axisPoint(X.y())).norm(), 0.033, 1e-12);
  EXPECT_NEAR((X - l.axisPoint(X.y())).normalized().dot(l.normal(u)), 1, 1e-12);
}

TEST(CylinderLabel, PixelInvertsPointOnPartialAndFullLabels) {
  std::mt19937_64 rng(7);
  for (const double w : {0.1, 2 * M_PI * 0.04}) {
    const CylinderLabel l = label(0.04, w, 0.1, 640, 200);
    std::uniform_real_distribution<double> U(-0.49, 639.49), V(0, 199);
    for (int i = 0; i < 200; ++i) {
      const Eigen::Vector2d uv(U(rng), V(rng));
      const auto back = l.pixel(l.point(uv));
      ASSERT_TRUE(back.has_value());
      EXPECT_NEAR((*back - uv).norm(), 0, 1e-9) << "w " << w;
    }
  }
  // A partial label: the bare surface behind it has no label pixel.
  const CylinderLabel partial = label(0.04, 0.1, 0.1, 640, 200);
  EXPECT_FALSE(partial.pixel(Eigen::Vector3d(0, 0, 0.08)).has_value());
  // A full wrap: the point opposite the label centre is the seam, column -0.5 or W - 0.5.
  const CylinderLabel full = label(0.04, 2 * M_PI * 0.04, 0.1, 640, 200);
  const auto seam = full.pixel(Eigen::Vector3d(1e-12, 0, 0.08));
  ASSERT_TRUE(seam.has_value());
  EXPECT_TRUE(std::abs(seam->x() + 0.5) < 1e-6 || std::abs(seam->x() - 639.5) < 1e-6) << seam->x();
}

TEST(CylinderLabel, OnlyTheHalfFacingTheCameraFacesIt) {
  const CylinderLabel l = label(0.05, 2 * M_PI * 0.05, 0.1, 720, 100);
  // Camera 1 m in front of the label's centre, looking along +z.
  const Pose cMo(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, 1));
  int facing = 0;
  for (int u = 0; u < 720; ++u) facing += l.facesCamera(u, 50, cMo);
  // From distance d the visible arc is 2 acos(r / (d + r)): 2 acos(0.05 / 1.05) = 174.5 deg.
  const double expected = 720 * 2 * std::acos(0.05 / 1.05) / (2 * M_PI);
  EXPECT_NEAR(facing, expected, 2.0);
  EXPECT_TRUE(l.facesCamera(359.5, 50, cMo));
  EXPECT_FALSE(l.facesCamera(0, 50, cMo));
}

TEST(CylinderLabel, RaysHitTheSurfacePointTheyAreCastAt) {
  const CylinderLabel l = label(0.033, 0.2073, 0.115, 600, 333);
  const Eigen::Vector3d o(0.1, -0.05, -0.6);  // a camera centre in the object frame
  for (const double u : {50.0, 200.0, 299.5, 420.0}) {
    const Eigen::Vector3d X = l.point({u, 100});
    const Eigen::Vector3d d = (X - o) * 3.7;  // any length
    const auto t = l.intersect(o, d);
    if (!l.facesCamera(u, 100, Pose(Eigen::Matrix3d::Identity(), -o))) continue;
    ASSERT_TRUE(t.has_value()) << u;
    EXPECT_NEAR((o + *t * d - X).norm(), 0, 1e-9) << u;
  }
  // A ray parallel to the axis, or passing beside the cylinder, misses.
  EXPECT_FALSE(l.intersect(o, Eigen::Vector3d(0, 1, 0)).has_value());
  EXPECT_FALSE(l.intersect(o, Eigen::Vector3d(1, 0, 0)).has_value());
}

TEST(CylinderLabel, CheckRefusesNonsenseWithTheField) {
  auto problem = [](const CylinderLabel& l) -> std::string {
    try {
      l.check("can.yaml");
    } catch (const ConfigError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_EQ(problem(label(0.033, 0.2073, 0.115, 600, 333)), "");
  // 1 % over the circumference is rounding in a measured label; more does not fit.
  EXPECT_EQ(problem(label(0.033, 2 * M_PI * 0.033 * 1.009, 0.115, 600, 333)), "");
  EXPECT_NE(problem(label(0.033, 2 * M_PI * 0.033 * 1.02, 0.115, 600, 333)).find("cylinder.label_size_m"),
            std::string::npos);
  EXPECT_NE(problem(label(0, 0.1, 0.1, 10, 10)).find("can.yaml: cylinder.radius_m"), std::string::npos);
  EXPECT_NE(problem(label(-0.03, 0.1, 0.1, 10, 10)).find("cylinder.radius_m"), std::string::npos);
  EXPECT_NE(problem(label(NAN, 0.1, 0.1, 10, 10)).find("cylinder.radius_m"), std::string::npos);
  EXPECT_NE(problem(label(0.03, 0.1, -1, 10, 10)).find("cylinder.label_size_m"), std::string::npos);
}

}  // namespace
}  // namespace refgrasp
