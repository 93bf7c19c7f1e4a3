// Pose estimation, sanity check and stereo fusion on exact synthetic geometry (no rendering).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "common/format.h"
#include "detector/homography.h"
#include "detector/pose.h"
#include "detector/sanity.h"
#include "detector/stereo.h"

using namespace refgrasp;
using namespace refgrasp::detector;

namespace {

const Eigen::Matrix3d kRefK = (Eigen::Matrix3d() << 1000, 0, 199.5, 0, 1000, 149.5, 0, 0, 1).finished();
const Eigen::Matrix3d kSceneK = (Eigen::Matrix3d() << 550, 0, 319.5, 0, 551, 239.5, 0, 0, 1).finished();

// A 400x300 reference image of a 0.2 m wide texture at 0.5 m (f = 400 * 0.5 / 0.2 = 1000).
PlanarTarget referenceTarget(const Eigen::Vector3d& n = Eigen::Vector3d::UnitZ(), double d = 0,
                             const Pose& ref_cMo = Pose(Eigen::Matrix3d::Identity(), {0, 0, 0.5})) {
  const std::array<Eigen::Vector2d, 4> corners = {Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(399.5, -0.5),
                                                  Eigen::Vector2d(399.5, 299.5), Eigen::Vector2d(-0.5, 299.5)};
  auto t = makePlanarTarget(kRefK, ref_cMo, n, d, corners);
  EXPECT_TRUE(t.has_value());
  return *t;
}

Pose randomPose(std::mt19937_64& rng, double min_z, double max_z, double max_tilt) {
  std::uniform_real_distribution<double> U(-1, 1);
  const Eigen::Vector3d axis(U(rng), U(rng), 0);
  const Eigen::Matrix3d tilt = axisAngle(axis, max_tilt * std::abs(U(rng)));
  const Eigen::Matrix3d spin = axisAngle(Eigen::Vector3d::UnitZ(), M_PI * U(rng));
  const double z = min_z + (max_z - min_z) * 0.5 * (1 + U(rng));
  return Pose(tilt * spin, Eigen::Vector3d(0.1 * z * U(rng), 0.1 * z * U(rng), z));
}

// The homography a planar target induces between the reference image and a scene camera,
// in closed form: x_s ~ K_s [r1 r2 t]_s ([r1 r2 t]_ref)^-1 K_ref^-1 x_ref (plane frame z = 0).
Eigen::Matrix3d inducedHomography(const PlanarTarget& t, const Pose& cMo) {
  auto A = [&](const Pose& cMp) {
    Eigen::Matrix3d M;
    M << cMp.R.col(0), cMp.R.col(1), cMp.t;
    return M;
  };
  return kSceneK * A(cMo * t.oMp) * A(t.ref_cMo * t.oMp).inverse() * t.K_ref.inverse();
}

}  // namespace

TEST(PlanarTarget, BackProjectsTheTextureConvention) {
  const PlanarTarget t = referenceTarget();
  // Pixel-edge corners of a 400 px wide, 0.2 m texture: (+-0.1, +-0.075, 0).
  EXPECT_NEAR((t.corners_o[0] - Eigen::Vector3d(-0.1, -0.075, 0)).norm(), 0, 1e-12);
  EXPECT_NEAR((t.corners_o[2] - Eigen::Vector3d(0.1, 0.075, 0)).norm(), 0, 1e-12);
  // A plane that faces away (ray parallel or behind) is rejected.
  EXPECT_FALSE(makePlanarTarget(kRefK, Pose(Eigen::Matrix3d::Identity(), {0, 0, -0.5}),
                                Eigen::Vector3d::UnitZ(), 0, t.corners_ref_px));
  EXPECT_FALSE(makePlanarTarget(kRefK, Pose(), Eigen::Vector3d::Zero(), 0, t.corners_ref_px));
}

