// Dense (ECC) homography refinement: recovers a known H from a perturbed start on rendered
// scenes, picks a coarse pyramid level for small targets, refuses bad starts; options checks.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "common/format.h"
#include "robot/sim/synthetic_scene.h"
#include "detector/dense.h"
#include "detector/homography.h"

using namespace refgrasp;
using namespace refgrasp::detector;
using namespace refgrasp::testing;

namespace {

constexpr double kWidth = 0.20;

std::array<Eigen::Vector2d, 4> textureRect(const cv::Mat& tex) {
  return {Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(tex.cols - 0.5, -0.5),
          Eigen::Vector2d(tex.cols - 0.5, tex.rows - 0.5), Eigen::Vector2d(-0.5, tex.rows - 0.5)};
}

Eigen::Matrix3d homographyFrom(const std::array<Eigen::Vector2d, 4>& a,
                               const std::array<Eigen::Vector2d, 4>& b) {
  std::vector<cv::Point2f> pa, pb;
  for (int i = 0; i < 4; ++i) {
    pa.emplace_back(static_cast<float>(a[i].x()), static_cast<float>(a[i].y()));
    pb.emplace_back(static_cast<float>(b[i].x()), static_cast<float>(b[i].y()));
  }
  const cv::Mat H = cv::getPerspectiveTransform(pa, pb);
  Eigen::Matrix3d E;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) E(r, c) = H.at<double>(r, c);
  return E;
}

double cornerError(const Eigen::Matrix3d& H, const std::array<Eigen::Vector2d, 4>& ref,
                   const std::array<Eigen::Vector2d, 4>& truth) {
  double e = 0;
  for (int i = 0; i < 4; ++i) e = std::max(e, (applyHomography(H, ref[i]) - truth[i]).norm());
  return e;
}

/// The corners, each pushed by up to 1.5 px (a start for the refinement).
std::array<Eigen::Vector2d, 4> pushed(std::array<Eigen::Vector2d, 4> corners) {
  const double d[4][2] = {{1.5, -1.0}, {-1.2, 0.8}, {0.7, 1.4}, {-1.0, -1.3}};
  for (int i = 0; i < 4; ++i) corners[i] += Eigen::Vector2d(d[i][0], d[i][1]);
  return corners;
}

}  // namespace

TEST(DenseRefine, RecoversPerturbedHomography) {
  const cv::Mat tex = loadMedia("targets/poster_concert.png");
  const double h = kWidth * tex.rows / tex.cols;
  const Intrinsics cam = sceneCamera();
  const std::vector<cv::Mat> pyr = buildReferencePyramid(tex);
  ASSERT_GE(pyr.size(), 4u);
  EXPECT_EQ(pyr[1].cols, (tex.cols + 1) / 2);
  const auto rect = textureRect(tex);
  struct Case {
    Pose cMo;
    double blur;
  };
  const std::vector<Case> cases = {
      {Pose::fromRotationVector({0.02, -0.01, 0.3}, {0.03, -0.02, 1.18}), 0.0},
      {Pose::fromRotationVector({0.25, -0.3, 0.1}, {-0.05, 0.02, 0.8}), 1.0},
      {Pose::fromRotationVector({-0.5, 0.3, -0.2}, {0.02, 0.03, 0.5}), 0.5},
      {Pose::fromRotationVector({0.1, 0.1, 1.2}, {0.0, 0.0, 0.35}), 1.5}};
  DenseRefineOptions opt;
  for (size_t k = 0; k < cases.size(); ++k) {
    SceneSpec spec;
    spec.cMo = cases[k].cMo;
    spec.motion_blur_px = cases[k].blur;
    spec.seed = 70 + k;
    const RenderedScene s = renderTarget(cam, tex, kWidth, h, spec);
    const Eigen::Matrix3d H_true = homographyFrom(rect, s.corners);
    // Start: every corner pushed by up to 1.5 px.
    const Eigen::Matrix3d H0 = homographyFrom(rect, pushed(s.corners));
    const DenseRefineResult r = refineHomographyDense(pyr, s.image, H0, rect, opt);
    ASSERT_TRUE(r.ok) << "case " << k;
    const double e0 = cornerError(H0, rect, s.corners), e1 = cornerError(r.H, rect, s.corners);
    SCOPED_TRACE(formatted("case %zu: level %d, corr %.3f, corner error %.3f -> %.3f px", k, r.level,
                           r.correlation, e0, e1));
    // The near, strongly blurred case is limited by the template budget (level 2, ~3x coarser
    // than the scene): 0.15 px measured.
    EXPECT_LT(e1, k == 3 ? 0.2 : 0.1) << "case " << k;
    EXPECT_LT(e1, 0.2 * e0) << "case " << k;
    EXPECT_LT(cornerError(H_true, rect, s.corners), 1e-3);
    // Level 2 (100x75): the far target is ~93 px wide; the near ones by the 16384 px budget.
    EXPECT_EQ(r.level, 2) << "case " << k;
  }
}

