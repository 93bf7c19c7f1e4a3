#include "eval/sift_equivalence.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>

#include "robot/sim/synthetic_scene.h"

namespace refgrasp::eval {

namespace {

using detector::Features;
using detector::SiftImplementation;
using detector::SiftOptions;

// A counterpart: within 0.5 px, 5 % in size, 5 degrees.
constexpr double kPosPx = 0.5, kSizeFrac = 0.05, kAngleDeg = 5;

double angleDiff(float a, float b) {
  const double d = std::abs(a - b);
  return std::min(d, 360 - d);
}

const std::vector<std::string>& photos() {
  static const std::vector<std::string> p = {"photos/cookie_box.png",        "photos/cookie_box_in_scene.png",
                                             "photos/fruits_closeup.jpg",    "photos/hotel_facade.jpg",
                                             "photos/butterfly_on_leaf.jpg", "photos/aerial_town.jpg"};
  return p;
}

}  // namespace

std::vector<int> siftCounterparts(const Features& a, const Features& b) {
  std::vector<int> idx(static_cast<size_t>(b.size()));
  for (int j = 0; j < b.size(); ++j) idx[static_cast<size_t>(j)] = j;
  std::sort(idx.begin(), idx.end(), [&](int p, int q) { return b.keypoints[p].pt.x < b.keypoints[q].pt.x; });
  std::vector<int> out(static_cast<size_t>(a.size()), -1);
  for (int i = 0; i < a.size(); ++i) {
    const cv::KeyPoint& ka = a.keypoints[i];
    auto lo = std::lower_bound(idx.begin(), idx.end(), ka.pt.x - kPosPx,
                               [&](int j, float x) { return b.keypoints[j].pt.x < x; });
    double best = 1e9;
    for (auto it = lo; it != idx.end() && b.keypoints[*it].pt.x <= ka.pt.x + kPosPx; ++it) {
      const cv::KeyPoint& kb = b.keypoints[*it];
      const double d = cv::norm(ka.pt - kb.pt);
      if (d > kPosPx || std::abs(kb.size - ka.size) > kSizeFrac * ka.size || angleDiff(ka.angle, kb.angle) > kAngleDeg)
        continue;
      const double score = d + 0.01 * angleDiff(ka.angle, kb.angle);
      if (score < best) {
        best = score;
        out[static_cast<size_t>(i)] = *it;
      }
    }
  }
  return out;
}

void SiftAgreement::add(const SiftAgreement& o) {
  reference += o.reference;
  fast += o.fast;
  recalled += o.recalled;
  precise += o.precise;
  identical += o.identical;
  desc.insert(desc.end(), o.desc.begin(), o.desc.end());
  max_pos = std::max(max_pos, o.max_pos);
  problems.insert(problems.end(), o.problems.begin(), o.problems.end());
}

double SiftAgreement::descQuantile(double q) const {
  if (desc.empty()) return 0;
  std::vector<double> d = desc;
  std::sort(d.begin(), d.end());
  return d[std::min(d.size() - 1, static_cast<size_t>(q * static_cast<double>(d.size() - 1) + 0.5))];
}

SiftAgreement compareSift(const cv::Mat& img, SiftOptions opt) {
  opt.implementation = SiftImplementation::kOpenCV;
  const Features ref = extractSift(img, opt);
  opt.implementation = SiftImplementation::kFast;
  const Features fast = extractSift(img, opt);
  SiftAgreement g;
  if (fast.descriptors.type() != CV_32F) g.problems.push_back("fast descriptors are not CV_32F");
  if (fast.descriptors.rows != fast.size())
    g.problems.push_back("fast descriptors: " + std::to_string(fast.descriptors.rows) + " rows for " +
                         std::to_string(fast.size()) + " keypoints");
  g.reference = ref.size();
  g.fast = fast.size();
  const std::vector<int> rf = siftCounterparts(ref, fast), fr = siftCounterparts(fast, ref);
  for (int i = 0; i < ref.size(); ++i) {
    const int j = rf[static_cast<size_t>(i)];
    if (j < 0) continue;
    ++g.recalled;
    const cv::KeyPoint &a = ref.keypoints[i], &b = fast.keypoints[j];
    g.max_pos = std::max(g.max_pos, static_cast<double>(cv::norm(a.pt - b.pt)));
    if (a.pt == b.pt && a.size == b.size && a.angle == b.angle && a.response == b.response) ++g.identical;
    g.desc.push_back(cv::norm(ref.descriptors.row(i), fast.descriptors.row(j), cv::NORM_L2));
  }
  for (int j : fr) g.precise += j >= 0;
  if (fast.descriptors.type() == CV_32F) {
    for (int r = 0; r < fast.descriptors.rows && g.problems.empty(); ++r)
      for (int c = 0; c < fast.descriptors.cols; ++c) {
        const float v = fast.descriptors.at<float>(r, c);
        if (!(v >= 0 && v <= 255 && v == std::floor(v))) {
          g.problems.push_back("descriptor " + std::to_string(r) + "," + std::to_string(c) + " = " + std::to_string(v));
          break;
        }
      }
  }
  return g;
}

std::vector<SiftEquivalenceRow> siftEquivalenceDefaultOptions() {
  std::vector<SiftEquivalenceRow> rows;
  // Rendered 640x480 scenes: each target at 4 seeded poses, as in the detector tests.
  const Intrinsics cam = testing::sceneCamera();
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> blur(0.0, 1.5), angle(0, M_PI);
  SiftAgreement scenes;
  uint64_t k = 0;
  for (const std::string& t : testing::targetTextures()) {
    const cv::Mat tex = testing::loadMedia(t);
    for (int i = 0; i < 4; ++i, ++k) {
      testing::SceneSpec spec;
      spec.cMo = testing::randomVisiblePose(rng, cam, 0.2, 0.2 * tex.rows / tex.cols, 0.3, 1.2, 50 * M_PI / 180);
      spec.motion_blur_px = blur(rng);
      spec.motion_blur_angle_rad = angle(rng);
      spec.seed = 700 + k;
      scenes.add(compareSift(testing::renderTarget(cam, tex, 0.2, 0.2 * tex.rows / tex.cols, spec).image, {}));
    }
  }
  rows.push_back({"rendered scenes (20)", scenes});
  SiftAgreement clutter;
  for (uint64_t i = 0; i < 4; ++i) clutter.add(compareSift(testing::clutterBackground(900 + i), {}));
  rows.push_back({"clutter only (4)", clutter});
  SiftAgreement textures;
  for (const std::string& t : testing::targetTextures()) textures.add(compareSift(testing::loadMedia(t), {}));
  for (const char* t : {"hard/tiled_motif.png", "hard/symmetric.png", "hard/low_texture.png", "boxes/box_side_a.png",
                        "backgrounds/wall.png"})
    textures.add(compareSift(testing::loadMedia(t), {}));
  rows.push_back({"textures (10)", textures});
  SiftAgreement all_photos;
  for (const std::string& p : photos()) {
    rows.push_back({p, compareSift(testing::loadMedia(p), {})});
    all_photos.add(rows.back().agreement);
  }
  rows.push_back({"photos (6)", all_photos});
  return rows;
}

std::vector<SiftEquivalenceRow> siftEquivalenceOtherOptions() {
  const cv::Mat photo = testing::loadMedia("photos/cookie_box_in_scene.png");
  const cv::Mat scene = testing::clutterBackground(77);
  std::vector<SiftEquivalenceRow> rows;
  auto add = [&](const char* name, auto edit) {
    SiftOptions o;
    edit(o);
    SiftAgreement g = compareSift(photo, o);
    g.add(compareSift(scene, o));
    rows.push_back({name, g});
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
  // Odd and small sizes, a colour image.
  SiftAgreement sizes;
  for (const cv::Rect r : {cv::Rect(3, 5, 333, 211), cv::Rect(100, 50, 97, 61), cv::Rect(0, 0, 41, 29),
                           cv::Rect(17, 0, 160, 480)})
    sizes.add(compareSift(scene(r).clone(), {}));
  cv::Mat colour;
  cv::cvtColor(scene, colour, cv::COLOR_GRAY2BGR);
  sizes.add(compareSift(colour, {}));
  rows.push_back({"odd sizes, colour (5)", sizes});
  return rows;
}

}  // namespace refgrasp::eval