TEST(Pose, LmJacobianMatchesFiniteDifferences) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> U(-0.1, 0.1);
  double worst = 0;
  for (int trial = 0; trial < 20; ++trial) {
    const Pose P = randomPose(rng, 0.3, 1.2, 0.9);
    const Eigen::Vector3d X(U(rng), U(rng), 0.02 * U(rng));
    const Eigen::Vector2d y(300, 200);
    Eigen::Vector2d r0;
    Eigen::Matrix<double, 2, 6> J;
    reprojectionResidual(P, X, y, kSceneK, &r0, &J);
    const double h = 1e-6;
    for (int k = 0; k < 6; ++k) {
      Eigen::Matrix<double, 6, 1> d = Eigen::Matrix<double, 6, 1>::Zero();
      d[k] = h;
      auto apply = [&](const Eigen::Matrix<double, 6, 1>& dd) {
        return Pose(Pose::fromRotationVector(dd.head<3>(), Eigen::Vector3d::Zero()).R * P.R,
                    P.t + dd.tail<3>());
      };
      Eigen::Vector2d rp, rm;
      reprojectionResidual(apply(d), X, y, kSceneK, &rp, nullptr);
      reprojectionResidual(apply(-d), X, y, kSceneK, &rm, nullptr);
      const Eigen::Vector2d fd = (rp - rm) / (2 * h);
      worst = std::max(worst, (fd - J.col(k)).norm() / std::max(1.0, J.col(k).norm()));
    }
  }
  std::printf("LM Jacobian vs central differences: worst relative error %.2e\n", worst);
  EXPECT_LT(worst, 1e-5);
}

TEST(Pose, Eq7RecoversExactPoseForDefaultAndTiltedPlanes) {
  std::mt19937_64 rng(11);
  // A pattern plane not at z = 0 in the object frame: normal (0.3, -0.2, 1), offset 0.05 m,
  // with the object seen from a general reference pose.
  const Pose ref_cMo = Pose::fromRotationVector({0.1, -0.15, 0.2}, {0.01, -0.02, 0.55});
  const Eigen::Vector3d n(0.3, -0.2, 1.0);
  for (const PlanarTarget& t : {referenceTarget(), referenceTarget(n, 0.05, ref_cMo)}) {
    for (int trial = 0; trial < 20; ++trial) {
      const Pose truth = randomPose(rng, 0.3, 1.2, 0.87);
      const Eigen::Matrix3d H = inducedHomography(t, truth);
      const auto eq7 = poseFromHomography(H, t, kSceneK);
      ASSERT_TRUE(eq7.has_value());
      EXPECT_LT(rotationError(*eq7, truth), 1e-8);
      EXPECT_LT(translationError(*eq7, truth), 1e-9);
      const PoseResult paper = estimatePosePaper(H, t, kSceneK, PoseOptions{});
      ASSERT_TRUE(paper.ok);
      EXPECT_LT(rotationError(paper.cMo, truth), 1e-8);
      EXPECT_LT(translationError(paper.cMo, truth), 1e-9);
      EXPECT_LT(paper.rms_px, 1e-6);
    }
  }
}

TEST(Pose, PaperLmFixesAPerturbedHomography) {
  // Noisy H: eq. 7 alone is off; LM on the four corners lands on the corners' pose.
  std::mt19937_64 rng(5);
  std::normal_distribution<double> N(0, 1.0);
  const PlanarTarget t = referenceTarget();
  for (int trial = 0; trial < 10; ++trial) {
    const Pose truth = randomPose(rng, 0.4, 1.0, 0.8);
    std::vector<Eigen::Vector2d> from, to;
    for (const auto& c : t.corners_ref_px) {
      from.push_back(c);
      to.push_back(projectPinhole(kSceneK, truth * *t.backProject(c)) + Eigen::Vector2d(N(rng), N(rng)));
    }
    const Eigen::Matrix3d H = fitHomographyLeastSquares(from, to);
    const PoseResult r = estimatePosePaper(H, t, kSceneK, PoseOptions{});
    ASSERT_TRUE(r.ok);
    // LM minimises the corner residual that eq. 7 + SVD leaves.
    PoseOptions no_lm;
    no_lm.paper_lm_iterations = 0;
    const PoseResult init = estimatePosePaper(H, t, kSceneK, no_lm);
    EXPECT_LT(r.rms_px, init.rms_px);
    EXPECT_LT(r.rms_px, 1.5);
    // 1 px corner noise on a 100-250 px wide target: a few degrees, a few percent at most.
    EXPECT_LT(rotationError(r.cMo, truth), 5.0 * M_PI / 180);
    EXPECT_LT(translationError(r.cMo, truth), 0.03 * truth.t.norm());
  }
}

