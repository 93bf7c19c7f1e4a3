#pragma once
// Seeded uniform noise images for tests (incompressible content): every draw comes from the
// caller's generator, seeded by the test, never from a global one (cv::theRNG, rand).
#include <opencv2/core.hpp>
#include <random>

namespace refgrasp::testing {

/// w x h of uniform noise in 0..255, type CV_8UC1 or CV_8UC3.
inline cv::Mat noiseImage(std::mt19937_64& rng, int w, int h, int type = CV_8UC1) {
  cv::Mat m(h, w, type);
  std::uniform_int_distribution<int> d(0, 255);
  for (size_t i = 0; i < m.total() * m.elemSize(); ++i) m.data[i] = static_cast<uchar>(d(rng));
  return m;
}

}  // namespace refgrasp::testing
