#pragma once
// The project's fast SIFT (SiftImplementation::kFast) against cv::SIFT of OpenCV 4.6 (kOpenCV) on
// the same images (docs/results.md "Equivalence"): keypoint recall and precision, keypoints equal
// to the bit, positions and descriptor distances of the counterparts. A counterpart: the nearest
// keypoint of the other extractor within 0.5 px, 5 % in size and 5 degrees.
// tests/detector/test_sift_fast.cpp asserts on these sets; bench_sift --equivalence prints them.
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "detector/features.h"

namespace refgrasp::eval {

struct SiftAgreement {
  int reference = 0, fast = 0;  ///< keypoint counts (cv::SIFT, fast)
  int recalled = 0;             ///< cv::SIFT keypoints with a fast counterpart
  int precise = 0;              ///< fast keypoints with a cv::SIFT counterpart
  int identical = 0;            ///< counterparts equal in position, size, angle, response (float ==)
  std::vector<double> desc;     ///< descriptor L2 distance of each recalled keypoint
  double max_pos = 0;           ///< largest position difference of a counterpart, px
  /// What is wrong with the fast descriptors' layout, one line each: not CV_32F, a row count
  /// other than the keypoints', an entry that is not an integer in 0..255 (the matcher relies on
  /// integer descriptors).
  std::vector<std::string> problems;

  void add(const SiftAgreement& o);
  double recall() const { return reference ? static_cast<double>(recalled) / reference : 1; }
  double precision() const { return fast ? static_cast<double>(precise) / fast : 1; }
  double identicalFraction() const { return recalled ? static_cast<double>(identical) / recalled : 0; }
  /// The q-quantile of the descriptor distances by nearest rank; 0 when none.
  double descQuantile(double q) const;
};

/// The counterpart of each keypoint of `a` in `b` (-1 when none): the nearest in position among
/// b's keypoints within the bars.
std::vector<int> siftCounterparts(const detector::Features& a, const detector::Features& b);

/// Both extractors with `opt` (its implementation field is overridden) on `img`.
SiftAgreement compareSift(const cv::Mat& img, detector::SiftOptions opt);

struct SiftEquivalenceRow {
  std::string set;
  SiftAgreement agreement;
};

/// The default options on: 20 rendered 640x480 scenes (each target at 4 seeded poses, 0.3-1.2 m,
/// tilt <= 50 deg, clutter, noise 2, motion blur <= 1.5 px), 4 clutter frames, 10 textures
/// (targets, hard cases, a box side, the wall), then each of the 6 photographs of media/photos/
/// and the 6 together: one row per set, in that order.
std::vector<SiftEquivalenceRow> siftEquivalenceDefaultOptions();

/// 8 other option sets (up-sampling off, octave layers, sigma, thresholds, max_features), each on
/// a photograph and a clutter frame, then odd sizes and a colour image: one row each.
std::vector<SiftEquivalenceRow> siftEquivalenceOtherOptions();

}  // namespace refgrasp::eval