// A photographed reference (DenseRefineOptions::normalize_sigma_px): the reference carries a
// light gradient (0.35x to 1.35x across) and a specular highlight the scene does not. ECC absorbs
// one gain and offset only, so the raw alignment is refused or pulled off (1.2-1.6 px, correlation
// about 0.7); the retry on locally normalised intensities recovers H. Without the retry nothing
// is recovered.
TEST(DenseRefine, ANormalisedRetryAlignsAReferencePhotographedUnderOtherLight) {
  const cv::Mat tex = loadMedia("targets/poster_concert.png");
  const double h = kWidth * tex.rows / tex.cols;
  cv::Mat lit(tex.size(), CV_8UC1);
  for (int y = 0; y < tex.rows; ++y)
    for (int x = 0; x < tex.cols; ++x) {
      const double gain = 0.35 + 1.0 * x / tex.cols;
      const double dx = x - 0.65 * tex.cols, dy = y - 0.35 * tex.rows, r = 0.12 * tex.cols;
      const double highlight = 150 * std::exp(-(dx * dx + dy * dy) / (2 * r * r));
      lit.at<uchar>(y, x) = cv::saturate_cast<uchar>(gain * tex.at<uchar>(y, x) + highlight);
    }
  const std::vector<cv::Mat> pyr = buildReferencePyramid(lit);
  const auto rect = textureRect(tex);
  const Intrinsics cam = sceneCamera();
  const std::vector<Pose> poses = {Pose::fromRotationVector({0.02, -0.01, 0.3}, {0.03, -0.02, 1.18}),
                                   Pose::fromRotationVector({0.25, -0.3, 0.1}, {-0.05, 0.02, 0.8}),
                                   Pose::fromRotationVector({-0.5, 0.3, -0.2}, {0.02, 0.03, 0.5})};
  DenseRefineOptions with, without;
  without.normalize_sigma_px = 0;
  int recovered_with = 0, recovered_without = 0;
  for (size_t k = 0; k < poses.size(); ++k) {
    SceneSpec spec;
    spec.cMo = poses[k];
    spec.seed = 90 + k;
    const RenderedScene s = renderTarget(cam, tex, kWidth, h, spec);
    const Eigen::Matrix3d H0 = homographyFrom(rect, pushed(s.corners));
    const DenseRefineResult a = refineHomographyDense(pyr, s.image, H0, rect, with);
    const DenseRefineResult b = refineHomographyDense(pyr, s.image, H0, rect, without);
    const double e0 = cornerError(H0, rect, s.corners);
    const double ea = cornerError(a.H, rect, s.corners), eb = cornerError(b.H, rect, s.corners);
    SCOPED_TRACE(formatted("case %zu: start %.2f px; with the retry ok %d corr %.3f error %.3f px; raw only ok %d "
                           "corr %.3f error %.3f px", k, e0, a.ok, a.correlation, ea, b.ok, b.correlation, eb));
    recovered_with += a.ok && ea < 0.5;
    recovered_without += b.ok && eb < 0.5;
    EXPECT_TRUE(a.ok) << "case " << k;
    EXPECT_LT(ea, 0.25) << "case " << k;
    EXPECT_GT(eb, 1.0) << "case " << k;  // raw only: refused, or accepted but off
  }
  EXPECT_EQ(recovered_with, 3);
  EXPECT_EQ(recovered_without, 0);
}

