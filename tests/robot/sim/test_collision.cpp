// Exact distances of the simulator's collision shapes (robot/sim/collision.h) against brute force.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>

#include "robot/sim/collision.h"

using namespace refgrasp;
using namespace refgrasp::sim;

namespace {

Eigen::Vector3d uniform3(std::mt19937_64& rng, double lo, double hi) {
  std::uniform_real_distribution<double> u(lo, hi);
  return Eigen::Vector3d(u(rng), u(rng), u(rng));
}

OrientedBox randomBox(std::mt19937_64& rng) {
  const Eigen::Vector3d rvec = uniform3(rng, -3, 3);
  return {Pose::fromRotationVector(rvec, uniform3(rng, -0.3, 0.3)), uniform3(rng, 0.01, 0.3)};
}

// Point-to-box reference: the closest point by clamping in box coordinates outside, the nearest
// face inside (a formulation independent of the one under test).
double referencePointDistance(const OrientedBox& box, const Eigen::Vector3d& p) {
  const Eigen::Vector3d q = box.wMb.R.transpose() * (p - box.wMb.t);
  const Eigen::Vector3d c = q.cwiseMax(-box.half_m).cwiseMin(box.half_m);
  if ((q - c).norm() > 0) return (q - c).norm();
  double inside = 1e300;
  for (int k = 0; k < 3; ++k) inside = std::min(inside, box.half_m[k] - std::abs(q[k]));
  return -inside;
}

OrientedCylinder randomCylinder(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.01, 0.3);
  return {Pose::fromRotationVector(uniform3(rng, -3, 3), uniform3(rng, -0.3, 0.3)), u(rng), u(rng)};
}

// Point-to-cylinder reference: outside, the distance to the closest point of the solid (the
// radial part clamped to the radius, the axial part to the caps); inside, the nearer of the side
// and the caps.
double referencePointDistance(const OrientedCylinder& c, const Eigen::Vector3d& p) {
  const Eigen::Vector3d q = c.wMc.R.transpose() * (p - c.wMc.t);
  const double rho = q.head<2>().norm();
  const Eigen::Vector2d radial = rho > c.radius_m ? Eigen::Vector2d(q.head<2>() * (c.radius_m / rho))
                                                  : Eigen::Vector2d(q.head<2>());
  const Eigen::Vector3d closest(radial.x(), radial.y(), std::clamp(q.z(), -c.half_height_m, c.half_height_m));
  if ((q - closest).norm() > 0) return (q - closest).norm();
  return -std::min(c.radius_m - rho, c.half_height_m - std::abs(q.z()));
}

// Brute force along the segment: 20001 samples, then 20001 more around the best one.
template <class Shape>
double bruteSegmentDistance(const Shape& shape, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const int n = 20000;
  double best = 1e300, best_s = 0;
  for (int i = 0; i <= n; ++i) {
    const double s = static_cast<double>(i) / n;
    const double d = referencePointDistance(shape, a + s * (b - a));
    if (d < best) best = d, best_s = s;
  }
  const double lo = std::max(0.0, best_s - 1.0 / n), hi = std::min(1.0, best_s + 1.0 / n);
  for (int i = 0; i <= n; ++i) {
    const double s = lo + (hi - lo) * i / n;
    best = std::min(best, referencePointDistance(shape, a + s * (b - a)));
  }
  return best;
}