TEST(Pose, RefinedIsRobustToOutliers) {
  // 150 correspondences, 0.5 px noise, 10% gross outliers (5-40 px): Huber-IRLS stays close to
  // the outlier-free solution, plain least squares does not.
  std::mt19937_64 rng(3);
  std::normal_distribution<double> N(0, 0.5);
  std::uniform_real_distribution<double> Uu(0, 399), Uv(0, 299), Ua(0, 2 * M_PI), Ur(5, 40);
  const PlanarTarget t = referenceTarget();
  PoseOptions plain;
  plain.huber_px = 0;
  double rob_t = 0, ls_t = 0, rob_r = 0, ls_r = 0, clean_r = 0;
  for (int trial = 0; trial < 10; ++trial) {
    const Pose truth = randomPose(rng, 0.3, 1.2, 0.87);
    std::vector<Eigen::Vector3d> X;
    std::vector<Eigen::Vector2d> y, y_clean;
    for (int i = 0; i < 150; ++i) {
      const Eigen::Vector3d Xo = *t.backProject({Uu(rng), Uv(rng)});
      const Eigen::Vector2d p = projectPinhole(kSceneK, truth * Xo) + Eigen::Vector2d(N(rng), N(rng));
      const double a = Ua(rng), r = Ur(rng);
      X.push_back(Xo);
      y_clean.push_back(p);
      y.push_back(i % 10 == 0 ? p + r * Eigen::Vector2d(std::cos(a), std::sin(a)) : p);
    }
    const PoseResult robust = estimatePoseRefined(X, y, t, kSceneK, PoseOptions{});
    const PoseResult ls = estimatePoseRefined(X, y, t, kSceneK, plain);
    const PoseResult clean = estimatePoseRefined(X, y_clean, t, kSceneK, plain);
    ASSERT_TRUE(robust.ok && ls.ok && clean.ok);
    rob_t = std::max(rob_t, translationError(robust.cMo, truth) / truth.t.norm());
    ls_t = std::max(ls_t, translationError(ls.cMo, truth) / truth.t.norm());
    rob_r = std::max(rob_r, rotationError(robust.cMo, truth) * 180 / M_PI);
    ls_r = std::max(ls_r, rotationError(ls.cMo, truth) * 180 / M_PI);
    clean_r = std::max(clean_r, rotationError(clean.cMo, truth) * 180 / M_PI);
  }
  std::printf("refined pose, 10%% outliers, worst of 10: Huber %.2f deg %.4f rel.t | least "
              "squares %.2f deg %.4f rel.t | no outliers %.2f deg\n", rob_r, rob_t, ls_r, ls_t, clean_r);
  EXPECT_LT(rob_t, 0.01);
  EXPECT_LT(rob_t, ls_t);
  EXPECT_LT(rob_r, ls_r);
  EXPECT_LT(rob_r, 2.0 * clean_r + 0.2);
}

TEST(Pose, OptionsCheckRejectsNonsense) {
  PoseOptions o;
  EXPECT_NO_THROW(o.check());
  o.huber_px = -1;
  EXPECT_THROW(o.check(), std::invalid_argument);
  o = PoseOptions{};
  o.paper_lm_iterations = -3;
  EXPECT_THROW(o.check(), std::invalid_argument);
  o = PoseOptions{};
  o.min_corner_depth_m = std::nan("");
  EXPECT_THROW(o.check(), std::invalid_argument);
}

