// SIFT extraction (determinism, pixel convention) and the grid index.
#include <gtest/gtest.h>

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <random>

#include "detector/features.h"

namespace refgrasp::detector {
namespace {

/// A textured test image drawn here (blobs, boxes, lines), smoothed like a real photograph.
cv::Mat drawnTexture(uint64_t seed, int w, int h) {
  cv::RNG rng(seed);
  cv::Mat m(h, w, CV_8U, cv::Scalar(128));
  for (int i = 0; i < 250; ++i) {
    cv::circle(m, {rng.uniform(0, w), rng.uniform(0, h)}, rng.uniform(2, 25),
               cv::Scalar(rng.uniform(0, 256)), rng.uniform(-1, 3), cv::LINE_AA);
    cv::rectangle(m, cv::Rect(rng.uniform(0, w), rng.uniform(0, h), rng.uniform(3, 30), rng.uniform(3, 30)),
                  cv::Scalar(rng.uniform(0, 256)), -1);
  }
  cv::GaussianBlur(m, m, cv::Size(0, 0), 1.0);
  return m;
}

TEST(Features, ExtractionIsDeterministicAndSorted) {
  const cv::Mat img = drawnTexture(1, 320, 240);
  const Features a = extractSift(img, SiftOptions{}), b = extractSift(img, SiftOptions{});
  ASSERT_GT(a.size(), 200);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a.descriptors.type(), CV_32F);
  EXPECT_EQ(a.descriptors.cols, 128);
  EXPECT_EQ(a.image_size, img.size());
  for (int i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a.keypoints[i].pt, b.keypoints[i].pt);
    if (i > 0) {
      EXPECT_GE(a.keypoints[i - 1].response, a.keypoints[i].response);
    }
  }
  EXPECT_EQ(cv::norm(a.descriptors, b.descriptors, cv::NORM_INF), 0.0);
}

TEST(Features, MaxFeaturesKeepsTheStrongest) {
  const cv::Mat img = drawnTexture(2, 320, 240);
  const Features all = extractSift(img, SiftOptions{});
  SiftOptions o;
  o.max_features = 100;
  const Features some = extractSift(img, o);
  ASSERT_EQ(some.size(), 100);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(some.keypoints[i].response, all.keypoints[i].response);
}

/// Median over keypoints of a that have a partner in b at the mapped position and same size,
/// of (residual of) the mapping check f(ka, kb).
template <class Map>
std::vector<double> pairedResiduals(const Features& a, const Features& b, Map map, double gate_px) {
  std::vector<double> r;
  for (const auto& ka : a.keypoints) {
    const cv::Point2f p = map(ka.pt);
    double best = gate_px;
    for (const auto& kb : b.keypoints) {
      if (std::abs(kb.size - ka.size) > 0.05 * ka.size) continue;
      best = std::min<double>(best, cv::norm(kb.pt - p));
    }
    if (best < gate_px) r.push_back(best);
  }
  std::sort(r.begin(), r.end());
  return r;
}

TEST(Features, KeypointsShiftWithTheImage) {
  // An integer shift of the texture moves every keypoint by exactly that shift.
  const cv::Mat big = drawnTexture(3, 400, 300);
  const cv::Mat a = big(cv::Rect(0, 0, 320, 240)).clone(), b = big(cv::Rect(17, 9, 320, 240)).clone();
  const Features fa = extractSift(a, SiftOptions{}), fb = extractSift(b, SiftOptions{});
  auto r = pairedResiduals(fa, fb, [](cv::Point2f p) { return p - cv::Point2f(17, 9); }, 1.0);
  ASSERT_GT(r.size(), 150u);
  EXPECT_LT(r[r.size() / 2], 0.1);
}

TEST(Features, PixelCentreConventionHasNoBias) {
  // Mirroring maps u -> W-1-u under the pixel-centre convention; OpenCV's raw positions after its
  // 2x up-sampling would be off by 0.25 px each, i.e. 0.5 px here.
  const cv::Mat a = drawnTexture(4, 320, 240);
  cv::Mat b;
  cv::flip(a, b, 1);
  for (bool up : {true, false}) {
    SiftOptions o;
    o.upsample = up;
    const Features fa = extractSift(a, o), fb = extractSift(b, o);
    auto r = pairedResiduals(fa, fb, [&](cv::Point2f p) { return cv::Point2f(a.cols - 1 - p.x, p.y); }, 1.5);
    ASSERT_GT(r.size(), 50u) << "upsample " << up;
    EXPECT_LT(r[r.size() / 2], 0.1) << "upsample " << up;
  }
}

