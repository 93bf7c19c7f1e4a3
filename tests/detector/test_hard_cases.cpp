// Paper matcher vs ratio baseline on the hard cases of Section III-B: small targets, strong motion
// blur, repeated motifs, symmetric patterns, several instances. Each category renders >= 10
// seeded scenes; "found" = the four projected texture corners within 3 px of the truth.
#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <random>
#include <string>

#include "robot/sim/synthetic_scene.h"
#include "detector/homography.h"
#include "detector/matching.h"

namespace refgrasp::detector {
namespace {

using Vec2 = Eigen::Vector2d;
constexpr double kFoundPx = 3.0;
constexpr int kScenes = 10;

struct Tally {
  std::string category;
  int paper = 0, ratio = 0, total = 0;
};

/// Largest corner error of H against the truth, over the allowed corner relabellings
/// (identity only, or the 8 symmetries of a square texture).
double cornerError(const Eigen::Matrix3d& H, const cv::Mat& tex, const std::array<Vec2, 4>& truth,
                   bool square_symmetry) {
  const std::array<Vec2, 4> c = {Vec2(-0.5, -0.5), Vec2(tex.cols - 0.5, -0.5),
                                 Vec2(tex.cols - 0.5, tex.rows - 0.5), Vec2(-0.5, tex.rows - 0.5)};
  double best = 1e18;
  for (int flip = 0; flip < (square_symmetry ? 2 : 1); ++flip) {
    for (int rot = 0; rot < (square_symmetry ? 4 : 1); ++rot) {
      double e = 0;
      for (int i = 0; i < 4; ++i) {
        const int j = flip ? (rot - i + 4) % 4 : (rot + i) % 4;
        e = std::max(e, (applyHomography(H, c[i]) - truth[j]).norm());
      }
      best = std::min(best, e);
    }
  }
  return best;
}

/// Instances (of up to max_instances) within kFoundPx of distinct true targets.
int countFound(const MatchResult& r, const cv::Mat& tex, const std::vector<std::array<Vec2, 4>>& truth,
               bool square_symmetry) {
  std::vector<bool> hit(truth.size(), false);
  int found = 0;
  for (const auto& inst : r.instances)
    for (size_t t = 0; t < truth.size(); ++t)
      if (!hit[t] && cornerError(inst.H, tex, truth[t], square_symmetry) < kFoundPx) {
        hit[t] = true;
        ++found;
        break;
      }
  return found;
}

void runBoth(const cv::Mat& tex, const cv::Mat& image, const std::vector<std::array<Vec2, 4>>& truth,
             int max_instances, bool square_symmetry, Tally* tally) {
  MatchOptions paper, ratio;
  paper.max_instances = ratio.max_instances = max_instances;
  ratio.matcher = MatcherType::kRatio;
  // The reference index does not depend on the matcher type.
  static std::map<const uchar*, ReferenceIndex> cache;
  auto it = cache.find(tex.data);
  if (it == cache.end()) it = cache.emplace(tex.data, buildReferenceIndex(extractSift(tex, SiftOptions{}), {}, paper)).first;
  const Features f = extractSift(image, SiftOptions{});
  const GridIndex grid(f.keypoints, f.image_size);
  tally->paper += countFound(matchObject(it->second, f, grid, paper), tex, truth, square_symmetry);
  tally->ratio += countFound(matchObject(it->second, f, grid, ratio), tex, truth, square_symmetry);
  tally->total += static_cast<int>(truth.size());
}

/// Single-target category: random visible poses in [dmin, dmax] m, tilt <= max_tilt.
Tally singleTarget(const std::string& category, const std::vector<std::string>& textures, double width_m,
                   double dmin, double dmax, double max_tilt_rad, double blur_px, bool square_symmetry,
                   uint64_t seed) {
  Tally t{category};
  const Intrinsics cam = testing::sceneCamera();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> angle(0, M_PI);
  for (int k = 0; k < kScenes; ++k) {
    const cv::Mat tex = testing::loadMedia(textures[k % textures.size()]);
    const double h = width_m * tex.rows / tex.cols;
    testing::SceneSpec spec;
    spec.cMo = testing::randomVisiblePose(rng, cam, width_m, h, dmin, dmax, max_tilt_rad);
    spec.motion_blur_px = blur_px;
    spec.motion_blur_angle_rad = angle(rng);
    spec.seed = seed * 100 + k;
    const auto scene = testing::renderTarget(cam, tex, width_m, h, spec);
    runBoth(tex, scene.image, {scene.corners}, 1, square_symmetry, &t);
  }
  return t;
}

Tally multipleInstances(uint64_t seed) {
  Tally t{"3 instances"};
  const Intrinsics cam = testing::sceneCamera();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  const auto& names = testing::targetTextures();
  for (int k = 0; k < kScenes; ++k) {
    const cv::Mat tex = testing::loadMedia(names[k % names.size()]);
    std::vector<sim::TexturedPlane> planes;
    for (int c = 0; c < 3; ++c) {
      sim::TexturedPlane p;
      p.texture = tex;
      p.width_m = 0.11;
      p.height_m = p.width_m * tex.rows / tex.cols;
      p.cMp = Pose(axisAngle(Eigen::Vector3d(u(rng), u(rng), 0), 0.5 * std::abs(u(rng))) *
                       axisAngle(Eigen::Vector3d::UnitZ(), M_PI * u(rng)),
                   Eigen::Vector3d((c - 1) * 0.17, 0.05 * u(rng), 0.65 + 0.1 * u(rng)));
      planes.push_back(p);
    }
    testing::SceneSpec spec;
    spec.seed = seed * 100 + k;
    spec.motion_blur_px = 1.5;
    spec.motion_blur_angle_rad = M_PI * u(rng);
    const auto scene = testing::renderTargets(cam, planes, spec);
    runBoth(tex, scene.image, scene.all_corners, 3, false, &t);
  }
  return t;
}

TEST(HardCases, PaperMatcherFindsAtLeastAsManyAsRatioBaseline) {
  const auto& targets = testing::targetTextures();
  std::vector<Tally> rows;
  // 20 cm wide target at 1.4-1.8 m: 60-80 px wide in the image.
  rows.push_back(singleTarget("small (60-80 px)", targets, 0.2, 1.4, 1.8, 30 * M_PI / 180, 0, false, 1));
  rows.push_back(singleTarget("motion blur 8 px", targets, 0.2, 0.4, 0.9, 30 * M_PI / 180, 8, false, 2));
  rows.push_back(singleTarget("repeated motif", {"hard/tiled_motif.png"}, 0.2, 0.4, 0.9, 30 * M_PI / 180, 0,
                              false, 3));
  // A pattern with the symmetries of the square is found up to them: corners may be relabelled.
  rows.push_back(singleTarget("symmetric (mod D4)", {"hard/symmetric.png"}, 0.2, 0.4, 0.9, 30 * M_PI / 180, 0,
                              true, 4));
  rows.push_back(multipleInstances(5));

  Tally all{"overall"};
  std::printf("\n%-20s %12s %12s\n", "category", "paper", "ratio");
  for (const auto& r : rows) {
    std::printf("%-20s %8d/%-3d %8d/%-3d\n", r.category.c_str(), r.paper, r.total, r.ratio, r.total);
    all.paper += r.paper;
    all.ratio += r.ratio;
    all.total += r.total;
  }
  std::printf("%-20s %8d/%-3d %8d/%-3d\n\n", all.category.c_str(), all.paper, all.total, all.ratio, all.total);
  for (const auto& r : rows) EXPECT_GE(r.paper, r.ratio) << r.category;
  EXPECT_GT(all.paper, all.ratio);
  EXPECT_GE(rows.back().paper, rows.back().total * 8 / 10) << "most instances found";
}

}  // namespace
}  // namespace refgrasp::detector
