#pragma once
// The project's own SIFT (SiftImplementation::kFast): the algorithm of OpenCV 4.6's cv::SIFT with
// its defaults (firstOctave = -1: the image is doubled first), re-implemented for speed:
//  - scale space: the same up-sampling, the same Gaussian kernels (cv::getGaussianKernel) applied
//    with the same fused multiply-add order as OpenCV's AVX2 filter, so the pyramid is bit-exact
//    with cv::GaussianBlur on AVX2 machines; computed row by row in one sweep per octave (all
//    layers, the DoG and the extremum test together while the rows are in cache);
//  - extrema: OpenCV's threshold, 26-neighbour test, sub-pixel interpolation (5 steps, its 3x3
//    solve), contrast and edge tests, the same floating-point expressions;
//  - orientation (36 bins, smoothing, 0.8 peaks, parabolic fit) and the 4x4x8 descriptor
//    (trilinear, 0.2 clip, normalisation, uchar rounding) as OpenCV computes them, vectorised,
//    from one window of gradients per keypoint spot (computed where the windows are only);
//    Differences left: the exp and atan approximations and the summation order of the histograms
//    differ from OpenCV's in the last bits (tests/detector/test_sift_fast.cpp measures the effect).
//  - pruning before the work: octaves that cannot yield a keypoint in the wanted size range are
//    not searched (and the ones above it are not built).
// SIMD kernels (sift_fast_kernels.h) for AVX-512, AVX2 and scalar give bit-identical results.
#include <opencv2/core.hpp>
#include <vector>

#include "detector/features.h"

namespace refgrasp::detector {

enum class SiftIsa { kScalar, kAvx2, kAvx512 };
/// The widest kernels this CPU runs: AVX-512 (F, DQ, BW, VL), else AVX2 + FMA, else scalar. The
/// environment variable REFGRASP_SIFT_ISA=scalar|avx2|avx512 lowers it (never above the CPU's).
SiftIsa bestSiftIsa();
bool siftIsaSupported(SiftIsa isa);
const char* siftIsaName(SiftIsa isa);

/// What one call did and where its time went: wall clock of this call's stages and the calling
/// thread's CPU time in them (ms; with FastSiftCall::threads = 1 that is all the work).
struct FastSiftStats {
  /// Pyramid, DoG, extremum test, sub-pixel interpolation with the contrast and edge tests (one
  /// sweep per octave).
  double scale_space_ms = 0;
  double localise_ms = 0;     ///< duplicates removed (the interpolation runs in the sweep)
  double describe_ms = 0;     ///< gradient windows, orientation histograms and descriptors
  double output_ms = 0;       ///< sort strongest first, cut to max_features, copy out
  double scale_space_cpu_ms = 0, localise_cpu_ms = 0, describe_cpu_ms = 0, output_cpu_ms = 0;
  int octaves_built = 0, octaves_searched = 0;
  int candidates = 0, extrema = 0, keypoints = 0;
  /// Interpolation steps at points the sweep's DoG rows no longer (or not yet) held: a Newton
  /// step that jumped far; their DoG is recomputed exactly on a small patch.
  int far_steps = 0;
};

struct FastSiftCall {
  SiftIsa isa = SiftIsa::kScalar;
  /// 1 = the caller's thread only; any other value = the keypoint stages (localisation,
  /// orientation, descriptors) also run on OpenCV's pool (cv::getNumThreads() threads). The
  /// scale-space sweep is single-threaded.
  int threads = 0;
  /// Only keypoints with size in [min_size, max_size] (work-image px) are searched for; octaves
  /// outside the range are skipped. Ignored (everything searched) when opt.max_features > 0, so
  /// that the strongest-N cut sees the same keypoints as cv::SIFT does.
  double min_size = 0, max_size = 1e30;
  /// When not empty: keypoints are only searched for around this region (work-image px, the
  /// extremum test runs in it widened by 4 octave px); the scale space is still computed on the whole
  /// image (the caller crops it first). Ignored, as the size range, when opt.max_features > 0.
  cv::Rect roi;
  FastSiftStats* stats = nullptr;  ///< filled when not null
};

/// Keypoints and descriptors of `gray8` (CV_8UC1), as cv::SIFT::create(opt.max_features,
/// opt.octave_layers, opt.contrast_threshold, opt.edge_threshold, opt.sigma)->detectAndCompute
/// returns them in OpenCV 4.6: same keypoint convention (its +0.25 px bias included, octave
/// packed the same way), descriptors CV_32F with integer values 0..255. Sorted strongest first,
/// ties by position, size, angle; cut to opt.max_features when > 0. opt.upsample is not read
/// here (extractSift handles it). Deterministic, whatever the thread count.
void fastSiftDetectAndCompute(const cv::Mat& gray8, const SiftOptions& opt, const FastSiftCall& call,
                              std::vector<cv::KeyPoint>* keypoints, cv::Mat* descriptors);

}  // namespace refgrasp::detector
