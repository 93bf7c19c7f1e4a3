// Photo pairs (eval/pairs_eval.h) in small: the generator's ground truth, the verification of a
// close-up where it is seen, and close-ups (zoomed 2.1-2.9x and rolled) found. The full tables:
// build/bench/bench_pairs.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "detector/dense.h"
#include "detector/detector.h"
#include "detector/object.h"
#include "detector/verify.h"
#include "eval/classic.h"
#include "eval/pairs_eval.h"

using namespace refgrasp;
using namespace refgrasp::eval;

namespace {

constexpr uint64_t kSeed = 7;  // a split neither tuned on (1) nor reported (1001)

cv::Mat toCv(const Eigen::Matrix3d& H) {
  cv::Mat m(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m.at<double>(r, c) = H(r, c);
  return m;
}

// Zero-mean NCC of the reference warped by H with the scene, over the pixels it covers
// (eroded by 3 px: the anti-aliased edges).
double warpedCorrelation(const ViewPair& p, const Eigen::Matrix3d& H) {
  cv::Mat warped, mask;
  cv::warpPerspective(p.reference, warped, toCv(H), p.scene.size(), cv::INTER_LINEAR);
  cv::warpPerspective(cv::Mat(p.reference.size(), CV_8UC1, cv::Scalar(255)), mask, toCv(H), p.scene.size(),
                      cv::INTER_NEAREST);
  cv::erode(mask, mask, cv::Mat(), cv::Point(-1, -1), 3);
  cv::Mat a, b;
  cv::GaussianBlur(warped, a, cv::Size(0, 0), 1.5);
  cv::GaussianBlur(p.scene, b, cv::Size(0, 0), 1.5);
  cv::Scalar ma, sa, mb, sb;
  cv::meanStdDev(a, ma, sa, mask);
  cv::meanStdDev(b, mb, sb, mask);
  cv::Mat fa, fb;
  a.convertTo(fa, CV_64F, 1, -ma[0]);
  b.convertTo(fb, CV_64F, 1, -mb[0]);
  const double n = cv::countNonZero(mask);
  cv::Mat m;
  mask.convertTo(m, CV_64F, 1.0 / 255);
  return cv::sum(fa.mul(fb).mul(m))[0] / (n * sa[0] * sb[0]);
}

}  // namespace

// Ground truth by construction: the reference warped by H_true is the scene over the picture,
// for every family at its mildest and harshest level; a homography 2 px off correlates less.
TEST(PhotoPairs, TheTrueHomographyMapsTheReferenceOntoTheScene) {
  for (int f = 0; f < kPairFamilies; ++f)
    for (int level : {0, kPairLevels - 1}) {
      const auto family = static_cast<PairFamily>(f);
      const ViewPair p = makeViewPair("targets/book_cover.png", family, level, kSeed);
      const bool near_identity = family == PairFamily::kNearLight || family == PairFamily::kNearJpeg;
      ASSERT_EQ(p.scene.size(), near_identity ? p.reference.size() : cv::Size(640, 480));
      const double truth = warpedCorrelation(p, p.H_true);
      Eigen::Matrix3d shift = Eigen::Matrix3d::Identity();
      shift(0, 2) = 2;
      const double off = warpedCorrelation(p, shift * p.H_true);
      const std::string what = std::string(pairFamilyName(family)) + " " + pairLevelLabel(family, level);
      // Blur 5 px and JPEG quality 4 (near-identity: 10) keep less of the picture's detail.
      const bool lossy = family == PairFamily::kBlur || family == PairFamily::kJpeg || family == PairFamily::kNearJpeg;
      EXPECT_GT(truth, lossy ? 0.8 : 0.9) << what;
      EXPECT_LT(off, truth - 0.01) << what;
      EXPECT_NEAR(worstCornerError(p, p.H_true), 0, 1e-9);
      EXPECT_GT(worstCornerError(p, shift * p.H_true), 1.99);
    }
  // Deterministic: the same seed gives the same pair.
  const ViewPair a = makeViewPair("photos/hotel_facade.jpg", PairFamily::kZoomRotation, 2, kSeed),
                 b = makeViewPair("photos/hotel_facade.jpg", PairFamily::kZoomRotation, 2, kSeed);
  EXPECT_EQ(cv::norm(a.scene, b.scene, cv::NORM_INF), 0);
  EXPECT_LE(a.reference.cols, 640);
}

// A close-up (the picture 2.1-2.9x its reference's scale, larger than the frame) is verified on
// the part in view: the truth passes, the truth shifted by a fifth of the reference or mirrored
// does not. (Before, less than a quarter of the pattern in view made it "not computable".)
TEST(PhotoPairs, ACloseUpIsVerifiedWhereItIsSeen) {
  const detector::VerifyOptions opt;
  int cases = 0;
  for (const char* tex : {"photos/fruits_closeup.jpg", "targets/magazine.png", "photos/aerial_town.jpg"})
    for (int level = 2; level < kPairLevels; ++level) {
      const ViewPair p = makeViewPair(tex, PairFamily::kZoomRotation, level, kSeed);
      const std::vector<cv::Mat> pyr = detector::buildReferencePyramid(p.reference);
      const double w = p.reference.cols, h = p.reference.rows;
      const std::vector<Eigen::Vector2d> rect = {{-0.5, -0.5}, {w - 0.5, -0.5}, {w - 0.5, h - 0.5}, {-0.5, h - 0.5}};
      const detector::VerifyResult truth = verifyInstance(pyr, rect, p.scene, p.camera, p.H_true, opt);
      EXPECT_TRUE(truth.ok) << tex << " level " << level << ": " << truth.correlation << ", " << truth.strong_cells;
      EXPECT_GT(truth.correlation, 0.7) << tex << " level " << level;
      // Wrong: the truth shifted by a fifth of the reference, or mirrored.
      Eigen::Matrix3d shift = Eigen::Matrix3d::Identity(), mirror = Eigen::Matrix3d::Identity();
      shift(0, 2) = 0.2 * w;
      mirror(0, 0) = -1;
      mirror(0, 2) = w - 1;
      for (const Eigen::Matrix3d& wrong : {Eigen::Matrix3d(p.H_true * shift), Eigen::Matrix3d(p.H_true * mirror)}) {
        const detector::VerifyResult v = verifyInstance(pyr, rect, p.scene, p.camera, wrong, opt);
        EXPECT_FALSE(v.ok) << tex << " level " << level << ": " << v.correlation << ", " << v.strong_cells;
      }
      ++cases;
    }
  EXPECT_EQ(cases, 9);
}

// Close-ups found: zoomed 2.1-2.9x and rolled 30-50 degrees, five pictures. refgrasp places the
// corners within 3 px on at least 12 of 15 pairs (the classic pipeline: 14; the facade at 2.5x
// and 2.9x is 5-7 px off, its 1000 reference features leave the close-up about a sixth of
// them) and reports none wrong. The area limit (SanityOptions::max_area_fraction: up to 4x the
// frame) and the close-up exclusion of the re-alignment (VerifyOptions::realign_min_in_view) are
// what it takes: with a pattern at most 1.5x the frame and close-ups re-aligned (their corners far
// outside the frame extrapolated) at most 3 are placed. That bound is the premise that these
// pairs show the case; the regression checks are the ones on the defaults.
TEST(PhotoPairs, CloseUpsAreFound) {
  detector::DetectorOptions now, former;
  former.sanity.max_area_fraction = 1.5;
  former.verify.realign_min_in_view = 0;
  int within_now = 0, within_former = 0, within_classic = 0, wrong_now = 0, pairs = 0;
  for (const char* tex : {"photos/fruits_closeup.jpg", "photos/hotel_facade.jpg", "photos/butterfly_on_leaf.jpg",
                          "targets/cereal_box.png", "targets/tea_box.png"})
    for (int level = 2; level < kPairLevels; ++level) {
      const ViewPair p = makeViewPair(tex, PairFamily::kZoomRotation, level, kSeed);
      const detector::ObjectModel model = detector::makeObjectModel(tex, p.reference, std::nullopt, std::nullopt);
      auto run = [&](const detector::DetectorOptions& opt) {
        detector::Detector det(opt);
        det.addObject(model);
        const auto d = det.detect(p.scene, p.camera).find(0);
        return d ? worstCornerError(p, d->H) : -1.0;
      };
      const double e_now = run(now), e_former = run(former);
      const ClassicResult c = ClassicPipeline(model).detect(p.scene, p.camera);
      const double e_classic = c.found ? worstCornerError(p, c.H) : -1.0;
      std::printf("%s %s: refgrasp %.2f px (former %.2f), classic %.2f px\n", tex,
                  pairLevelLabel(PairFamily::kZoomRotation, level).c_str(), e_now, e_former, e_classic);
      within_now += e_now >= 0 && e_now <= 3;
      within_former += e_former >= 0 && e_former <= 3;
      within_classic += e_classic >= 0 && e_classic <= 3;
      wrong_now += e_now > 30;
      ++pairs;
    }
  std::printf("within 3 px: refgrasp %d, former %d, classic %d of %d\n", within_now, within_former, within_classic, pairs);
  EXPECT_GE(within_now, 12);
  EXPECT_GE(within_classic, 12);  // the pairs are fair: the classic pipeline places them too
  EXPECT_EQ(wrong_now, 0);
  EXPECT_LE(within_former, 3);
}

// Near-identity pairs at full resolution (1400 px wide under another light; JPEG quality 30):
// hundreds of features agree, and refgrasp's corners are as precise as the classic pipeline's.
// The dense alignment of such a pattern runs on a template 8-16x coarser than the scene (its size
// cap) and is not used for the corners, which come from the features: all of them, not only the
// strongest that the reference index keeps.
TEST(PhotoPairs, NearIdentityPairsAreAsPreciseAsTheClassicPipeline) {
  std::vector<double> e_refgrasp, e_classic;
  for (const PairFamily family : {PairFamily::kNearLight, PairFamily::kNearJpeg})
    for (int level : {3})  // 1400 px wide; JPEG quality 30 (800-1600 px)
      for (const char* tex : {"photos/fruits_closeup.jpg", "photos/butterfly_on_leaf.jpg", "targets/poster_concert.png"}) {
        const ViewPair p = makeViewPair(tex, family, level, kSeed);
        const detector::ObjectModel model = detector::makeObjectModel(tex, p.reference, std::nullopt, std::nullopt);
        detector::Detector det{detector::DetectorOptions{}};
        det.addObject(model);
        const auto d = det.detect(p.scene, p.camera).find(0);
        const ClassicResult c = ClassicPipeline(model).detect(p.scene, p.camera);
        ASSERT_TRUE(d && c.found) << tex << " " << pairFamilyName(family) << " " << pairLevelLabel(family, level);
        e_refgrasp.push_back(worstCornerError(p, d->H));
        e_classic.push_back(worstCornerError(p, c.H));
        std::printf("%s %s %s: refgrasp %.3f px, classic %.3f px\n", tex, pairFamilyName(family),
                    pairLevelLabel(family, level).c_str(), e_refgrasp.back(), e_classic.back());
        EXPECT_LT(e_refgrasp.back(), 3) << tex << " " << pairFamilyName(family) << " " << pairLevelLabel(family, level);
      }
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  const double m_refgrasp = median(e_refgrasp), m_classic = median(e_classic);
  std::printf("median worst-corner error: refgrasp %.3f px, classic %.3f px\n", m_refgrasp, m_classic);
  EXPECT_LE(m_refgrasp, m_classic);
  EXPECT_LT(m_refgrasp, 0.3);
}
