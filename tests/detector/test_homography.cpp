// Homography estimation: exact recovery, robustness to outliers, degenerate input.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>

#include "detector/homography.h"

namespace refgrasp::detector {
namespace {

using Vec2 = Eigen::Vector2d;

/// A well-conditioned random homography: a plane seen by a 640x480 pinhole under a mild tilt.
Eigen::Matrix3d randomHomography(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::Matrix3d H;
  const double a = 0.5 * u(rng), s = 0.8 + 0.3 * u(rng);
  H << s * std::cos(a), -s * std::sin(a), 300 + 50 * u(rng),  //
      s * std::sin(a), s * std::cos(a), 200 + 50 * u(rng),    //
      3e-4 * u(rng), 3e-4 * u(rng), 1;
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) H(r, c) += 0.1 * u(rng);  // from the test's generator, not Eigen's Random() (rand)
  return H;
}

std::vector<Vec2> randomPoints(std::mt19937_64& rng, int n) {
  std::uniform_real_distribution<double> x(0, 400), y(0, 300);
  std::vector<Vec2> p;
  for (int i = 0; i < n; ++i) p.emplace_back(x(rng), y(rng));
  return p;
}

double maxTransfer(const Eigen::Matrix3d& H, const Eigen::Matrix3d& Htrue, const std::vector<Vec2>& pts) {
  double e = 0;
  for (const auto& p : pts) e = std::max(e, (applyHomography(H, p) - applyHomography(Htrue, p)).norm());
  return e;
}

TEST(Homography, ExactCorrespondencesRecovered) {
  std::mt19937_64 rng(11);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Matrix3d Ht = randomHomography(rng);
    const auto from = randomPoints(rng, 4 + trial * 5);
    std::vector<Vec2> to;
    for (const auto& p : from) to.push_back(applyHomography(Ht, p));
    const auto res = estimateHomography(from, to, HomographyOptions{});
    ASSERT_TRUE(res.ok) << "trial " << trial;
    EXPECT_EQ(res.inliers.size(), from.size());
    EXPECT_LT(maxTransfer(res.H, Ht, from), 1e-6) << "trial " << trial;
    EXPECT_LT(res.rms_px, 1e-6);
    const Eigen::Matrix3d Hl = fitHomographyLeastSquares(from, to);
    EXPECT_LT(maxTransfer(Hl, Ht, from), 1e-6) << "trial " << trial;
  }
}

TEST(Homography, OutliersAndNoise) {
  std::mt19937_64 rng(12);
  std::normal_distribution<double> noise(0, 0.5);
  std::uniform_real_distribution<double> junk_x(0, 640), junk_y(0, 480);
  for (int trial = 0; trial < 10; ++trial) {
    const Eigen::Matrix3d Ht = randomHomography(rng);
    const auto from = randomPoints(rng, 200);
    std::vector<Vec2> to;
    std::vector<bool> outlier;
    for (size_t i = 0; i < from.size(); ++i) {
      const bool out = i % 5 < 2;  // 40 %
      outlier.push_back(out);
      Vec2 p = applyHomography(Ht, from[i]);
      if (out) {
        Vec2 q;
        do q = Vec2(junk_x(rng), junk_y(rng));
        while ((q - p).norm() < 20);
        p = q;
      } else {
        p += Vec2(noise(rng), noise(rng));
      }
      to.push_back(p);
    }
    HomographyOptions opt;
    opt.seed = trial;
    const auto res = estimateHomography(from, to, opt);
    ASSERT_TRUE(res.ok);
    int true_inliers_found = 0, outliers_taken = 0;
    for (int k : res.inliers) (outlier[k] ? outliers_taken : true_inliers_found)++;
    EXPECT_GE(true_inliers_found, 0.95 * 120) << "trial " << trial;
    EXPECT_EQ(outliers_taken, 0);
    EXPECT_LT(res.rms_px, 1.0);  // 0.5 px per axis noise -> ~0.7 px rms
    EXPECT_LT(maxTransfer(res.H, Ht, from), 1.5) << "trial " << trial;
  }
}

TEST(Homography, SeededAndDeterministic) {
  std::mt19937_64 rng(13);
  const Eigen::Matrix3d Ht = randomHomography(rng);
  auto from = randomPoints(rng, 60);
  std::vector<Vec2> to;
  std::uniform_real_distribution<double> junk(0, 400);
  for (size_t i = 0; i < from.size(); ++i)
    to.push_back(i % 2 ? Vec2(junk(rng), junk(rng)) : applyHomography(Ht, from[i]));
  HomographyOptions opt;
  opt.seed = 5;
  const auto a = estimateHomography(from, to, opt), b = estimateHomography(from, to, opt);
  ASSERT_TRUE(a.ok);
  EXPECT_EQ(a.inliers, b.inliers);
  EXPECT_EQ((a.H - b.H).norm(), 0.0);
}

