// Matchers on synthetic scenes rendered at known poses: the paper's local-geometric-consistency
// matcher and the ratio baseline. Ground truth: the renderer's texture -> image homography.
#include <gtest/gtest.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <map>
#include <cstdio>
#include <random>
#include <set>

#include <opencv2/imgproc.hpp>

#include "robot/sim/synthetic_scene.h"
#include "detector/homography.h"
#include "detector/matching.h"

namespace refgrasp::detector {
namespace {

using testing::loadMedia;
using testing::sceneCamera;
using Vec2 = Eigen::Vector2d;

/// Outer texture corners in reference (= texture) pixels, TL TR BR BL.
std::array<Vec2, 4> textureCorners(const cv::Mat& tex) {
  return {Vec2(-0.5, -0.5), Vec2(tex.cols - 0.5, -0.5), Vec2(tex.cols - 0.5, tex.rows - 0.5),
          Vec2(-0.5, tex.rows - 0.5)};
}

/// Largest image distance between the corners mapped by H and the true corners.
double cornerError(const Eigen::Matrix3d& H, const cv::Mat& tex, const std::array<Vec2, 4>& truth) {
  const auto c = textureCorners(tex);
  double e = 0;
  for (int i = 0; i < 4; ++i) e = std::max(e, (applyHomography(H, c[i]) - truth[i]).norm());
  return e;
}

ReferenceIndex referenceFor(const cv::Mat& tex, const MatchOptions& opt) {
  return buildReferenceIndex(extractSift(tex, SiftOptions{}), {}, opt);
}

/// tex rendered 0.2 m wide at a random visible pose (depth z0-z1 m, tilt up to max_tilt rad),
/// optionally with motion blur.
testing::RenderedScene renderAtRandom(std::mt19937_64& rng, const Intrinsics& cam, const cv::Mat& tex, double z0,
                                      double z1, double max_tilt, uint64_t seed, double blur_px = 0,
                                      double blur_angle_rad = 0) {
  const double w = 0.2, h = w * tex.rows / tex.cols;
  testing::SceneSpec spec;
  spec.cMo = testing::randomVisiblePose(rng, cam, w, h, z0, z1, max_tilt);
  spec.seed = seed;
  spec.motion_blur_px = blur_px;
  spec.motion_blur_angle_rad = blur_angle_rad;
  return testing::renderTarget(cam, tex, w, h, spec);
}

MatchResult run(const ReferenceIndex& ref, const cv::Mat& image, const MatchOptions& opt) {
  const Features f = extractSift(image, SiftOptions{});
  const GridIndex grid(f.keypoints, f.image_size);
  return matchObject(ref, f, grid, opt);
}

TEST(Matching, NearestTwoIsExact) {
  const cv::Mat tex = loadMedia("targets/book_cover.png");
  const ReferenceIndex ref = referenceFor(tex, MatchOptions{});
  const Features scene = extractSift(testing::clutterBackground(3), SiftOptions{});
  ASSERT_GT(ref.features.size(), 300);
  ASSERT_GT(scene.size(), 300);
  const auto nn = nearestTwo(ref, scene);
  ASSERT_EQ(static_cast<int>(nn.size()), scene.size());
  // Every kernel this CPU has gives the identical answer.
  for (KnnKernel k : {KnnKernel::kScalar, KnnKernel::kAvx2, KnnKernel::kVnni}) {
    if (!knnKernelAvailable(k)) continue;
    const auto other = nearestTwo(ref, scene, k);
    for (int j = 0; j < scene.size(); ++j) {
      ASSERT_EQ(other[j].best, nn[j].best) << "kernel " << static_cast<int>(k) << " feature " << j;
      ASSERT_EQ(other[j].second, nn[j].second);
      ASSERT_EQ(other[j].d1, nn[j].d1);
      ASSERT_EQ(other[j].d2, nn[j].d2);
    }
  }
  for (int j = 0; j < scene.size(); ++j) {
    long d1 = LONG_MAX, d2 = LONG_MAX;
    for (int i = 0; i < ref.features.size(); ++i) {
      const double d = cv::norm(scene.descriptors.row(j), ref.features.descriptors.row(i), cv::NORM_L2SQR);
      const long di = std::lround(d);
      if (di < d1) {
        d2 = d1;
        d1 = di;
      } else if (di < d2) {
        d2 = di;
      }
    }
    ASSERT_EQ(nn[j].d1, d1) << "scene feature " << j;
    ASSERT_EQ(nn[j].d2, d2) << "scene feature " << j;
    const double at_best = cv::norm(scene.descriptors.row(j), ref.features.descriptors.row(nn[j].best), cv::NORM_L2SQR);
    const double at_second = cv::norm(scene.descriptors.row(j), ref.features.descriptors.row(nn[j].second), cv::NORM_L2SQR);
    ASSERT_EQ(std::lround(at_best), d1);
    ASSERT_EQ(std::lround(at_second), d2);
  }
}

TEST(Matching, NearestTwoKernelsAgreeOnTiesAndOddSizes) {
  // Values 0..255 including both ends, few distinct values (many equal distances), reference
  // sizes around the kernels' blocks of 16 and 64 rows, scene sizes not a multiple of 4.
  std::mt19937_64 rng(5);
  int compared = 0;
  for (int nr : {1, 2, 15, 16, 17, 63, 64, 65, 130}) {
    for (int ns : {1, 3, 5, 37}) {
      cv::Mat r(nr, 128, CV_32F), s(ns, 128, CV_32F);
      std::uniform_int_distribution<int> v(0, 3);
      for (cv::Mat* m : {&r, &s})
        for (int i = 0; i < m->rows; ++i)
          for (int k = 0; k < 128; ++k) m->at<float>(i, k) = static_cast<float>(v(rng) * 85);  // 0, 85, 170, 255
      for (int i = 1; i < nr; i += 3) r.row(i - 1).copyTo(r.row(i));  // exact duplicates
      for (int i = 16; i < nr; i += 16) r.row(0).copyTo(r.row(i));     // ... in one lane of 16
      r.row(0).copyTo(s.row(0));                                       // at distance 0
      const IntegerDescriptors ref = integerDescriptors(r, /*byte_split=*/true);
      const IntegerDescriptors scene = integerDescriptors(s, /*byte_split=*/false);
      const auto want = nearestTwo(ref, scene, KnnKernel::kScalar);
      for (int j = 0; j < ns; ++j) {  // the scalar loop against a full sort by (distance, index)
        std::vector<std::pair<long, int>> all;
        for (int i = 0; i < nr; ++i)
          all.emplace_back(static_cast<long>(cv::norm(s.row(j), r.row(i), cv::NORM_L2SQR)), i);
        std::sort(all.begin(), all.end());
        ASSERT_EQ(want[j].best, all[0].second);
        ASSERT_EQ(want[j].d1, all[0].first);
        ASSERT_EQ(want[j].second, nr > 1 ? all[1].second : -1);
        if (nr > 1) {
          ASSERT_EQ(want[j].d2, all[1].first);
        }
      }
      for (KnnKernel k : {KnnKernel::kAvx2, KnnKernel::kVnni, KnnKernel::kAuto}) {
        if (!knnKernelAvailable(k)) continue;
        const auto got = nearestTwo(ref, scene, k);
        for (int j = 0; j < ns; ++j) {
          ASSERT_EQ(got[j].best, want[j].best) << "kernel " << static_cast<int>(k) << " nr " << nr << " ns " << ns;
          ASSERT_EQ(got[j].second, want[j].second) << "kernel " << static_cast<int>(k) << " nr " << nr;
          ASSERT_EQ(got[j].d1, want[j].d1);
          ASSERT_EQ(got[j].d2, want[j].d2);
          ++compared;
        }
      }
    }
  }
  EXPECT_GT(compared, 9 * 46);
}

TEST(Matching, PaperMatcherRecoversHomographyOnRandomPoses) {
  const Intrinsics cam = sceneCamera();
  std::mt19937_64 rng(2024);
  const auto& names = testing::targetTextures();
  MatchOptions opt;
  int n = 0;
  double worst = 0;
  for (const auto& name : names) {
    const cv::Mat tex = loadMedia(name);
    const ReferenceIndex ref = referenceFor(tex, opt);
    for (int k = 0; k < 4; ++k, ++n) {
      const auto scene = renderAtRandom(rng, cam, tex, 0.3, 1.2, 50 * M_PI / 180, 500 + n, k % 2 ? 2.0 : 0.0, 0.3 * k);
      const MatchResult res = run(ref, scene.image, opt);
      ASSERT_EQ(res.instances.size(), 1u) << name << " pose " << k << " z " << scene.cMo.t.z();
      const double e = cornerError(res.instances[0].H, tex, scene.corners);
      EXPECT_LT(e, 2.0) << name << " pose " << k << " z " << scene.cMo.t.z();
      EXPECT_GE(static_cast<int>(res.instances[0].inliers.size()), opt.min_inliers);
      EXPECT_LE(res.hypotheses_evaluated, opt.max_hypotheses);
      worst = std::max(worst, e);
    }
  }
  std::printf("paper matcher: %d random poses, worst corner error %.2f px\n", n, worst);
}

TEST(Matching, RatioMatcherRecoversHomography) {
  const Intrinsics cam = sceneCamera();
  std::mt19937_64 rng(77);
  const cv::Mat tex = loadMedia("targets/cereal_box.png");
  MatchOptions opt;
  opt.matcher = MatcherType::kRatio;
  const ReferenceIndex ref = referenceFor(tex, opt);
  for (int k = 0; k < 4; ++k) {
    testing::SceneSpec spec;
    spec.cMo = testing::randomVisiblePose(rng, cam, 0.2, 0.2, 0.3, 0.8, 40 * M_PI / 180);
    spec.seed = 900 + k;
    const auto scene = testing::renderTarget(cam, tex, 0.2, 0.2, spec);
    const MatchResult res = run(ref, scene.image, opt);
    ASSERT_EQ(res.instances.size(), 1u) << "pose " << k;
    EXPECT_LT(cornerError(res.instances[0].H, tex, scene.corners), 2.0) << "pose " << k;
  }
}

TEST(Matching, MultipleInstancesAreFoundAndDisjoint) {
  const Intrinsics cam = sceneCamera();
  const cv::Mat tex = loadMedia("targets/tea_box.png");
  MatchOptions opt;
  opt.max_instances = 4;
  const ReferenceIndex ref = referenceFor(tex, opt);
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int frame = 0; frame < 3; ++frame) {
    const int copies = 2 + frame % 2;  // 2, 3, 2
    std::vector<sim::TexturedPlane> planes;
    for (int c = 0; c < copies; ++c) {
      sim::TexturedPlane p;
      p.texture = tex;
      p.width_m = p.height_m = 0.12;
      const double x = (c - (copies - 1) / 2.0) * 0.19;
      p.cMp = Pose(axisAngle(Eigen::Vector3d(u(rng), u(rng), 0), 0.35 * std::abs(u(rng))) *
                       axisAngle(Eigen::Vector3d::UnitZ(), 3 * u(rng)),
                   Eigen::Vector3d(x, 0.04 * u(rng), 0.7));
      planes.push_back(p);
    }
    testing::SceneSpec spec;
    spec.seed = 40 + frame;
    const auto scene = testing::renderTargets(cam, planes, spec);
    const MatchResult res = run(ref, scene.image, opt);
    ASSERT_EQ(static_cast<int>(res.instances.size()), copies) << "frame " << frame;
    std::set<int> truth_hit, scene_used;
    for (const auto& inst : res.instances) {
      int best = -1;
      double best_e = 1e9;
      for (int c = 0; c < copies; ++c) {
        const double e = cornerError(inst.H, tex, scene.all_corners[c]);
        if (e < best_e) best_e = e, best = c;
      }
      EXPECT_LT(best_e, 2.0) << "frame " << frame;
      truth_hit.insert(best);
      for (const auto& m : inst.inliers) EXPECT_TRUE(scene_used.insert(m.scene).second) << "shared scene feature";
    }
    EXPECT_EQ(static_cast<int>(truth_hit.size()), copies) << "each copy found once, frame " << frame;
    for (size_t i = 1; i < res.instances.size(); ++i) EXPECT_LE(res.instances[i - 1].score, res.instances[i].score);
  }
}

TEST(Matching, NothingOnClutterAlone) {
  const cv::Mat tex = loadMedia("targets/magazine.png");
  for (MatcherType type : {MatcherType::kPaper, MatcherType::kRatio}) {
    MatchOptions opt;
    opt.matcher = type;
    opt.max_instances = 3;
    const ReferenceIndex ref = referenceFor(tex, opt);
    for (uint64_t seed = 0; seed < 6; ++seed) {
      const MatchResult res = run(ref, testing::clutterBackground(7000 + seed), opt);
      EXPECT_TRUE(res.instances.empty()) << "seed " << seed << " matcher " << static_cast<int>(type);
    }
  }
}

TEST(Matching, SharedFragmentIsNotTheObject) {
  // A 70x70 px piece of the target (4% of it) pasted at its native scale into clutter: a real
  // local match, but not the object. Rejected by the inlier-spread rule, accepted without it.
  const cv::Mat tex = loadMedia("targets/magazine.png");
  cv::Mat img = testing::clutterBackground(11);
  tex(cv::Rect(150, 100, 70, 70)).copyTo(img(cv::Rect(300, 200, 70, 70)));
  MatchOptions opt;
  const ReferenceIndex ref = referenceFor(tex, opt);
  EXPECT_TRUE(run(ref, img, opt).instances.empty());
  opt.min_inlier_spread = 0;
  const MatchResult loose = run(ref, img, opt);
  ASSERT_EQ(loose.instances.size(), 1u);
  // The fragment is where it was pasted: texture (150,100) -> image (300,200).
  EXPECT_LT((applyHomography(loose.instances[0].H, Vec2(185, 135)) - Vec2(335, 235)).norm(), 1.0);
}

TEST(Matching, DeterministicForTheSameInput) {
  const Intrinsics cam = sceneCamera();
  const cv::Mat tex = loadMedia("targets/poster_concert.png");
  std::mt19937_64 rng(5);
  testing::SceneSpec spec;
  spec.cMo = testing::randomVisiblePose(rng, cam, 0.2, 0.15, 0.5, 0.9, 0.6);
  const auto scene = testing::renderTarget(cam, tex, 0.2, 0.15, spec);
  const MatchOptions opt;
  const ReferenceIndex ref = referenceFor(tex, opt);
  const MatchResult a = run(ref, scene.image, opt), b = run(ref, scene.image, opt);
  ASSERT_EQ(a.instances.size(), 1u);
  ASSERT_EQ(b.instances.size(), 1u);
  EXPECT_EQ((a.instances[0].H - b.instances[0].H).norm(), 0.0);
  EXPECT_EQ(a.instances[0].inliers.size(), b.instances[0].inliers.size());
  EXPECT_EQ(a.hypotheses_evaluated, b.hypotheses_evaluated);
}

TEST(Matching, ReferenceIndexCapKeepsEveryOctave) {
  const cv::Mat tex = loadMedia("targets/cereal_box.png");
  const Features f = extractSift(tex, SiftOptions{});
  MatchOptions opt;
  opt.max_reference_features = 150;
  const std::vector<Vec2> left_half = {Vec2(0, 0), Vec2(200, 0), Vec2(200, 399), Vec2(0, 399)};
  const ReferenceIndex ri = buildReferenceIndex(f, left_half, opt);
  ASSERT_EQ(ri.features.size(), 150);
  EXPECT_EQ(ri.features.descriptors.rows, 150);
  for (const auto& k : ri.features.keypoints) EXPECT_LE(k.pt.x, 200.f);
  for (int i = 1; i < ri.features.size(); ++i)
    EXPECT_GE(ri.features.keypoints[i - 1].response, ri.features.keypoints[i].response);
  // Round robin over octaves: every octave present inside the polygon keeps its strongest
  // features, including the coarse ones a response-only cap would drop.
  auto octave = [](const cv::KeyPoint& k) { return static_cast<int>(std::floor(std::log2(k.size))); };
  std::map<int, std::vector<float>> inside, kept;
  for (const auto& k : f.keypoints)
    if (k.pt.x <= 200) inside[octave(k)].push_back(k.response);
  for (const auto& k : ri.features.keypoints) kept[octave(k)].push_back(k.response);
  ASSERT_EQ(kept.size(), inside.size());
  for (auto& [oct, responses] : inside) {
    std::sort(responses.rbegin(), responses.rend());
    const auto& k = kept[oct];
    ASSERT_FALSE(k.empty()) << "octave " << oct;
    for (size_t i = 0; i < k.size(); ++i) EXPECT_EQ(k[i], responses[i]) << "octave " << oct;
  }
  EXPECT_NEAR(ri.centre_px.x(), 100, 1e-9);
  EXPECT_NEAR(ri.centre_px.y(), 199.5, 1e-9);
  EXPECT_THROW(buildReferenceIndex(f, {Vec2(0, 0), Vec2(1, 1)}, opt), std::invalid_argument);
  EXPECT_THROW(buildReferenceIndex(f, {Vec2(0, 0), Vec2(1, 1), Vec2(2, 2)}, opt), std::invalid_argument);
  EXPECT_THROW(buildReferenceIndex(f, {Vec2(0, 0), Vec2(std::nan(""), 1), Vec2(0, 9)}, opt), std::invalid_argument);
}

TEST(Matching, OptionsCheckRejectsNonsense) {
  EXPECT_NO_THROW(MatchOptions{}.check());
  auto bad = [](auto mutate) {
    MatchOptions o;
    mutate(o);
    EXPECT_THROW(o.check(), std::invalid_argument);
  };
  bad([](MatchOptions& o) { o.global_ratio = 0; });
  bad([](MatchOptions& o) { o.global_ratio = 1.5; });
  bad([](MatchOptions& o) { o.local_ratio = -0.1; });
  bad([](MatchOptions& o) { o.search_radius_factor = 0; });
  bad([](MatchOptions& o) { o.orientation_tolerance_rad = 4; });
  bad([](MatchOptions& o) { o.scale_tolerance = 1; });
  bad([](MatchOptions& o) { o.max_hypotheses = 0; });
  bad([](MatchOptions& o) { o.max_reference_features = 3; });
  bad([](MatchOptions& o) { o.min_inliers = 3; });
  bad([](MatchOptions& o) { o.ransac_reproj_px = std::nan(""); });
  bad([](MatchOptions& o) { o.max_instances = 0; });
  bad([](MatchOptions& o) { o.max_descriptor_distance = -1; });
  bad([](MatchOptions& o) { o.min_inlier_spread = 1; });
  bad([](MatchOptions& o) { o.affine_below_px = -1; });
  bad([](MatchOptions& o) { o.affine_below_px = NAN; });
  // matchObject checks its options too, and tolerates empty inputs.
  MatchOptions o;
  const ReferenceIndex empty = buildReferenceIndex(Features{}, {Vec2(0, 0), Vec2(9, 0), Vec2(0, 9)}, o);
  const Features none;
  EXPECT_TRUE(matchObject(empty, none, GridIndex(), o).instances.empty());
  o.min_inliers = 0;
  EXPECT_THROW(matchObject(empty, none, GridIndex(), o), std::invalid_argument);
}

// matchUnderHomography (the detector's photometric re-alignment matches the features again
// under a precise alignment found otherwise): from the true homography moved by 1 px it recovers
// the instance (corners within 2 px, as many inliers as the seeded search within 20 %); from an
// alignment a third of the pattern away, on clutter alone, or from nonsense it gives nothing.
TEST(Matching, MatchUnderAGivenHomographyRecoversTheInstanceOnlyWhereItIs) {
  const Intrinsics cam = sceneCamera();
  std::mt19937_64 rng(77);
  MatchOptions opt;
  int n = 0;
  for (const char* name : {"targets/poster_concert.png", "targets/book_cover.png", "targets/tea_box.png"}) {
    const cv::Mat tex = loadMedia(name);
    const ReferenceIndex ref = referenceFor(tex, opt);
    for (int k = 0; k < 3; ++k, ++n) {
      const auto scene = renderAtRandom(rng, cam, tex, 0.4, 1.0, 40 * M_PI / 180, 900 + n);
      const Features f = extractSift(scene.image, SiftOptions{});
      const GridIndex grid(f.keypoints, f.image_size);
      const auto c = textureCorners(tex);
      const Eigen::Matrix3d truth = fitHomographyLeastSquares(std::vector<Vec2>(c.begin(), c.end()),
                                                              std::vector<Vec2>(scene.corners.begin(), scene.corners.end()));
      const MatchResult seeded = matchObject(ref, f, grid, opt);
      ASSERT_EQ(seeded.instances.size(), 1u) << name << " " << k;
      // Moved by 1 px in the scene.
      Eigen::Matrix3d move = Eigen::Matrix3d::Identity();
      move(0, 2) = std::cos(k);
      move(1, 2) = std::sin(k);
      const auto near = matchUnderHomography(ref, f, grid, opt, move * truth);
      ASSERT_TRUE(near.has_value()) << name << " " << k;
      EXPECT_LT(cornerError(near->H, tex, scene.corners), 2.0) << name << " " << k;
      EXPECT_GE(near->inliers.size(), 0.8 * seeded.instances[0].inliers.size()) << name << " " << k;
      EXPECT_LE(near->log10_nfa, opt.max_log10_nfa);
      // A third of the pattern's diagonal away: the features do not support an instance there.
      const double diag = (scene.corners[2] - scene.corners[0]).norm();
      Eigen::Matrix3d away = Eigen::Matrix3d::Identity();
      away(0, 2) = diag / 3;
      EXPECT_FALSE(matchUnderHomography(ref, f, grid, opt, away * truth).has_value()) << name << " " << k;
    }
    const cv::Mat clutter = testing::clutterBackground(7100);
    const Features fc = extractSift(clutter, SiftOptions{});
    const GridIndex gc(fc.keypoints, fc.image_size);
    Eigen::Matrix3d H = Eigen::Matrix3d::Identity();
    H(0, 0) = H(1, 1) = 0.4;
    H(0, 2) = 200;
    H(1, 2) = 150;
    EXPECT_FALSE(matchUnderHomography(ref, fc, gc, opt, H).has_value()) << name;
    EXPECT_FALSE(matchUnderHomography(ref, fc, gc, opt, Eigen::Matrix3d::Constant(NAN)).has_value());
    EXPECT_FALSE(matchUnderHomography(ref, Features{}, GridIndex(), opt, H).has_value());
  }
}

// repeatPeriods: a motif tiled with a period of 48 px gives +-(48, 0) and +-(0, 48) among its
// strongest periods (the reference of a 2D-only object is its own rectified plane); a photograph
// without repeats (fruits) gives none.
TEST(Matching, RepeatPeriodsFindATiledMotifsSpacingAndNothingInAPhoto) {
  cv::Mat tile(48, 48, CV_8UC1);
  cv::RNG rng(3);
  rng.fill(tile, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(tile, tile, cv::Size(0, 0), 2.0);
  cv::normalize(tile, tile, 0, 255, cv::NORM_MINMAX);
  cv::Mat tiled;
  cv::repeat(tile, 4, 6, tiled);
  const MatchOptions opt;
  const std::vector<Vec2> periods = repeatPeriods(referenceFor(tiled, opt));
  ASSERT_GE(periods.size(), 4u);
  auto has = [&](const Vec2& v) {
    for (const Vec2& p : periods)
      if ((p - v).norm() <= 3) return true;
    return false;
  };
  int found = 0;
  for (const Vec2& v : {Vec2(48, 0), Vec2(-48, 0), Vec2(0, 48), Vec2(0, -48)}) found += has(v);
  EXPECT_EQ(found, 4);
  EXPECT_TRUE(repeatPeriods(referenceFor(loadMedia("photos/fruits_closeup.jpg"), opt)).empty());
  EXPECT_TRUE(repeatPeriods(ReferenceIndex{}).empty());
}

}  // namespace
}  // namespace refgrasp::detector