// A polygon region (make_reference's pattern_region): only the template pixels inside it count.
// The scene shows the pattern inside a hexagon and another texture outside it (what a reference
// photo's surroundings do): with the mask the refinement recovers H (the mask must be moved into
// the scene's frame: a size mismatch makes OpenCV throw and the refinement fail).
TEST(DenseRefine, APolygonRegionMasksTheTemplate) {
  const cv::Mat tex = loadMedia("targets/poster_concert.png");
  const cv::Mat other = loadMedia("clutter/clutter_03.png");
  cv::Mat outside;
  cv::resize(other, outside, tex.size());
  const double W = tex.cols, Hh = tex.rows;
  const std::vector<Eigen::Vector2d> hexagon = {
      {0.25 * W, 0.1 * Hh}, {0.75 * W, 0.1 * Hh}, {0.95 * W, 0.5 * Hh},
      {0.75 * W, 0.9 * Hh}, {0.25 * W, 0.9 * Hh}, {0.05 * W, 0.5 * Hh}};
  cv::Mat inside = cv::Mat::zeros(tex.size(), CV_8UC1);
  std::vector<cv::Point> poly;
  for (const auto& p : hexagon) poly.emplace_back(cvRound(p.x()), cvRound(p.y()));
  cv::fillPoly(inside, std::vector<std::vector<cv::Point>>{poly}, cv::Scalar(255));
  cv::Mat shown = outside.clone();
  tex.copyTo(shown, inside);  // the scene's object: the pattern in the hexagon, clutter around it
  const double h = kWidth * tex.rows / tex.cols;
  const Intrinsics cam = sceneCamera();
  const std::vector<cv::Mat> pyr = buildReferencePyramid(tex);  // the reference: the whole photo
  const auto rect = textureRect(tex);
  SceneSpec spec;
  spec.cMo = Pose::fromRotationVector({0.25, -0.3, 0.1}, {-0.05, 0.02, 0.8});
  spec.seed = 90;
  const RenderedScene s = renderTarget(cam, shown, kWidth, h, spec);
  const Eigen::Matrix3d H0 = homographyFrom(rect, pushed(s.corners));
  const DenseRefineOptions opt;
  const DenseRefineResult masked = refineHomographyDense(pyr, s.image, H0, rect, opt, &hexagon);
  ASSERT_TRUE(masked.ok);
  const double e0 = cornerError(H0, rect, s.corners), e1 = cornerError(masked.H, rect, s.corners);
  const DenseRefineResult whole = refineHomographyDense(pyr, s.image, H0, rect, opt);
  std::printf("polygon mask: corr %.3f, corner error %.3f -> %.3f px (without the mask: ok %d, corr %.3f, %.3f px)\n",
              masked.correlation, e0, e1, whole.ok, whole.correlation, cornerError(whole.H, rect, s.corners));
  EXPECT_GT(masked.correlation, 0.9);
  // The rectangle's corners lie outside the hexagon: their error is extrapolated.
  EXPECT_LT(e1, 0.3);
  EXPECT_LT(e1, 0.2 * e0);
  // Robust too (the tracker's alignment of a polygon reference).
  DenseRefineOptions robust = opt;
  robust.robust = true;
  const DenseRefineResult r2 = refineHomographyDense(pyr, s.image, H0, rect, robust, &hexagon);
  ASSERT_TRUE(r2.ok);
  EXPECT_LT(cornerError(r2.H, rect, s.corners), 0.3);
}

