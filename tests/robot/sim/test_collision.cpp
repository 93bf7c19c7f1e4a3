// Exact distances of the simulator's collision shapes (robot/sim/collision.h) against brute force.
#include <gtest/gtest.h>

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

// Brute force along the segment: 20001 samples, then 20001 more around the best one.
double bruteSegmentDistance(const OrientedBox& box, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const int n = 20000;
  double best = 1e300, best_s = 0;
  for (int i = 0; i <= n; ++i) {
    const double s = static_cast<double>(i) / n;
    const double d = referencePointDistance(box, a + s * (b - a));
    if (d < best) best = d, best_s = s;
  }
  const double lo = std::max(0.0, best_s - 1.0 / n), hi = std::min(1.0, best_s + 1.0 / n);
  for (int i = 0; i <= n; ++i) {
    const double s = lo + (hi - lo) * i / n;
    best = std::min(best, referencePointDistance(box, a + s * (b - a)));
  }
  return best;
}

}  // namespace

TEST(Collision, PointAndSegmentDistancesMatchBruteForce) {
  std::mt19937_64 rng(11);
  for (int i = 0; i < 2000; ++i) {
    const OrientedBox box = randomBox(rng);
    const Eigen::Vector3d p = uniform3(rng, -0.6, 0.6);
    EXPECT_NEAR(signedDistance(box, p), referencePointDistance(box, p), 1e-12);
  }
  double worst = 0;
  int inside = 0;
  for (int i = 0; i < 200; ++i) {
    const OrientedBox box = randomBox(rng);
    const Eigen::Vector3d a = uniform3(rng, -0.6, 0.6), b = uniform3(rng, -0.6, 0.6);
    double s = -1;
    const double d = segmentSignedDistance(box, a, b, &s);
    const double ref = bruteSegmentDistance(box, a, b);
    worst = std::max(worst, std::abs(d - ref));
    inside += ref < 0;
    EXPECT_NEAR(d, ref, 1e-6) << i;
    ASSERT_GE(s, 0);
    ASSERT_LE(s, 1);
    EXPECT_NEAR(referencePointDistance(box, a + s * (b - a)), d, 1e-12);
    // Capsules: the radius comes off.
    EXPECT_NEAR(signedDistance(box, Capsule{a, b, 0.03}), d - 0.03, 1e-12);
  }
  std::printf("segment-box: worst |exact - brute force| %.2e m over 200 (%d penetrating)\n", worst, inside);
  EXPECT_GT(inside, 10);  // both regimes are exercised
  EXPECT_LT(inside, 190);
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