TEST(Sanity, EachRuleRejects) {
  const std::array<Eigen::Vector2d, 4> square = {Eigen::Vector2d(100, 100), Eigen::Vector2d(200, 100),
                                                 Eigen::Vector2d(200, 200), Eigen::Vector2d(100, 200)};
  const SanityOptions opt;
  const Pose at1m(Eigen::Matrix3d::Identity(), {0, 0, 1});
  EXPECT_EQ(checkDetection(square, at1m, 640, 480, opt), SanityStatus::kOk);
  EXPECT_EQ(checkDetection(square, std::nullopt, 640, 480, opt), SanityStatus::kOk);
  EXPECT_EQ(checkDetection(square, Pose(Eigen::Matrix3d::Identity(), {0, 0, -1}), 640, 480, opt),
            SanityStatus::kBehindCamera);
  EXPECT_EQ(checkDetection(square, Pose(Eigen::Matrix3d::Identity(), {0, 0, 0.15}), 640, 480, opt),
            SanityStatus::kTooClose);
  EXPECT_EQ(checkDetection(square, Pose(Eigen::Matrix3d::Identity(), {0, 0, 10.5}), 640, 480, opt),
            SanityStatus::kTooFar);
  auto bowtie = square;
  std::swap(bowtie[1], bowtie[2]);
  EXPECT_EQ(checkDetection(bowtie, at1m, 640, 480, opt), SanityStatus::kNotConvex);
  auto tiny = square;
  for (auto& c : tiny) c = Eigen::Vector2d(100, 100) + 0.1 * (c - Eigen::Vector2d(100, 100));
  EXPECT_EQ(checkDetection(tiny, at1m, 640, 480, opt), SanityStatus::kAreaTooSmall);
  // A close-up may show the pattern up to 4x the frame (max_area_fraction 16): 2000 px passes,
  // 3000 px does not.
  auto closeup = square, huge = square;
  for (auto& c : closeup) c = Eigen::Vector2d(150, 150) + 20.0 * (c - Eigen::Vector2d(150, 150));
  for (auto& c : huge) c = Eigen::Vector2d(150, 150) + 30.0 * (c - Eigen::Vector2d(150, 150));
  EXPECT_EQ(checkDetection(closeup, at1m, 640, 480, opt), SanityStatus::kOk);
  EXPECT_EQ(checkDetection(huge, at1m, 640, 480, opt), SanityStatus::kAreaTooLarge);
  auto nan = square;
  nan[0].x() = std::nan("");
  EXPECT_EQ(checkDetection(nan, at1m, 640, 480, opt), SanityStatus::kNotFinite);
  SanityOptions bad;
  bad.max_distance_m = 0.1;
  EXPECT_THROW(bad.check(), std::invalid_argument);
  for (const double gap : {0.0, -1.0, 2e9, std::nan("")}) {
    SanityOptions o;
    o.max_pose_gap_px = gap;
    EXPECT_THROW(o.check(), std::invalid_argument) << gap;
  }
  SanityOptions never;
  never.max_pose_gap_px = 1e9;  // the pose check off
  EXPECT_NO_THROW(never.check());
}

TEST(Stereo, FusionAveragesInTheLeftFrame) {
  StereoRig rig;
  rig.lMr = Pose::fromRotationVector({0, 0.02, 0}, {0.12, 0, 0});
  const Pose truth = Pose::fromRotationVector({0.3, -0.2, 0.1}, {0.05, 0.02, 0.8});
  const Pose rMo = rig.lMr.inverse() * truth;
  // Perturb the two eyes in opposite directions: the average cancels the perturbation.
  const Eigen::Vector3d dr(0.01, -0.005, 0.002), dt(0.003, -0.002, 0.004);
  const Pose left = Pose::fromRotationVector(truth.rotationVector() + dr, truth.t + dt);
  const Pose right_in_l = Pose::fromRotationVector(truth.rotationVector() - dr, truth.t - dt);
  const FusedPose f = fuseStereo(left, rig.lMr.inverse() * right_in_l, rig);
  ASSERT_EQ(f.eyes, EyesUsed::kBoth);
  EXPECT_LT(translationError(*f.lMo, truth), 1e-12);
  EXPECT_LT(rotationError(*f.lMo, truth), 1e-12);
  const FusedPose r_only = fuseStereo(std::nullopt, rMo, rig);
  EXPECT_EQ(r_only.eyes, EyesUsed::kRight);
  EXPECT_LT(translationError(*r_only.lMo, truth), 1e-12);
  EXPECT_EQ(fuseStereo(left, std::nullopt, rig).eyes, EyesUsed::kLeft);
  EXPECT_EQ(fuseStereo(std::nullopt, std::nullopt, rig).eyes, EyesUsed::kNone);
  EXPECT_FALSE(fuseStereo(std::nullopt, std::nullopt, rig).lMo.has_value());
}