TEST(Features, OrientationFollowsImageRotation) {
  // A 90 degree clockwise turn on screen is +90 degrees in image coordinates (u towards v).
  const cv::Mat a = drawnTexture(5, 240, 240);
  cv::Mat b;
  cv::rotate(a, b, cv::ROTATE_90_CLOCKWISE);
  const Features fa = extractSift(a, SiftOptions{}), fb = extractSift(b, SiftOptions{});
  std::vector<double> d;
  for (const auto& ka : fa.keypoints) {
    const cv::Point2f p(a.rows - 1 - ka.pt.y, ka.pt.x);
    for (const auto& kb : fb.keypoints)
      if (cv::norm(kb.pt - p) < 0.3 && std::abs(kb.size - ka.size) < 0.05 * ka.size)
        d.push_back(std::fmod(kb.angle - ka.angle + 720.0, 360.0));
  }
  ASSERT_GT(d.size(), 100u);
  std::sort(d.begin(), d.end());
  EXPECT_NEAR(d[d.size() / 2], 90.0, 1.0);
}

TEST(Features, BadInput) {
  EXPECT_THROW(extractSift(cv::Mat(), SiftOptions{}), std::invalid_argument);
  SiftOptions o;
  o.sigma = -1;
  EXPECT_THROW(o.check(), std::invalid_argument);
  o = {};
  o.max_features = -3;
  EXPECT_THROW(o.check(), std::invalid_argument);
  o = {};
  o.octave_layers = 0;
  EXPECT_THROW(o.check(), std::invalid_argument);
  o = {};
  o.contrast_threshold = std::nan("");
  EXPECT_THROW(o.check(), std::invalid_argument);
  // Colour input is converted; a tiny image gives no features rather than a crash.
  cv::Mat colour;
  cv::cvtColor(drawnTexture(6, 160, 120), colour, cv::COLOR_GRAY2BGR);
  EXPECT_GT(extractSift(colour, SiftOptions{}).size(), 10);
  EXPECT_EQ(extractSift(cv::Mat(4, 4, CV_8U, cv::Scalar(9)), SiftOptions{}).size(), 0);
}

// A region of interest gives the whole-image keypoints inside it (same positions, sizes,
// descriptors), except within a few keypoint sizes of the ROI's edge.
TEST(Features, RegionOfInterestMatchesTheWholeImage) {
  const cv::Mat img = drawnTexture(5, 640, 480);
  const Features all = extractSift(img, SiftOptions{});
  ExtractRegion region;
  region.roi = cv::Rect(200, 150, 240, 180);
  region.max_size_px = 40;
  // inner_margin_px: the keypoints that must match lie that much further in, the crop is smaller.
  int part_size[2] = {0, 0};
  for (double inner : {0.0, 30.0}) {
    region.inner_margin_px = inner;
    const Features part = extractSift(img, SiftOptions{}, region);
    ASSERT_GT(part.size(), 50);
    EXPECT_EQ(part.image_size, img.size());
    part_size[inner > 0] = part.size();
    int expected = 0, found = 0, outside = 0;
    for (const auto& k : part.keypoints)
      if (!region.roi.contains(cv::Point(cvRound(k.pt.x), cvRound(k.pt.y))) || k.size > 40) ++outside;
    for (int i = 0; i < all.size(); ++i) {
      const cv::KeyPoint& ka = all.keypoints[i];
      const double margin = inner + 1.5 * ka.size;
      if (ka.size > 40 || ka.pt.x < region.roi.x + margin || ka.pt.y < region.roi.y + margin ||
          ka.pt.x > region.roi.br().x - margin || ka.pt.y > region.roi.br().y - margin)
        continue;
      ++expected;
      for (int j = 0; j < part.size(); ++j) {
        const cv::KeyPoint& kb = part.keypoints[j];
        if (cv::norm(ka.pt - kb.pt) < 0.01 && std::abs(ka.size - kb.size) < 0.01 &&
            cv::norm(all.descriptors.row(i), part.descriptors.row(j), cv::NORM_L2) < 1.0) {
          ++found;
          break;
        }
      }
    }
    EXPECT_EQ(outside, 0);
    ASSERT_GT(expected, 30);
    EXPECT_GE(found, expected * 98 / 100) << found << " of " << expected << ", inner margin " << inner;
  }
  // Every keypoint of the region is still reported (near its edge, from less context).
  EXPECT_NEAR(part_size[1], part_size[0], 0.1 * part_size[0]);
  region.inner_margin_px = 0;

  region.roi = cv::Rect(700, 500, 10, 10);  // outside the image
  EXPECT_EQ(extractSift(img, SiftOptions{}, region).size(), 0);
  region = ExtractRegion{};
  region.min_size_px = 5;
  region.max_size_px = 4;
  EXPECT_THROW(extractSift(img, SiftOptions{}, region), std::invalid_argument);
}

