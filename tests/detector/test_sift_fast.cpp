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

namespace refgrasp::detector {
namespace {

// Equivalence bars (the issue's: >= 97 % of cv::SIFT's keypoints within 0.5 px, 5 %, 5 degrees).
constexpr double kMinRecall = 0.97, kMinPrecision = 0.97;
constexpr double kPosPx = 0.5, kSizeFrac = 0.05, kAngleDeg = 5;
// Descriptors are integer vectors of L2 norm ~512. Matched pairs: the median distance is 0 and
// 99 % are within 2 (an entry off by one from float rounding); none beyond 30.
constexpr double kDescMedian = 0.0, kDescP99 = 2.0, kDescMax = 30.0;
// Regression guard, far inside the bar: the same float expressions as OpenCV's keep matched
// positions within rounding (OpenCV's compiled code contracts some of them into FMAs).
constexpr double kMaxPosDiffPx = 0.01;

struct Agreement {
  int reference = 0, fast = 0;  ///< keypoint counts
  int recalled = 0;             ///< reference keypoints with a fast counterpart
  int precise = 0;              ///< fast keypoints with a reference counterpart
  int identical = 0;            ///< counterparts equal in position, size, angle, response (float ==)
  std::vector<double> desc;     ///< descriptor L2 distance of each recalled keypoint
  double max_pos = 0;
  void add(const Agreement& o) {
    reference += o.reference;
    fast += o.fast;
    recalled += o.recalled;
    precise += o.precise;
    identical += o.identical;
    desc.insert(desc.end(), o.desc.begin(), o.desc.end());
    max_pos = std::max(max_pos, o.max_pos);
  }
  double recall() const { return reference ? static_cast<double>(recalled) / reference : 1; }
  double precision() const { return fast ? static_cast<double>(precise) / fast : 1; }
  double descQuantile(double q) const {
    if (desc.empty()) return 0;
    std::vector<double> d = desc;
    std::sort(d.begin(), d.end());
    return d[std::min(d.size() - 1, static_cast<size_t>(q * (d.size() - 1) + 0.5))];
  }
};

double angleDiff(float a, float b) {
  const double d = std::abs(a - b);
  return std::min(d, 360 - d);
}

/// The counterpart of each keypoint of `a` in `b` (-1 when none): nearest in position among the
/// keypoints within the bars.
std::vector<int> counterparts(const Features& a, const Features& b) {
  std::vector<int> idx(b.size());
  for (int j = 0; j < b.size(); ++j) idx[j] = j;
  std::sort(idx.begin(), idx.end(), [&](int p, int q) { return b.keypoints[p].pt.x < b.keypoints[q].pt.x; });
  std::vector<int> out(a.size(), -1);
  for (int i = 0; i < a.size(); ++i) {
    const cv::KeyPoint& ka = a.keypoints[i];
    auto lo = std::lower_bound(idx.begin(), idx.end(), ka.pt.x - kPosPx,
                               [&](int j, float x) { return b.keypoints[j].pt.x < x; });
    double best = 1e9;
    for (auto it = lo; it != idx.end() && b.keypoints[*it].pt.x <= ka.pt.x + kPosPx; ++it) {
      const cv::KeyPoint& kb = b.keypoints[*it];
      const double d = cv::norm(ka.pt - kb.pt);
      if (d > kPosPx || std::abs(kb.size - ka.size) > kSizeFrac * ka.size ||
          angleDiff(ka.angle, kb.angle) > kAngleDeg)
        continue;
      const double score = d + 0.01 * angleDiff(ka.angle, kb.angle);
      if (score < best) {
        best = score;
        out[i] = *it;
      }
    }
  }
  return out;
}

Agreement compare(const cv::Mat& img, SiftOptions opt) {
  opt.implementation = SiftImplementation::kOpenCV;
  const Features ref = extractSift(img, opt);
  opt.implementation = SiftImplementation::kFast;
  const Features fast = extractSift(img, opt);
  EXPECT_EQ(fast.descriptors.type(), CV_32F);
  EXPECT_EQ(fast.descriptors.rows, fast.size());
  Agreement g;
  g.reference = ref.size();
  g.fast = fast.size();
  const std::vector<int> rf = counterparts(ref, fast), fr = counterparts(fast, ref);
  for (int i = 0; i < ref.size(); ++i) {
    if (rf[i] < 0) continue;
    ++g.recalled;
    const cv::KeyPoint &a = ref.keypoints[i], &b = fast.keypoints[rf[i]];
    g.max_pos = std::max(g.max_pos, static_cast<double>(cv::norm(a.pt - b.pt)));
    if (a.pt == b.pt && a.size == b.size && a.angle == b.angle && a.response == b.response) ++g.identical;
    g.desc.push_back(cv::norm(ref.descriptors.row(i), fast.descriptors.row(rf[i]), cv::NORM_L2));
  }
  for (int j = 0; j < fast.size(); ++j) g.precise += fr[j] >= 0;
  // The matcher relies on integer descriptors in 0..255.
  for (int r = 0; r < fast.descriptors.rows; ++r)
    for (int c = 0; c < 128; ++c) {
      const float v = fast.descriptors.at<float>(r, c);
      if (!(v >= 0 && v <= 255 && v == std::floor(v))) {
        ADD_FAILURE() << "descriptor " << r << "," << c << " = " << v;
        return g;
      }
    }
  return g;
}

void report(const char* set, const Agreement& g) {
  std::printf("| %-32s | %6d | %6d | %6.2f%% | %6.2f%% | %6.2f%% | %5.2g | %4.1f | %4.1f | %5.1f |\n", set,
              g.reference, g.fast, 100 * g.recall(), 100 * g.precision(),
              g.recalled ? 100.0 * g.identical / g.recalled : 0.0, g.max_pos, g.descQuantile(0.5),
              g.descQuantile(0.99), g.descQuantile(1.0));
}

void expectEquivalent(const char* set, const Agreement& g) {
  report(set, g);
  EXPECT_GE(g.recall(), kMinRecall) << set;
  EXPECT_GE(g.precision(), kMinPrecision) << set;
  EXPECT_LE(g.descQuantile(0.5), kDescMedian) << set;
  EXPECT_LE(g.descQuantile(0.99), kDescP99) << set;
  EXPECT_LE(g.descQuantile(1.0), kDescMax) << set;
  EXPECT_LE(g.max_pos, kMaxPosDiffPx) << set;
}

void printHeader() {
  std::printf("| %-32s | %6s | %6s | %7s | %7s | %7s | %5s | %4s | %4s | %5s |\n", "set", "cv", "fast",
              "recall", "precis.", "same", "dpos", "dmed", "d99", "dmax");
}

const std::vector<std::string>& photos() {
  static const std::vector<std::string> p = {"photos/cookie_box.png",        "photos/cookie_box_in_scene.png",
                                             "photos/fruits_closeup.jpg",    "photos/hotel_facade.jpg",
                                             "photos/butterfly_on_leaf.jpg", "photos/aerial_town.jpg"};
  return p;
}

}  // namespace

TEST(SiftFast, EquivalentToOpenCvOnRenderedScenesTexturesAndPhotos) {
  printHeader();
  // Rendered 640x480 scenes: each target at 4 seeded poses (0.3-1.2 m, tilt <= 50 deg), clutter,
  // noise 2, motion blur up to 1.5 px, as in the detector tests.
  const Intrinsics cam = testing::sceneCamera();
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> blur(0.0, 1.5), angle(0, M_PI);
  Agreement scenes;
  int k = 0;
  for (const std::string& t : testing::targetTextures()) {
    const cv::Mat tex = testing::loadMedia(t);
    for (int i = 0; i < 4; ++i, ++k) {
      testing::SceneSpec spec;
      spec.cMo = testing::randomVisiblePose(rng, cam, 0.2, 0.2 * tex.rows / tex.cols, 0.3, 1.2, 50 * M_PI / 180);
      spec.motion_blur_px = blur(rng);
      spec.motion_blur_angle_rad = angle(rng);
      spec.seed = 700 + k;
      scenes.add(compare(testing::renderTarget(cam, tex, 0.2, 0.2 * tex.rows / tex.cols, spec).image, {}));
    }
  }
  expectEquivalent("rendered scenes (20)", scenes);
  Agreement clutter;
  for (int i = 0; i < 4; ++i) clutter.add(compare(testing::clutterBackground(900 + i), {}));
  expectEquivalent("clutter only (4)", clutter);
  Agreement textures;
  for (const std::string& t : testing::targetTextures()) textures.add(compare(testing::loadMedia(t), {}));
  for (const char* t : {"hard/tiled_motif.png", "hard/symmetric.png", "hard/low_texture.png",
                        "boxes/box_side_a.png", "backgrounds/wall.png"})
    textures.add(compare(testing::loadMedia(t), {}));
  expectEquivalent("textures (10)", textures);
  Agreement all_photos;
  for (const std::string& p : photos()) {
    const Agreement g = compare(testing::loadMedia(p), {});
    expectEquivalent(p.c_str(), g);
    all_photos.add(g);
  }
  expectEquivalent("photos (6)", all_photos);
}

TEST(SiftFast, EquivalentForOtherOptionsAndSizes) {
  printHeader();
  const cv::Mat photo = testing::loadMedia("photos/cookie_box_in_scene.png");
  const cv::Mat scene = testing::clutterBackground(77);
  struct Variant {
    const char* name;
    SiftOptions opt;
  };
  std::vector<Variant> variants;
  auto add = [&](const char* name, auto edit) {
    SiftOptions o;
    edit(o);
    variants.push_back({name, o});
  };
  add("no up-sampling", [](SiftOptions& o) { o.upsample = false; });
  add("octave_layers 2", [](SiftOptions& o) { o.octave_layers = 2; });
  add("octave_layers 5", [](SiftOptions& o) { o.octave_layers = 5; });
  add("sigma 1.2", [](SiftOptions& o) { o.sigma = 1.2; });
  add("sigma 2.0", [](SiftOptions& o) { o.sigma = 2.0; });
  add("contrast 0.02", [](SiftOptions& o) { o.contrast_threshold = 0.02; });
  add("contrast 0.08, edge 5", [](SiftOptions& o) {
    o.contrast_threshold = 0.08;
    o.edge_threshold = 5;
  });
  add("max_features 300", [](SiftOptions& o) { o.max_features = 300; });
  for (const Variant& v : variants) {
    Agreement g = compare(photo, v.opt);
    g.add(compare(scene, v.opt));
    expectEquivalent(v.name, g);
  }
  // Odd and small sizes, a colour image.
  Agreement sizes;
  for (const cv::Rect r : {cv::Rect(3, 5, 333, 211), cv::Rect(100, 50, 97, 61), cv::Rect(0, 0, 41, 29),
                           cv::Rect(17, 0, 160, 480)})
    sizes.add(compare(scene(r).clone(), {}));
  cv::Mat colour;
  cv::cvtColor(scene, colour, cv::COLOR_GRAY2BGR);
  sizes.add(compare(colour, {}));
  expectEquivalent("odd sizes, colour (5)", sizes);
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
  const std::vector<int> rf = counterparts(ref, fast), fr = counterparts(fast, ref);
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