TEST(Stereo, RotationVectorAverageDoesNotWrapNearPi) {
  // Rotations of pi - 0.01 and pi + 0.01 about x: naive vector averaging gives ~0 rotation.
  StereoRig rig;  // identity lMr
  const Pose a = Pose::fromRotationVector({M_PI - 0.01, 0, 0}, {0, 0, 1});
  const Pose b(axisAngle(Eigen::Vector3d::UnitX(), M_PI + 0.01), Eigen::Vector3d(0, 0, 1));
  const Pose truth(axisAngle(Eigen::Vector3d::UnitX(), M_PI), Eigen::Vector3d(0, 0, 1));
  const FusedPose f = fuseStereo(a, b, rig);
  EXPECT_LT(rotationError(*f.lMo, truth), 1e-9);
  const Eigen::Vector3d c = closestRotationVector({-(M_PI - 0.01), 0, 0}, {M_PI - 0.01, 0, 0});
  EXPECT_NEAR(c.x(), M_PI + 0.01, 1e-12);
}

// The planar pose ambiguity (tracking): the 0.2 m target seen at 60 deg from 3.3 m is ~33 px
// wide and nearly affine, so IPPE's two solutions reproject within a fraction of a pixel of the
// points (0.3 px noise) although they are far apart in rotation. estimatePoseRefinedNear returns
// the one that continues the prior; far from the ambiguity (0.6 m) the wrong solution fits
// clearly worse and the truth is returned whatever the prior.
TEST(Pose, RefinedNearAPriorResolvesThePlanarAmbiguity) {
  const PlanarTarget t = referenceTarget();
  std::mt19937_64 rng(8);
  std::normal_distribution<double> N(0, 0.3);
  std::uniform_real_distribution<double> Uu(0, 399), Uv(0, 299);
  for (const double z : {3.3, 0.6}) {
    const Pose truth(axisAngle(Eigen::Vector3d(1, 0.4, 0), 60 * M_PI / 180), Eigen::Vector3d(0.02, -0.01, z));
    std::vector<Eigen::Vector3d> X;
    std::vector<Eigen::Vector2d> y;
    for (int i = 0; i < 64; ++i) {
      const Eigen::Vector3d Xo = *t.backProject({Uu(rng), Uv(rng)});
      X.push_back(Xo);
      y.push_back(projectPinhole(kSceneK, truth * Xo) + Eigen::Vector2d(N(rng), N(rng)));
    }
    const PoseResult near_truth = estimatePoseRefinedNear(X, y, t, kSceneK, PoseOptions{}, truth, 0.5);
    ASSERT_TRUE(near_truth.ok) << z;
    EXPECT_LT(rotationError(near_truth.cMo, truth) * 180 / M_PI, z > 1 ? 3.0 : 0.5) << z;
    // A prior tilted the other way (the mirror of the truth about the viewing ray): near the
    // second solution when the view is ambiguous.
    const Pose flipped(axisAngle(Eigen::Vector3d(-1, -0.4, 0), 60 * M_PI / 180), truth.t);
    const PoseResult near_flip = estimatePoseRefinedNear(X, y, t, kSceneK, PoseOptions{}, flipped, 0.5);
    ASSERT_TRUE(near_flip.ok) << z;
    const double flip_deg = rotationError(near_flip.cMo, truth) * 180 / M_PI;
    SCOPED_TRACE(refgrasp::testing::formatted(
        "z %.1f m: near the truth %.2f deg off (rms %.3f px); near the mirror %.1f deg off (rms %.3f px)", z,
        rotationError(near_truth.cMo, truth) * 180 / M_PI, near_truth.rms_px, flip_deg, near_flip.rms_px));
    if (z > 1) {
      EXPECT_GT(flip_deg, 30.0) << "far: the prior picks the mirror solution";
      EXPECT_LT(near_flip.rms_px, near_truth.rms_px + 0.5);
    } else {
      EXPECT_LT(flip_deg, 0.5) << "near: the mirror fits too badly to be taken";
    }
  }
}