TEST(Homography, DegenerateInputsFailCleanly) {
  const HomographyOptions opt;
  std::vector<Vec2> three = {Vec2(0, 0), Vec2(1, 0), Vec2(0, 1)};
  EXPECT_FALSE(estimateHomography(three, three, opt).ok);
  EXPECT_FALSE(estimateHomography({}, {}, opt).ok);
  EXPECT_FALSE(fitHomographyLeastSquares(three, three).allFinite());

  std::vector<Vec2> line;
  for (int i = 0; i < 20; ++i) line.emplace_back(i * 3.0, i * 2.0 + 1);
  EXPECT_FALSE(estimateHomography(line, line, opt).ok);

  std::vector<Vec2> sq = {Vec2(0, 0), Vec2(10, 0), Vec2(10, 10), Vec2(0, 10), Vec2(5, 5)};
  auto nan = sq;
  nan[2].x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(estimateHomography(nan, sq, opt).ok);
  EXPECT_FALSE(estimateHomography(sq, nan, opt).ok);
  EXPECT_FALSE(fitHomographyLeastSquares(nan, sq).allFinite());
  // Mismatched sizes.
  EXPECT_FALSE(estimateHomography(sq, three, opt).ok);
  // All points mapped to one point: singular.
  std::vector<Vec2> same(5, Vec2(3, 3));
  EXPECT_FALSE(estimateHomography(sq, same, opt).ok);
}

TEST(Homography, AffineLeastSquaresIsExactOnAffineDataAndFailsCleanly) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();
  A.topRows<2>() << 0.7, -0.2, 120, 0.15, 0.9, -40;
  std::vector<Vec2> from, to;
  for (int i = 0; i < 7; ++i) {
    from.emplace_back(300 * u(rng), 200 * u(rng));
    to.push_back((A * from.back().homogeneous()).hnormalized());
  }
  const Eigen::Matrix3d F = fitAffineLeastSquares(from, to);
  ASSERT_TRUE(F.allFinite());
  EXPECT_LT((F - A).cwiseAbs().maxCoeff(), 1e-9);
  // Noisy: the least-squares solution (its residual is orthogonal to the design's columns).
  std::normal_distribution<double> n(0, 0.5);
  for (Vec2& y : to) y += Vec2(n(rng), n(rng));
  const Eigen::Matrix3d G = fitAffineLeastSquares(from, to);
  Eigen::Vector3d sx = Eigen::Vector3d::Zero(), sy = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < from.size(); ++i) {
    const Vec2 r = (G * from[i].homogeneous()).hnormalized() - to[i];
    sx += r.x() * from[i].homogeneous();
    sy += r.y() * from[i].homogeneous();
  }
  EXPECT_LT(sx.norm() + sy.norm(), 1e-6);
  EXPECT_DOUBLE_EQ(G(2, 0), 0);
  EXPECT_DOUBLE_EQ(G(2, 1), 0);
  // Too few, collinear, coincident or non-finite points: a non-finite matrix, no throw.
  EXPECT_FALSE(fitAffineLeastSquares({from[0], from[1]}, {to[0], to[1]}).allFinite());
  EXPECT_FALSE(fitAffineLeastSquares({{0, 0}, {1, 1}, {2, 2}, {5, 5}}, {{0, 0}, {1, 0}, {2, 1}, {3, 3}}).allFinite());
  EXPECT_FALSE(fitAffineLeastSquares({{4, 4}, {4, 4}, {4, 4}}, {{0, 0}, {1, 0}, {0, 1}}).allFinite());
  std::vector<Vec2> bad = from;
  bad[3].x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(fitAffineLeastSquares(bad, to).allFinite());
  EXPECT_FALSE(fitAffineLeastSquares(from, {to[0], to[1], to[2]}).allFinite());
}

TEST(Homography, OptionsCheck) {
  HomographyOptions o;
  EXPECT_NO_THROW(o.check());
  o.ransac_reproj_px = 0;
  EXPECT_THROW(o.check(), std::invalid_argument);
  o = {};
  o.confidence = 1;
  EXPECT_THROW(o.check(), std::invalid_argument);
  o = {};
  o.max_iterations = 0;
  EXPECT_THROW(o.check(), std::invalid_argument);
}

TEST(Homography, PlausibilityRejectsFlipsAndCollapse) {
  const std::vector<Vec2> quad = {Vec2(0, 0), Vec2(100, 0), Vec2(100, 80), Vec2(0, 80)};
  EXPECT_TRUE(homographyPlausible(Eigen::Matrix3d::Identity(), quad));
  Eigen::Matrix3d mirror = Eigen::Matrix3d::Identity();
  mirror(0, 0) = -1;
  EXPECT_FALSE(homographyPlausible(mirror, quad));
  Eigen::Matrix3d tiny = Eigen::Matrix3d::Identity();
  tiny(0, 0) = tiny(1, 1) = 0.01;
  EXPECT_FALSE(homographyPlausible(tiny, quad));
  Eigen::Matrix3d horizon = Eigen::Matrix3d::Identity();
  horizon(2, 0) = -0.015;  // the vanishing line u = 66.7 cuts the quad
  EXPECT_FALSE(homographyPlausible(horizon, quad));
  EXPECT_FALSE(homographyPlausible(Eigen::Matrix3d::Constant(std::nan("")), quad));
}

}  // namespace
}  // namespace refgrasp::detector
