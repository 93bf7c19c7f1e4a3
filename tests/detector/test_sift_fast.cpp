// The project's fast SIFT (SiftImplementation::kFast, detector/sift_fast.h) against cv::SIFT of
// OpenCV 4.6 (kOpenCV), on rendered scenes, the textures themselves and real photographs:
// keypoint recall and precision (a counterpart within 0.5 px, 5 % in size, 5 degrees), descriptor
// distances of the matched keypoints, and the kernels' dispatch paths (bit-identical).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <random>
#include <string>
#include <thread>

#include "robot/sim/synthetic_scene.h"
#include "detector/detector.h"
#include "detector/features.h"
#include "detector/sift_fast.h"
#include "eval/sift_equivalence.h"

namespace refgrasp::detector {
namespace {

// Equivalence bars (the extractor must keep >= 97 % of cv::SIFT's keypoints within 0.5 px, 5 %, 5 degrees;
// the counterparts: eval::siftCounterparts).
constexpr double kMinRecall = 0.97, kMinPrecision = 0.97;
// Descriptors are integer vectors of L2 norm ~512. Matched pairs: the median distance is 0 and
// 99 % are within 2 (an entry off by one from float rounding); none beyond 30.
constexpr double kDescMedian = 0.0, kDescP99 = 2.0, kDescMax = 30.0;
// Regression guard, far inside the bar: the same float expressions as OpenCV's keep matched
// positions within rounding (OpenCV's compiled code contracts some of them into FMAs).
constexpr double kMaxPosDiffPx = 0.01;

void expectEquivalent(const eval::SiftEquivalenceRow& row) {
  const eval::SiftAgreement& g = row.agreement;
  const char* set = row.set.c_str();
  for (const std::string& p : g.problems) ADD_FAILURE() << set << ": " << p;
  EXPECT_GE(g.recall(), kMinRecall) << set;
  EXPECT_GE(g.precision(), kMinPrecision) << set;
  EXPECT_LE(g.descQuantile(0.5), kDescMedian) << set;
  EXPECT_LE(g.descQuantile(0.99), kDescP99) << set;
  EXPECT_LE(g.descQuantile(1.0), kDescMax) << set;
  EXPECT_LE(g.max_pos, kMaxPosDiffPx) << set;
}

}  // namespace

// The sets and their table: eval/sift_equivalence.h, build/bench/bench_sift --equivalence.
TEST(SiftFast, EquivalentToOpenCvOnRenderedScenesTexturesAndPhotos) {
  const std::vector<eval::SiftEquivalenceRow> rows = eval::siftEquivalenceDefaultOptions();
  ASSERT_EQ(rows.size(), 10u);  // scenes, clutter, textures, 6 photos, the photos together
  for (const eval::SiftEquivalenceRow& row : rows) expectEquivalent(row);
}

TEST(SiftFast, EquivalentForOtherOptionsAndSizes) {
  const std::vector<eval::SiftEquivalenceRow> rows = eval::siftEquivalenceOtherOptions();
  ASSERT_EQ(rows.size(), 9u);  // 8 option sets, odd sizes and colour
  for (const eval::SiftEquivalenceRow& row : rows) expectEquivalent(row);
}

TEST(SiftFast, MaxFeaturesKeepsTheSameStrongest) {
  const cv::Mat img = testing::loadMedia("photos/hotel_facade.jpg");
  SiftOptions o;
  o.max_features = 500;
  o.implementation = SiftImplementation::kOpenCV;
  const Features ref = extractSift(img, o);
  o.implementation = SiftImplementation::kFast;
  const Features fast = extractSift(img, o);
  ASSERT_EQ(ref.size(), 500);
  ASSERT_EQ(fast.size(), 500);
  // The same keypoints, in the same order (strongest first).
  int same = 0;
  for (int i = 0; i < 500; ++i)
    same += cv::norm(ref.keypoints[i].pt - fast.keypoints[i].pt) < 0.01 &&
            std::abs(ref.keypoints[i].response - fast.keypoints[i].response) < 1e-6;
  EXPECT_GE(same, 490);
}

// Every kernel table this CPU can run gives the same bits as the scalar one.
TEST(SiftFast, EveryDispatchPathAgrees) {
  SiftOptions opt;
  std::vector<cv::Mat> images = {testing::loadMedia("photos/cookie_box.png"),
                                 testing::clutterBackground(5)(cv::Rect(40, 30, 301, 197)).clone()};
  for (const cv::Mat& img : images) {
    FastSiftCall call;
    call.threads = 1;
    call.isa = SiftIsa::kScalar;
    std::vector<cv::KeyPoint> k0;
    cv::Mat d0;
    fastSiftDetectAndCompute(img, opt, call, &k0, &d0);
    ASSERT_GT(k0.size(), 100u);
    for (SiftIsa isa : {SiftIsa::kAvx2, SiftIsa::kAvx512}) {
      if (!siftIsaSupported(isa)) {
        std::printf("%s: not on this CPU, skipped\n", siftIsaName(isa));
        continue;
      }
      call.isa = isa;
      std::vector<cv::KeyPoint> k;
      cv::Mat d;
      fastSiftDetectAndCompute(img, opt, call, &k, &d);
      ASSERT_EQ(k.size(), k0.size()) << siftIsaName(isa);
      int differ = 0;
      for (size_t i = 0; i < k.size(); ++i)
        differ += !(k[i].pt == k0[i].pt && k[i].size == k0[i].size && k[i].angle == k0[i].angle &&
                    k[i].response == k0[i].response && k[i].octave == k0[i].octave);
      EXPECT_EQ(differ, 0) << siftIsaName(isa);
      EXPECT_EQ(cv::norm(d, d0, cv::NORM_INF), 0.0) << siftIsaName(isa);
      std::printf("%s: %zu keypoints, identical to scalar\n", siftIsaName(isa), k.size());
    }
  }
}

TEST(SiftFast, ThreadsDoNotChangeTheResult) {
  const cv::Mat img = testing::loadMedia("photos/aerial_town.jpg");
  SiftOptions opt;
  FastSiftCall call;
  call.isa = bestSiftIsa();
  std::vector<cv::KeyPoint> k1, k2;
  cv::Mat d1, d2;
  call.threads = 1;
  fastSiftDetectAndCompute(img, opt, call, &k1, &d1);
  call.threads = 0;
  fastSiftDetectAndCompute(img, opt, call, &k2, &d2);
  ASSERT_EQ(k1.size(), k2.size());
  for (size_t i = 0; i < k1.size(); ++i) {
    EXPECT_EQ(k1[i].pt, k2[i].pt);
    EXPECT_EQ(k1[i].angle, k2[i].angle);
  }
  EXPECT_EQ(cv::norm(d1, d2, cv::NORM_INF), 0.0);
}

// The extractor keeps its buffers between calls; nothing of a previous call may leak into the
// next one (a Newton step that jumps far reads a stored layer only where this call has made it).
// The statistics count the interpolation's steps too, so they see a path that a stale value bent
// even when the keypoint was rejected in the end.
TEST(SiftFast, TheResultDoesNotDependOnThePreviousCall) {
  const cv::Mat a = testing::clutterBackground(900);
  const std::vector<cv::Mat> before = {cv::Mat(), testing::clutterBackground(901),
                                       testing::loadMedia("photos/aerial_town.jpg"),
                                       cv::Mat(480, 640, CV_8UC1, cv::Scalar(255))};
  struct Run {
    std::vector<cv::KeyPoint> k;
    cv::Mat d;
    FastSiftStats stats;
  };
  std::vector<Run> runs;
  std::thread([&] {  // a thread of its own: buffers that no other test has touched yet
    SiftOptions opt;
    FastSiftCall call;
    call.isa = bestSiftIsa();
    call.threads = 1;
    for (const cv::Mat& b : before) {
      std::vector<cv::KeyPoint> k;
      cv::Mat d;
      if (!b.empty()) fastSiftDetectAndCompute(b, opt, call, &k, &d);
      Run r;
      call.stats = &r.stats;
      fastSiftDetectAndCompute(a, opt, call, &r.k, &r.d);
      call.stats = nullptr;
      runs.push_back(std::move(r));
    }
  }).join();
  ASSERT_EQ(runs.size(), before.size());
  ASSERT_GT(runs[0].stats.far_steps, 0);  // the case in question occurs on this image
  for (size_t i = 1; i < runs.size(); ++i) {
    EXPECT_EQ(runs[i].stats.candidates, runs[0].stats.candidates) << i;
    EXPECT_EQ(runs[i].stats.far_steps, runs[0].stats.far_steps) << i;
    EXPECT_EQ(runs[i].stats.extrema, runs[0].stats.extrema) << i;
    ASSERT_EQ(runs[i].k.size(), runs[0].k.size()) << i;
    for (size_t q = 0; q < runs[0].k.size(); ++q) {
      EXPECT_EQ(runs[i].k[q].pt, runs[0].k[q].pt);
      EXPECT_EQ(runs[i].k[q].response, runs[0].k[q].response);
    }
    EXPECT_EQ(cv::norm(runs[i].d, runs[0].d, cv::NORM_INF), 0.0) << i;
  }
  std::printf("%d far interpolation steps, %d extrema, %zu keypoints, whatever ran before\n",
              runs[0].stats.far_steps, runs[0].stats.extrema, runs[0].k.size());
}

// A size range prunes octaves before they are computed; what is kept is exactly the unpruned
// result restricted to the range.
TEST(SiftFast, SizeRangePrunesWithoutChangingTheKept) {
  const cv::Mat img = testing::loadMedia("photos/fruits_closeup.jpg");
  SiftOptions opt;
  FastSiftCall call;
  call.isa = bestSiftIsa();
  FastSiftStats full_stats, pruned_stats;
  std::vector<cv::KeyPoint> all, part;
  cv::Mat dall, dpart;
  call.stats = &full_stats;
  fastSiftDetectAndCompute(img, opt, call, &all, &dall);
  call.min_size = 6;
  call.max_size = 20;
  call.stats = &pruned_stats;
  fastSiftDetectAndCompute(img, opt, call, &part, &dpart);
  std::vector<int> expected;
  for (size_t i = 0; i < all.size(); ++i)
    if (all[i].size >= 6 && all[i].size <= 20) expected.push_back(static_cast<int>(i));
  ASSERT_GT(expected.size(), 50u);
  ASSERT_EQ(part.size(), expected.size());
  for (size_t i = 0; i < part.size(); ++i) {
    EXPECT_EQ(part[i].pt, all[expected[i]].pt);
    EXPECT_EQ(part[i].size, all[expected[i]].size);
    EXPECT_EQ(cv::norm(dpart.row(static_cast<int>(i)), dall.row(expected[i]), cv::NORM_INF), 0.0);
  }
  // Sizes 6-20 px live in three octaves; the others are not searched, the top ones not built.
  EXPECT_LT(pruned_stats.octaves_searched, full_stats.octaves_searched);
  EXPECT_LT(pruned_stats.octaves_built, full_stats.octaves_built);
  std::printf("octaves searched %d of %d, built %d of %d\n", pruned_stats.octaves_searched,
              full_stats.octaves_searched, pruned_stats.octaves_built, full_stats.octaves_built);
}

TEST(SiftFast, RegionOfInterestAgreesWithOpenCv) {
  const cv::Mat img = testing::loadMedia("photos/aerial_town.jpg");
  ExtractRegion region;
  region.roi = cv::Rect(200, 150, 240, 180);
  region.min_size_px = 2;
  region.max_size_px = 30;
  SiftOptions o;
  o.implementation = SiftImplementation::kOpenCV;
  const Features ref = extractSift(img, o, region);
  o.implementation = SiftImplementation::kFast;
  const Features fast = extractSift(img, o, region);
  ASSERT_GT(ref.size(), 100);
  const std::vector<int> rf = eval::siftCounterparts(ref, fast), fr = eval::siftCounterparts(fast, ref);
  EXPECT_GE(std::count_if(rf.begin(), rf.end(), [](int j) { return j >= 0; }), ref.size() * 97 / 100);
  EXPECT_GE(std::count_if(fr.begin(), fr.end(), [](int j) { return j >= 0; }), fast.size() * 97 / 100);
}

// A real photograph pair: the cookie box (its own photo as the reference, 20 cm wide) among other
// packets, rotated and tilted. Both extractors find it, at the same place.
TEST(SiftFast, DetectorFindsTheBoxInTheRealPhotoWithBothExtractors) {
  const cv::Mat ref = testing::loadMedia("photos/cookie_box.png");
  const cv::Mat scene = testing::loadMedia("photos/cookie_box_in_scene.png");
  const Intrinsics cam = Intrinsics::pinhole(scene.cols, scene.rows, 500, (scene.cols - 1) / 2.0,
                                             (scene.rows - 1) / 2.0);
  std::array<Eigen::Vector2d, 4> corners[2];
  int inliers[2] = {0, 0};
  for (int k = 0; k < 2; ++k) {
    DetectorOptions opt;
    opt.sift.implementation = k == 0 ? SiftImplementation::kOpenCV : SiftImplementation::kFast;
    Detector det(opt);
    const int id = det.addObject(textureObject("cookie box", ref, 0.2));
    const DetectionResult r = det.detect(scene, cam);
    ASSERT_TRUE(r.ok) << r.error;
    const std::optional<Detection> d = r.find(id);
    ASSERT_TRUE(d.has_value()) << (k == 0 ? "opencv" : "fast");
    corners[k] = d->corners;
    inliers[k] = d->inliers;
  }
  double worst = 0;
  for (int i = 0; i < 4; ++i) worst = std::max(worst, (corners[0][i] - corners[1][i]).norm());
  std::printf("cookie box: %d / %d inliers (cv::SIFT / fast), corners differ by %.3f px at most\n",
              inliers[0], inliers[1], worst);
  EXPECT_LT(worst, 0.5);
  EXPECT_GE(inliers[1], inliers[0] * 9 / 10);
}

TEST(SiftFast, OptionsAndDispatchQueries) {
  SiftOptions o;
  o.threads = -1;
  EXPECT_THROW(o.check(), std::invalid_argument);
  o = {};
  o.implementation = static_cast<SiftImplementation>(7);
  EXPECT_THROW(o.check(), std::invalid_argument);
  EXPECT_TRUE(siftIsaSupported(SiftIsa::kScalar));
  EXPECT_TRUE(siftIsaSupported(bestSiftIsa()));
  std::printf("best kernels on this CPU: %s; default implementation: %s\n", siftIsaName(bestSiftIsa()),
              defaultSiftImplementation() == SiftImplementation::kFast ? "fast" : "opencv");
}

}  // namespace refgrasp::detector