TEST(GridIndex, RadiusSearchEqualsBruteForce) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> x(-20, 660), y(-20, 500);  // some outside the image
  std::vector<cv::KeyPoint> kps;
  for (int i = 0; i < 3000; ++i) kps.emplace_back(x(rng), y(rng), 3.f);
  for (int cell : {1, 7, 16, 64, 1000}) {
    const GridIndex grid(kps, cv::Size(640, 480), cell);
    std::uniform_real_distribution<double> cx(-100, 740), cy(-100, 580), rad(0, 120);
    std::vector<int> got;
    for (int q = 0; q < 300; ++q) {
      const Eigen::Vector2d c(cx(rng), cy(rng));
      const double r = q == 0 ? 0.0 : rad(rng);
      grid.radiusSearch(c, r, &got);
      std::vector<int> want;
      for (int i = 0; i < static_cast<int>(kps.size()); ++i) {
        const double dx = kps[i].pt.x - c.x(), dy = kps[i].pt.y - c.y();
        if (dx * dx + dy * dy <= r * r) want.push_back(i);
      }
      std::sort(got.begin(), got.end());
      ASSERT_EQ(got, want) << "cell " << cell << " query " << q;
    }
  }
  const GridIndex empty({}, cv::Size(640, 480));
  std::vector<int> got{1, 2};
  empty.radiusSearch(Eigen::Vector2d(10, 10), 50, &got);
  EXPECT_TRUE(got.empty());
}

TEST(GridIndex, NearestEqualsAFilteredFullSort) {
  // The matcher's neighbour order: the first k by (squared distance, index), self first, among
  // the points a size filter accepts. Points outside the image, exact duplicates, every cell size.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<float> x(-30, 670), y(-30, 510), size(1.f, 40.f);
  std::vector<cv::KeyPoint> kps;
  for (int i = 0; i < 1200; ++i) kps.emplace_back(x(rng), y(rng), size(rng));
  for (int i = 0; i < 50; ++i) kps.push_back(kps[static_cast<size_t>(i) * 7]);  // duplicates
  kps.emplace_back(-300.f, 900.f, 30.f);                                       // far outside
  const int n = static_cast<int>(kps.size());
  std::uniform_int_distribution<int> pick(0, n - 1);
  int checked = 0;
  for (int cell : {1, 5, 16, 37, 1000}) {
    const GridIndex grid(kps, cv::Size(640, 480), cell);
    std::vector<int> got;
    for (int q = 0; q < 120; ++q) {
      const int self = q == 0 ? n - 1 : pick(rng);
      const float min_size = q % 3 == 0 ? 0.f : (q % 3 == 1 ? 20.f : 38.f);
      auto accept = [&](int i) { return kps[i].size >= min_size; };
      std::vector<std::pair<double, int>> all;
      for (int i = 0; i < n; ++i) {
        if (!accept(i)) continue;
        const double dx = static_cast<double>(kps[i].pt.x) - kps[self].pt.x;
        const double dy = static_cast<double>(kps[i].pt.y) - kps[self].pt.y;
        all.emplace_back(dx * dx + dy * dy + (i == self ? -1.0 : 0.0), i);
      }
      std::sort(all.begin(), all.end());
      for (int k : {1, 40, 200, 5000}) {
        grid.nearest(self, k, accept, &got);
        std::vector<int> want;
        for (int j = 0; j < std::min(k, static_cast<int>(all.size())); ++j) want.push_back(all[j].second);
        ASSERT_EQ(got, want) << "cell " << cell << " self " << self << " k " << k << " min size " << min_size;
        ++checked;
      }
    }
  }
  EXPECT_EQ(checked, 5 * 120 * 4);
  std::vector<int> got{1};
  GridIndex({}, cv::Size(640, 480)).nearest(0, 5, [](int) { return true; }, &got);
  EXPECT_TRUE(got.empty());
}

}  // namespace
}  // namespace refgrasp::detector