// dense.robust (the tracker's alignment): a panel over part of the pattern is left out of the
// fit, the rest aligns as well as an unoccluded view; too little left is refused.
TEST(DenseRefine, RobustLeavesAnOccluderOut) {
  const cv::Mat tex = loadMedia("targets/poster_concert.png");
  const cv::Mat panel = loadMedia("clutter/clutter_03.png");
  const Intrinsics cam = sceneCamera();
  const std::vector<cv::Mat> pyr = buildReferencePyramid(tex);
  const auto rect = textureRect(tex);
  SceneSpec spec;
  spec.cMo = Pose::fromRotationVector({0.15, -0.1, 0.05}, {0.0, 0.0, 0.6});
  spec.seed = 11;
  const RenderedScene s = renderTarget(cam, tex, kWidth, kWidth * tex.rows / tex.cols, spec);
  const Eigen::Matrix3d H0 = homographyFrom(rect, pushed(s.corners));
  std::vector<cv::Point> outline;
  for (const auto& c : s.corners) outline.emplace_back(cvRound(c.x()), cvRound(c.y()));
  const cv::Rect box = cv::boundingRect(outline);
  // The panel covers the left `fraction` of the pattern's bounding box.
  const auto occluded = [&](double fraction) {
    cv::Mat img = s.image.clone();
    const cv::Rect r(box.x, box.y, static_cast<int>(fraction * box.width), box.height);
    cv::Mat p;
    cv::resize(panel, p, r.size());
    p.copyTo(img(r));
    return img;
  };
  DenseRefineOptions plain, robust;
  robust.robust = true;
  plain.max_corner_shift_px = robust.max_corner_shift_px = 20;  // as the tracker's alignment
  const cv::Mat third = occluded(0.35);
  const DenseRefineResult a = refineHomographyDense(pyr, third, H0, rect, plain);
  const DenseRefineResult b = refineHomographyDense(pyr, third, H0, rect, robust);
  const double ea = a.ok ? cornerError(a.H, rect, s.corners) : NAN;
  ASSERT_TRUE(b.ok) << "corr " << b.correlation << " shift " << b.corner_shift_px;
  const double eb = cornerError(b.H, rect, s.corners);
  std::printf("35 %% occluded: plain %s (corr %.3f, corner error %.3f px), robust corr %.3f, corner "
              "error %.3f px, masked %.2f\n", a.ok ? "ok" : "refused", a.correlation, ea, b.correlation, eb,
              b.masked_fraction);
  EXPECT_LT(eb, 0.2);
  EXPECT_LT(eb, ea);
  EXPECT_GT(b.masked_fraction, 0.25);  // 35 % of the bounding box, less of the tilted pattern
  EXPECT_LT(b.masked_fraction, 0.45);
  // Unoccluded: nothing left out.
  const DenseRefineResult c = refineHomographyDense(pyr, s.image, H0, rect, robust);
  ASSERT_TRUE(c.ok);
  EXPECT_LT(c.masked_fraction, 0.05);
  EXPECT_LT(cornerError(c.H, rect, s.corners), 0.1);
  // 85 % hidden: less than robust_min_kept left.
  EXPECT_FALSE(refineHomographyDense(pyr, occluded(0.85), H0, rect, robust).ok);
}