// Point, segment and capsule distances to random shapes against the references: 2000 points
// within 1e-12, 200 segments within 1e-6 m of brute force, some of them penetrating.
template <class Shape>
void expectDistancesMatchBruteForce(std::mt19937_64& rng, Shape (*random)(std::mt19937_64&), const char* what) {
  for (int i = 0; i < 2000; ++i) {
    const Shape shape = random(rng);
    const Eigen::Vector3d p = uniform3(rng, -0.6, 0.6);
    EXPECT_NEAR(signedDistance(shape, p), referencePointDistance(shape, p), 1e-12) << i;
  }
  double worst = 0;
  int inside = 0;
  for (int i = 0; i < 200; ++i) {
    const Shape shape = random(rng);
    const Eigen::Vector3d a = uniform3(rng, -0.6, 0.6), b = uniform3(rng, -0.6, 0.6);
    double s = -1;
    const double d = segmentSignedDistance(shape, a, b, &s);
    const double ref = bruteSegmentDistance(shape, a, b);
    worst = std::max(worst, std::abs(d - ref));
    inside += ref < 0;
    EXPECT_NEAR(d, ref, 1e-6) << i;
    ASSERT_GE(s, 0);
    ASSERT_LE(s, 1);
    EXPECT_NEAR(referencePointDistance(shape, a + s * (b - a)), d, 1e-12);
    // Capsules: the radius comes off.
    EXPECT_NEAR(signedDistance(shape, Capsule{a, b, 0.03}), d - 0.03, 1e-12);
  }
  std::printf("segment-%s: worst |exact - brute force| %.2e m over 200 (%d penetrating)\n", what, worst, inside);
  EXPECT_GT(inside, 10);  // both regimes are exercised
  EXPECT_LT(inside, 190);
}

}  // namespace

TEST(Collision, PointAndSegmentDistancesMatchBruteForce) {
  std::mt19937_64 rng(11);
  expectDistancesMatchBruteForce(rng, randomBox, "box");
}

TEST(Collision, KnownSegmentDistancesAndExtents) {
  const OrientedBox box{Pose(), Eigen::Vector3d(0.1, 0.2, 0.3)};
  // Minimum at an end of the segment.
  EXPECT_NEAR(segmentSignedDistance(box, {0.5, 0, 0}, {0.9, 0, 0}), 0.4, 1e-12);
  EXPECT_NEAR(segmentSignedDistance(box, {0.9, 0, 0}, {0.5, 0, 0}), 0.4, 1e-12);
  // Parallel to a face: constant distance.
  EXPECT_NEAR(segmentSignedDistance(box, {0.15, -0.1, 0}, {0.15, 0.1, 0}), 0.05, 1e-12);
  // Through the box: minus the depth of its deepest point (the centre, 0.1 from the x faces).
  EXPECT_NEAR(segmentSignedDistance(box, {0, 0, -1}, {0, 0, 1}), -0.1, 1e-9);
  // A point segment.
  EXPECT_NEAR(segmentSignedDistance(box, {0, 0.5, 0}, {0, 0.5, 0}), 0.3, 1e-12);
  // Extents.
  const OrientedBox turned{Pose::fromRotationVector({0, 0, 0.3}, {1, 2, 3}), Eigen::Vector3d(0.1, 0.04, 0.2)};
  EXPECT_NEAR(extentAlong(turned, Eigen::Vector3d::UnitX()), 0.2 * std::cos(0.3) + 0.08 * std::sin(0.3), 1e-12);
  EXPECT_NEAR(extentAlong(turned, Eigen::Vector3d::UnitZ()), 0.4, 1e-12);
}

