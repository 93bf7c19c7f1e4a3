#pragma once
// Photo pairs: a reference photo and one scene photo of the same planar picture, 2D
// only, scored by the corners of the reference mapped by the reported homography, the way
// affine-viewpoint benchmarks score image pairs. Seven families of pairs, each at five levels:
//   viewpoint       the picture seen at 20, 30, 40, 50, 60 deg from its normal
//   zoom+rotation   the camera closer (1.3x .. 2.9x the reference's scale) and rolled 10 .. 50 deg
//   blur            defocus sigma 1 .. 5 px
//   light           darker exposure (gain 0.7 .. 0.2) with a brightness gradient
//   jpeg            JPEG quality 40, 25, 15, 8, 4
//   near-light      near-identity at full resolution (below), 800, 1000, 1200, 1400, 1600 px
//                   wide, under other light (gain 0.6-1.4, gamma 0.7-1.4, a gradient of 10-30 %)
//   near-jpeg       near-identity at full resolution, 800-1600 px wide, JPEG quality 90, 70, 50,
//                   30, 10
// The picture is a real photograph of media/photos/ or a pattern of media/targets/, set in a
// canvas three times its size filled with photo clutter (a poster on a wall); the reference is
// the picture alone, fronto-parallel, at most 640 px wide, with a mild camera look; the scene is
// 640x480 (f = 700 px) rendered exactly (sim::renderView) with its own look.
// Near-identity families: the picture resized to the level's width is the reference (with the
// same mild look); the scene, of the reference's size (f = 1.2 x its width), shows it on a wall
// of clutter a quarter of its size wider on each side, seen from straight ahead at a scale of
// 0.97-1.03, rolled up to 2 deg, tilted up to 2 deg and shifted up to 5 px: two photos of one
// poster taken one after the other, where hundreds of features agree.
//
// Pixels: H_true maps reference px -> scene px (x_scene ~ H x_ref, pixel centres).
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "core/camera.h"
#include "detector/detector.h"

namespace refgrasp::eval {

enum class PairFamily { kViewpoint, kZoomRotation, kBlur, kLight, kJpeg, kNearLight, kNearJpeg };
constexpr int kPairFamilies = 7;
constexpr int kPairLevels = 5;
const char* pairFamilyName(PairFamily f);
/// What level 0..4 of the family means, e.g. "2.1x, 30 deg".
std::string pairLevelLabel(PairFamily f, int level);

struct ViewPair {
  std::string texture;      ///< media path
  PairFamily family = PairFamily::kViewpoint;
  int level = 0;
  cv::Mat reference;        ///< CV_8UC1
  cv::Mat scene;            ///< CV_8UC1, 640x480 (near-identity families: the reference's size)
  Intrinsics camera;        ///< the scene's (pinhole)
  Eigen::Matrix3d H_true;   ///< reference px -> scene px
};

/// The pictures of the pairs: media/photos then media/targets (loadMedia paths).
std::vector<std::string> pairTextures();
/// The seed of the pairs of picture `texture_index` in split `split_seed` (evaluatePairs,
/// bench_pairs --dump and --diagnose draw the same pairs).
uint64_t pairSeed(uint64_t split_seed, int texture_index);

/// The pair of (texture, family, level) drawn with `seed` (pose details, looks, background).
ViewPair makeViewPair(const std::string& texture, PairFamily family, int level, uint64_t seed);

/// Largest distance between the reference image's four corners mapped by H and by H_true, px
/// (the corners may lie outside the scene; 1e9 when H maps one to infinity).
double worstCornerError(const ViewPair& p, const Eigen::Matrix3d& H);

struct PairOutcome {
  std::string texture;
  PairFamily family = PairFamily::kViewpoint;
  int level = 0;
  uint64_t seed = 0;
  bool r_reported = false, c_reported = false;
  double r_err = 0, c_err = 0;  ///< worst corner error when reported
  int r_inliers = 0, c_inliers = 0;
  double r_ms = 0, c_ms = 0;    ///< thread CPU time of each method on the scene (the classic: with its cv::SIFT)
  std::string r_miss;           ///< refgrasp's miss reason when not reported
};

/// Every texture (photos + targets) x family x level for seeds first_seed .. first_seed+seeds-1,
/// refgrasp (the reference registered 2D-only, whole image) beside the classic pipeline.
/// only_family >= 0: that family alone. progress(done, total) after each pair when given.
std::vector<PairOutcome> evaluatePairs(const detector::DetectorOptions& opt, int seeds, uint64_t first_seed,
                                       int only_family = -1, const std::function<void(int, int)>& progress = {});

/// Markdown: per family and level, corners within `tol_px` (refgrasp / classic), reported, wrong
/// (reported with a worst corner error > 10 tol_px), median worst-corner error over the pairs
/// both placed within 10 tol_px, median time per scene; then the totals.
std::string formatPairTables(const std::vector<PairOutcome>& rows, double tol_px);

struct PairCounts {
  int n = 0, within_r = 0, within_c = 0, reported_r = 0, reported_c = 0, wrong_r = 0, wrong_c = 0;
};
PairCounts countPairs(const std::vector<PairOutcome>& rows, double tol_px);

}  // namespace refgrasp::eval