TEST(DenseRefine, RefusesBadStartsAndInputs) {
  const cv::Mat tex = loadMedia("targets/poster_concert.png");
  const Intrinsics cam = sceneCamera();
  const std::vector<cv::Mat> pyr = buildReferencePyramid(tex);
  const auto rect = textureRect(tex);
  SceneSpec spec;
  spec.cMo = Pose::fromRotationVector({0.2, -0.1, 0.1}, {0.0, 0.0, 0.7});
  spec.seed = 5;
  const RenderedScene s = renderTarget(cam, tex, kWidth, kWidth * tex.rows / tex.cols, spec);
  DenseRefineOptions opt;
  // A start 12 px off: whatever ECC does, the result may not move a corner more than 3 px.
  std::array<Eigen::Vector2d, 4> far = s.corners;
  for (auto& c : far) c += Eigen::Vector2d(12, -9);
  const Eigen::Matrix3d H_far = homographyFrom(rect, far);
  const DenseRefineResult r = refineHomographyDense(pyr, s.image, H_far, rect, opt);
  if (r.ok) EXPECT_LE(r.corner_shift_px, opt.max_corner_shift_px);
  else EXPECT_TRUE(r.H.isApprox(H_far));
  // A blank scene: no correlation, input H returned.
  const cv::Mat blank(480, 640, CV_8UC1, cv::Scalar(128));
  const Eigen::Matrix3d H_true = homographyFrom(rect, s.corners);
  const DenseRefineResult b = refineHomographyDense(pyr, blank, H_true, rect, opt);
  EXPECT_FALSE(b.ok);
  EXPECT_TRUE(b.H.isApprox(H_true));
  // Empty inputs, wrong pixel type, non-finite H, pattern mapped behind the camera.
  EXPECT_FALSE(refineHomographyDense({}, s.image, H_true, rect, opt).ok);
  EXPECT_FALSE(refineHomographyDense(pyr, cv::Mat(), H_true, rect, opt).ok);
  EXPECT_FALSE(refineHomographyDense(pyr, cv::Mat(480, 640, CV_32F, 0.0f), H_true, rect, opt).ok);
  Eigen::Matrix3d nan_H = H_true;
  nan_H(0, 0) = NAN;
  EXPECT_FALSE(refineHomographyDense(pyr, s.image, nan_H, rect, opt).ok);
  EXPECT_FALSE(refineHomographyDense(pyr, s.image, -H_true * Eigen::Vector3d(1, 1, -1).asDiagonal(),
                                     rect, opt).ok);
}

TEST(DenseRefine, OptionsCheck) {
  EXPECT_NO_THROW(DenseRefineOptions{}.check());
  auto bad = [](auto mutate) {
    DenseRefineOptions o;
    mutate(o);
    EXPECT_THROW(o.check(), std::invalid_argument);
  };
  bad([](DenseRefineOptions& o) { o.max_iterations = 0; });
  bad([](DenseRefineOptions& o) { o.epsilon = NAN; });
  bad([](DenseRefineOptions& o) { o.max_template_px = 10; });
  bad([](DenseRefineOptions& o) { o.max_corner_shift_px = 0; });
  bad([](DenseRefineOptions& o) { o.min_correlation = 1.5; });
  bad([](DenseRefineOptions& o) { o.gauss_filter_size = 4; });
  bad([](DenseRefineOptions& o) { o.normalize_sigma_px = -1; });
  bad([](DenseRefineOptions& o) { o.normalize_sigma_px = NAN; });
  bad([](DenseRefineOptions& o) { o.raw_trusted_correlation = 1.5; });
  bad([](DenseRefineOptions& o) { o.normalized_min_correlation = 1; });
  bad([](DenseRefineOptions& o) { o.max_2d_coarsening = 0.5; });
  bad([](DenseRefineOptions& o) { o.max_2d_coarsening = NAN; });
  bad([](DenseRefineOptions& o) { o.pose_grid = 1; });
  bad([](DenseRefineOptions& o) { o.robust_block_px = 1; });
  bad([](DenseRefineOptions& o) { o.robust_min_residual = 0; });
  bad([](DenseRefineOptions& o) { o.robust_min_kept = 1.5; });
  try {
    DenseRefineOptions o;
    o.gauss_filter_size = 2;
    o.check();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("DenseRefineOptions.gauss_filter_size"),
              std::string::npos);
  }
  // Pyramid: level k has ceil(W / 2^k) columns, stops before a side drops below the minimum.
  const cv::Mat img(300, 400, CV_8UC1, cv::Scalar(0));
  const std::vector<cv::Mat> pyr = buildReferencePyramid(img, 16);
  ASSERT_EQ(pyr.size(), 5u);  // 400x300, 200x150, 100x75, 50x38, 25x19
  EXPECT_EQ(pyr[4].cols, 25);
  EXPECT_EQ(pyr[4].rows, 19);
  EXPECT_TRUE(buildReferencePyramid(cv::Mat()).empty());
}