TEST(Collision, CylinderDistanceMatchesSamplingAndKnownOverlaps) {
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 60; ++i) {
    // Upright boxes turned about the vertical (a box axis along z_w), and tilted ones.
    const bool upright = i % 2 == 0;
    OrientedBox box;
    box.half_m = uniform3(rng, 0.05, 0.3);
    const Eigen::Vector3d rvec = upright ? Eigen::Vector3d(0, 0, 3 * u(rng)) : uniform3(rng, -3, 3);
    box.wMb = Pose::fromRotationVector(rvec, Eigen::Vector3d(u(rng), u(rng), 0.5 + 0.5 * u(rng)));
    const VerticalCylinder c{Eigen::Vector2d(u(rng), u(rng)), 0.0, 1.0, 0.25};
    const double d = signedDistance(box, c);
    // Brute force over the cylinder's surface (side, top and bottom discs): the distance when
    // they are apart. The AABB of a tilted box is never closer than the box.
    double brute = 1e300;
    for (int k = 0; k < 400; ++k) {
      const double a = 2 * M_PI * k / 400;
      const Eigen::Vector2d dir(std::cos(a), std::sin(a));
      for (int h = 0; h <= 200; ++h) {
        const Eigen::Vector2d side = c.centre + c.radius_m * dir, disc = c.centre + c.radius_m * h / 200 * dir;
        brute = std::min({brute,
                          referencePointDistance(box, Eigen::Vector3d(side.x(), side.y(), c.height_m * h / 200)),
                          referencePointDistance(box, Eigen::Vector3d(disc.x(), disc.y(), 0.0)),
                          referencePointDistance(box, Eigen::Vector3d(disc.x(), disc.y(), c.height_m))});
      }
    }
    if (brute > 0.01) {
      if (upright) {
        EXPECT_NEAR(d, brute, 3e-3) << i;  // the samples are 5 mm apart at most
      } else {
        EXPECT_LE(d, brute + 3e-3) << i;
      }
      EXPECT_GT(d, 0) << i;
    } else if (brute <= 0) {
      EXPECT_LT(d, 1e-9) << i;
    }
  }
  // By construction: a table block 0.72 high whose edge is 3 cm inside the cylinder.
  const OrientedBox table{Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(1.0, 0, 0.36)),
                          Eigen::Vector3d(0.35, 0.6, 0.36)};
  EXPECT_NEAR(signedDistance(table, VerticalCylinder{{0.65 - 0.22, 0.0}, 0.0, 1.3, 0.25}), -0.03, 1e-12);
  EXPECT_NEAR(signedDistance(table, VerticalCylinder{{0.65 - 0.30, 0.0}, 0.0, 1.3, 0.25}), 0.05, 1e-12);
  // Corner: diagonal distance.
  EXPECT_NEAR(signedDistance(table, VerticalCylinder{{0.65 - 0.3, 0.6 + 0.4}, 0.0, 1.3, 0.25}), 0.25,
              1e-12);
  // Above the table: vertical gap only, then both gaps combined.
  EXPECT_NEAR(signedDistance(table, VerticalCylinder{{1.0, 0.0}, 0.82, 0.3, 0.25}), 0.10, 1e-12);
  EXPECT_NEAR(signedDistance(table, VerticalCylinder{{0.65 - 0.28, 0.0}, 0.76, 0.3, 0.25}),
              std::hypot(0.03, 0.04), 1e-12);
}

namespace {

// The surface of a vertical cylinder (side and both discs) by its parameters (a, b) in [0, 1]^2.
Eigen::Vector3d baseSurfacePoint(const VerticalCylinder& v, int part, double a, double b) {
  const Eigen::Vector2d dir(std::cos(2 * M_PI * a), std::sin(2 * M_PI * a));
  if (part == 0) {
    const Eigen::Vector2d s = v.centre + v.radius_m * dir;
    return Eigen::Vector3d(s.x(), s.y(), v.z0_m + b * v.height_m);
  }
  const Eigen::Vector2d s = v.centre + v.radius_m * b * dir;
  return Eigen::Vector3d(s.x(), s.y(), part == 1 ? v.z0_m : v.z0_m + v.height_m);
}

// Distance between a vertical cylinder and a cylinder that it does not touch: the minimum over
// the vertical cylinder's surface of the exact point distance, on a 720 x 200 grid per part, then
// a 200 x 200 grid over the cells around the best sample.
double bruteBaseDistance(const OrientedCylinder& c, const VerticalCylinder& v) {
  double best = 1e300;
  int best_part = 0;
  double best_a = 0, best_b = 0;
  const int na = 720, nb = 200;
  for (int part = 0; part < 3; ++part)
    for (int i = 0; i < na; ++i)
      for (int j = 0; j <= nb; ++j) {
        const double a = static_cast<double>(i) / na, b = static_cast<double>(j) / nb;
        const double d = referencePointDistance(c, baseSurfacePoint(v, part, a, b));
        if (d < best) best = d, best_part = part, best_a = a, best_b = b;
      }
  for (int i = 0; i <= 200; ++i)
    for (int j = 0; j <= 200; ++j) {
      const double a = best_a + (i - 100) / (100.0 * na);
      const double b = std::clamp(best_b + (j - 100) / (100.0 * nb), 0.0, 1.0);
      best = std::min(best, referencePointDistance(c, baseSurfacePoint(v, best_part, a, b)));
    }
  return best;
}

}  // namespace

TEST(Collision, CylinderPointSegmentAndCapsuleDistancesMatchBruteForce) {
  std::mt19937_64 rng(17);
  expectDistancesMatchBruteForce(rng, randomCylinder, "cylinder");
}

TEST(Collision, KnownCylinderDistancesAndExtents) {
  // A can of radius 0.05, 0.2 high, axis along world y.
  const OrientedCylinder can{Pose::fromRotationVector({M_PI / 2, 0, 0}, {1, 0, 0}), 0.05, 0.1};
  EXPECT_NEAR(signedDistance(can, Eigen::Vector3d(1.3, 0, 0)), 0.25, 1e-12);        // side
  EXPECT_NEAR(signedDistance(can, Eigen::Vector3d(1, 0.4, 0)), 0.3, 1e-12);         // cap
  EXPECT_NEAR(signedDistance(can, Eigen::Vector3d(1.08, 0.14, 0)), 0.05, 1e-12);    // rim: (0.03, 0.04)
  EXPECT_NEAR(signedDistance(can, Eigen::Vector3d(1.02, 0.05, 0)), -0.03, 1e-12);   // inside, side nearer
  EXPECT_NEAR(signedDistance(can, Eigen::Vector3d(1, 0.09, 0)), -0.01, 1e-12);      // inside, cap nearer
  // A finger (capsule) passing along the side, parallel to the axis, 2 cm from the surface.
  EXPECT_NEAR(signedDistance(can, Capsule{{1, -0.3, 0.082}, {1, 0.3, 0.082}, 0.012}), 0.02, 1e-9);
  // Across the axis, through the can: minus the depth of its deepest point (the radius).
  EXPECT_NEAR(segmentSignedDistance(can, {0, 0, 0}, {2, 0, 0}), -0.05, 1e-9);
  // Extents: the diameter across the axis, the height along it, both in between.
  EXPECT_NEAR(extentAlong(can, Eigen::Vector3d::UnitX()), 0.1, 1e-12);
  EXPECT_NEAR(extentAlong(can, Eigen::Vector3d::UnitZ()), 0.1, 1e-12);
  EXPECT_NEAR(extentAlong(can, Eigen::Vector3d::UnitY()), 0.2, 1e-12);
  const Eigen::Vector3d u = Eigen::Vector3d(1, 1, 0).normalized();
  EXPECT_NEAR(extentAlong(can, u), (0.2 + 0.1) / std::sqrt(2.0), 1e-12);
}

TEST(Collision, CylinderExtentMatchesItsRims) {
  // The projection's extremes lie on the rims: 100000 points on each.
  std::mt19937_64 rng(19);
  for (int i = 0; i < 50; ++i) {
    const OrientedCylinder c = randomCylinder(rng);
    const Eigen::Vector3d u = uniform3(rng, -1, 1).normalized();
    double lo = 1e300, hi = -1e300;
    for (int k = 0; k < 100000; ++k) {
      const double a = 2 * M_PI * k / 100000;
      for (const double z : {-c.half_height_m, c.half_height_m}) {
        const double x = u.dot(c.wMc * Eigen::Vector3d(c.radius_m * std::cos(a), c.radius_m * std::sin(a), z));
        lo = std::min(lo, x);
        hi = std::max(hi, x);
      }
    }
    // Rim samples 2 pi r / 1e5 apart: the sampled extent is short by at most r (1 - cos(pi / 1e5)) a side.
    EXPECT_NEAR(extentAlong(c, u), hi - lo, 1e-9) << i;
  }
}

TEST(Collision, BaseAgainstACylinderMatchesBruteForce) {
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> u(-1, 1);
  double worst = 0;
  int apart = 0;
  for (int i = 0; i < 40; ++i) {
    // Upright cylinders (a can, a bin: exact) and tilted ones (bounded by their bounding box).
    const bool upright = i % 2 == 0;
    const Eigen::Matrix3d R =
        upright ? (Eigen::AngleAxisd(3 * u(rng), Eigen::Vector3d::UnitZ()) *
                   Eigen::AngleAxisd(u(rng) > 0 ? M_PI : 0.0, Eigen::Vector3d::UnitX()))
                      .toRotationMatrix()
                : Pose::fromRotationVector(uniform3(rng, -3, 3), Eigen::Vector3d::Zero()).R;
    const OrientedCylinder c{Pose(R, Eigen::Vector3d(u(rng), u(rng), 0.5 + 0.5 * u(rng))),
                             0.05 + 0.1 * (1 + u(rng)), 0.05 + 0.1 * (1 + u(rng))};
    const VerticalCylinder v{Eigen::Vector2d(u(rng), u(rng)), 0.0, 1.0, 0.25};
    const double d = signedDistance(c, v);
    const double brute = bruteBaseDistance(c, v);
    if (brute > 0) {
      ++apart;
      if (upright) {
        EXPECT_NEAR(d, brute, 1e-6) << i;
        worst = std::max(worst, std::abs(d - brute));
      } else {
        EXPECT_LE(d, brute + 1e-9) << i;  // the bounding box: never less contact than there is
      }
    } else {
      // The surface touches or enters the cylinder.
      EXPECT_LT(d, 1e-6) << i;
    }
  }
  std::printf("base-cylinder (upright): worst |exact - brute force| %.2e m, %d of 40 apart\n", worst, apart);
  EXPECT_GT(apart, 10);
  EXPECT_LT(apart, 38);
  // By construction: a can (r 0.033, 0.122 high) on a table 0.72 high; the base 0.25 in radius.
  const OrientedCylinder can{Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(1, 0, 0.781)), 0.033, 0.061};
  EXPECT_NEAR(signedDistance(can, VerticalCylinder{{0.6, 0.0}, 0.0, 1.3, 0.25}), 0.4 - 0.283, 1e-12);
  EXPECT_NEAR(signedDistance(can, VerticalCylinder{{0.8, 0.0}, 0.0, 1.3, 0.25}), 0.2 - 0.283, 1e-12);
  // Tilted by 1e-3 rad: bounded (never more than brute force when apart), and within
  // (half height + radius) sin(tilt) of the upright can, apart and penetrating.
  const OrientedCylinder tilted{Pose::fromRotationVector({0, 1e-3, 0}, can.wMc.t), 0.033, 0.061};
  for (const double x : {0.6, 0.8}) {
    const VerticalCylinder base{{x, 0.0}, 0.0, 1.3, 0.25};
    const double d = signedDistance(tilted, base);
    EXPECT_NEAR(d, signedDistance(can, base), (0.061 + 0.033) * 1e-3) << x;
    if (x == 0.6) EXPECT_LE(d, bruteBaseDistance(tilted, base) + 1e-9);
  }
  // Below the can's bottom (a low robot): vertical gap, then both gaps combined.
  EXPECT_NEAR(signedDistance(can, VerticalCylinder{{1.0, 0.0}, 0.0, 0.62, 0.25}), 0.1, 1e-12);
  EXPECT_NEAR(signedDistance(can, VerticalCylinder{{1.0 - 0.283 - 0.03, 0.0}, 0.0, 0.68, 0.25}),
              std::hypot(0.03, 0.04), 1e-12);
}
