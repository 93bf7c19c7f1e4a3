#include "detector/sift_fast.h"

#include <algorithm>
#include <atomic>
#include <cfloat>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <memory>
#include <numeric>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

#include "detector/sift_fast_kernels.h"

namespace refgrasp::detector {

namespace si = sift_internal;

// ------------------------------------------------------------------------------------------------
// Instruction-set dispatch.

bool siftIsaSupported(SiftIsa isa) {
#if defined(__x86_64__) || defined(__i386__)
  static const bool avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  static const bool avx512 = avx2 && __builtin_cpu_supports("avx512f") &&
                             __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw") &&
                             __builtin_cpu_supports("avx512vl");
  if (isa == SiftIsa::kAvx2) return avx2;
  if (isa == SiftIsa::kAvx512) return avx512;
#endif
  return isa == SiftIsa::kScalar;
}

const char* siftIsaName(SiftIsa isa) {
  switch (isa) {
    case SiftIsa::kAvx512: return "avx512";
    case SiftIsa::kAvx2: return "avx2";
    default: return "scalar";
  }
}

SiftIsa bestSiftIsa() {
  static const SiftIsa best = [] {
    SiftIsa b = siftIsaSupported(SiftIsa::kAvx512) ? SiftIsa::kAvx512
                : siftIsaSupported(SiftIsa::kAvx2) ? SiftIsa::kAvx2
                                                   : SiftIsa::kScalar;
    if (const char* env = std::getenv("REFGRASP_SIFT_ISA")) {
      const std::string e = env;
      if (e == "scalar") b = SiftIsa::kScalar;
      if (e == "avx2" && b == SiftIsa::kAvx512) b = SiftIsa::kAvx2;
    }
    return b;
  }();
  return best;
}

namespace {

const si::Kernels& kernelsFor(SiftIsa isa) {
  if (isa == SiftIsa::kAvx512 && siftIsaSupported(isa)) return si::avx512Kernels();
  if (isa != SiftIsa::kScalar && siftIsaSupported(SiftIsa::kAvx2)) return si::avx2Kernels();
  return si::scalarKernels();
}

// ------------------------------------------------------------------------------------------------
// OpenCV 4.6 constants (sift.simd.hpp).
constexpr int kBorder = 5;            // SIFT_IMG_BORDER
constexpr int kMaxInterpSteps = 5;    // SIFT_MAX_INTERP_STEPS
constexpr int kOriBins = 36;          // SIFT_ORI_HIST_BINS
constexpr float kOriSigFactor = 1.5f; // SIFT_ORI_SIG_FCTR
constexpr float kOriRadius = 4.5f;    // SIFT_ORI_RADIUS
constexpr float kOriPeakRatio = 0.8f; // SIFT_ORI_PEAK_RATIO
constexpr float kDescrSclFactor = 3.f;
constexpr float kDescrMagThr = 0.2f;
constexpr float kIntDescrFactor = 512.f;
constexpr int kDescrWidth = 4, kDescrBins = 8, kDescrLen = 128;
constexpr float kInitSigma = 0.5f;    // SIFT_INIT_SIGMA

int cvRoundF(float v) { return static_cast<int>(std::lrint(v)); }
int cvRoundD(double v) { return static_cast<int>(std::lrint(v)); }
int roundUp(int v, int a) { return (v + a - 1) / a * a; }

/// cv::BORDER_REFLECT_101 index (gfedcb|abcdefgh|gfedcba).
int reflect101(int p, int n) {
  if (n == 1) return 0;
  while (p < 0 || p >= n) p = p < 0 ? -p : 2 * n - 2 - p;
  return p;
}

struct FreeDeleter {
  void operator()(void* p) const { std::free(p); }
};

/// Grow-only 64-byte-aligned buffer of T: reused across calls, so that a frame neither
/// allocates nor page-faults once the first one has run. It grows by at least half its size, so
/// that images of varying sizes (regions of interest) reallocate a few times only.
template <class T>
class Buffer {
 public:
  T* get(size_t count) {
    if (count > size_) {
      const size_t bytes = (std::max(count, size_ + size_ / 2) * sizeof(T) + 63) / 64 * 64;
      data_.reset(static_cast<T*>(std::aligned_alloc(64, bytes)));
      if (!data_) throw std::bad_alloc();
      size_ = bytes / sizeof(T);
    }
    return data_.get();
  }
  size_t size() const { return size_; }

 private:
  std::unique_ptr<T, FreeDeleter> data_;
  size_t size_ = 0;
};

/// A Gaussian kernel as cv::GaussianBlur builds it for a CV_32F image.
struct Kernel {
  int n = 1, h = 0;
  std::vector<float> taps;    ///< n taps
  std::vector<float> centre;  ///< taps[h + j], j = 0..h
};

Kernel gaussianKernel(double sigma) {
  Kernel k;
  k.n = cvRoundD(sigma * 4 * 2 + 1) | 1;  // createGaussianKernels for depth != CV_8U
  k.h = k.n / 2;
  const cv::Mat m = cv::getGaussianKernel(k.n, sigma, CV_32F);
  k.taps.assign(m.ptr<float>(), m.ptr<float>() + k.n);
  k.centre.assign(k.taps.begin() + k.h, k.taps.end());
  return k;
}

/// One octave of the Gaussian scale space, as the later stages read it: the layers where
/// keypoints live (1..n_layers, w x h floats, OpenCV's values) for the gradient windows and the
/// next octave's base; the other layers and the DoG exist only as the sweep's rows in flight.
/// Rows carry `pad` floats of BORDER_REFLECT_101 copies on each side (the next blur reads them)
/// plus slack for the vector kernels' over-reads.
struct Octave {
  int w = 0, h = 0, stride = 0, pad = 0;
  std::vector<float*> g;  ///< per layer; null for the layers not kept
  /// Unique per octave and call (gradient windows cached in per-thread scratch are keyed by it).
  uint64_t generation = 0;
  float* row(int layer, int y) const { return g[layer] + static_cast<ptrdiff_t>(y) * stride; }
};

/// The DoG rows the sweep keeps, a ring of `depth` rows per layer, and the window of rows (and
/// columns) they hold at a given moment, for the interpolation.
struct DogView {
  const float* ring = nullptr;  ///< layer k, row y: ring + (k * depth + y mod depth) * stride
  int depth = 0, stride = 0, w = 0, h = 0;
  int row_lo = 0, row_hi = -1;  ///< rows held (inclusive)
  int col_lo = 0, col_hi = 0;   ///< columns [col_lo, col_hi) held
  const float* row(int k, int y) const {
    return ring + (static_cast<size_t>(k) * depth + static_cast<size_t>(y & (depth - 1))) * stride;
  }
  /// DoG layer k (= Gaussian layer k + 1 - layer k), as cv::SIFT's dog_pyr.
  float dog(int k, int y, int x) const { return row(k, y)[x]; }
  /// The 3x3x3 neighbourhood of (r, c) is held.
  bool holds(int r, int c) const { return r - 1 >= row_lo && r + 1 <= row_hi && c - 1 >= col_lo && c + 1 < col_hi; }
};

/// BORDER_REFLECT_101 copies in the `pad` samples left (left = true) or right of a row.
void fillPad(float* row, int w, int pad, bool left) {
  if (w > pad) {
    if (left) {
      for (int p = 1; p <= pad; ++p) row[-p] = row[p];
    } else {
      for (int p = 1; p <= pad; ++p) row[w - 1 + p] = row[w - 1 - p];
    }
    return;
  }
  for (int p = 1; p <= pad; ++p) {
    if (left) {
      row[-p] = row[reflect101(-p, w)];
    } else {
      row[w - 1 + p] = row[reflect101(w - 1 + p, w)];
    }
  }
}

struct Candidate {
  int layer, r, c;
};

/// An extremum after interpolation (adjustLocalExtrema).
struct Extremum {
  int octave, layer, r, c;  ///< octave index in the pyramid (0 = doubled image)
  float xc, xr, xi, contr;
  bool operator<(const Extremum& o) const {
    if (octave != o.octave) return octave < o.octave;
    if (layer != o.layer) return layer < o.layer;
    if (r != o.r) return r < o.r;
    return c < o.c;
  }
  bool sameSpot(const Extremum& o) const {
    return octave == o.octave && layer == o.layer && r == o.r && c == o.c;
  }
};

/// A keypoint with what its descriptor needs.
struct Kp {
  cv::KeyPoint kp;  ///< cv::SIFT's convention (firstOctave applied)
  int octave, layer;
  float ptf_x, ptf_y, scl;  ///< in octave px: c + xc, r + xr; sigma of the keypoint
};

struct Params {
  int n_layers;
  float contrast, edge, sigma;
  int threshold;
  std::vector<Kernel> kernels;  ///< layer i (1..n_layers+2) blurs layer i-1 by kernels[i]
  Kernel init;                  ///< the doubled input -> layer 0 of octave 0
};

Params makeParams(const SiftOptions& opt) {
  Params p;
  p.n_layers = opt.octave_layers;
  p.contrast = static_cast<float>(opt.contrast_threshold);
  p.edge = static_cast<float>(opt.edge_threshold);
  p.sigma = static_cast<float>(opt.sigma);
  p.threshold = static_cast<int>(std::floor(0.5 * opt.contrast_threshold / opt.octave_layers * 255));
  // Incremental sigmas, as buildGaussianPyramid computes them (double).
  p.kernels.resize(p.n_layers + 3);
  const double k = std::pow(2., 1. / p.n_layers);
  for (int i = 1; i < p.n_layers + 3; ++i) {
    const double sig_prev = std::pow(k, static_cast<double>(i - 1)) * opt.sigma;
    const double sig_total = sig_prev * k;
    p.kernels[i] = gaussianKernel(std::sqrt(sig_total * sig_total - sig_prev * sig_prev));
  }
  const float s = p.sigma;
  const float sig_diff = std::sqrt(std::max(s * s - kInitSigma * kInitSigma * 4, 0.01f));
  p.init = gaussianKernel(sig_diff);
  return p;
}

/// The keypoints (and, without a strongest-N cut, descriptors) of one chunk of extrema.
struct KeypointPart {
  std::vector<Kp> kps;
  std::vector<float> desc;  ///< 128 per keypoint when descriptors are computed with them
};

/// Per-thread memory, reused from one call to the next.
struct Workspace {
  std::vector<KeypointPart> parts;
  Buffer<float> pyramid, rings, dog_rows, maxmin, temp;
  std::vector<Octave> octaves;
  std::vector<Candidate> candidates;
  std::vector<int32_t> cols;
};

/// Source of Octave::generation.
std::atomic<uint64_t> generation{0};

Workspace& workspace() {
  thread_local Workspace ws;
  return ws;
}

/// Gradient samples (magnitude, angle) around (r, c) of a layer, computed on demand into the
/// thread's scratch (not as whole gradient planes in the sweep: those went to memory and back,
/// and cost more than the windows, which cover part of the image): rows |i| <= radius, in row i
/// the columns [lo, hi] computed so far, grown by coverRow (the orientation square, then each
/// descriptor's rotated grid: only the samples a histogram reads). Kept while the next keypoint
/// of the same spot asks for it.
struct GradientWindow {
  si::GradientPatch p;
  uint64_t generation = 0;  ///< Octave::generation of the pyramid it was computed from
  int layer = -1, r = 0, c = 0, radius = -1;
  const float* img = nullptr;  ///< the layer at (r, c)
  int stride = 0;
  std::vector<int> lo, hi;  ///< per row i + radius; lo > hi: nothing yet
};

/// Per-thread scratch of the keypoint stages.
struct KeypointScratch {
  Buffer<float> weights, gauss, sum;
  /// The descriptor's slots, zero between calls (the kernel clears what it reads).
  float* slots() {
    if (!slots_) {
      const size_t n = static_cast<size_t>(si::kDescrCopies) * si::kDescrSlotFloats;
      slots_ = slot_buf_.get(n);
      std::fill(slots_, slots_ + n, 0.f);
    }
    return slots_;
  }
  Buffer<float> slot_buf_;
  float* slots_ = nullptr;
  std::vector<int32_t> index;
  std::vector<uint32_t> bits;
  /// The last gradient window (gradientWindow) and its samples.
  GradientWindow window;
  Buffer<float> window_mag, window_ori;
  size_t window_zeroed = 0;
  std::vector<int> columns_a, columns_b;  ///< a descriptor's columns per row (descriptor_columns)
};

KeypointScratch& keypointScratch() {
  thread_local KeypointScratch s;
  return s;
}

// ------------------------------------------------------------------------------------------------
// Keypoint localisation (adjustLocalExtrema), in OpenCV's float expressions.

/// x = H^-1 b by Cramer's rule as cv::Matx<float,3,3>::solve(DECOMP_LU) computes it; false when
/// det(H) == 0 (OpenCV then returns zeros).
bool solve3(const float a[3][3], const float b[3], float x[3]) {
  float d = a[0][0] * (a[1][1] * a[2][2] - a[2][1] * a[1][2]) -
            a[0][1] * (a[1][0] * a[2][2] - a[2][0] * a[1][2]) +
            a[0][2] * (a[1][0] * a[2][1] - a[2][0] * a[1][1]);
  if (d == 0) return false;
  d = 1 / d;
  x[0] = d * (b[0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (b[1] * a[2][2] - a[1][2] * b[2]) +
              a[0][2] * (b[1] * a[2][1] - a[1][1] * b[2]));
  x[1] = d * (a[0][0] * (b[1] * a[2][2] - a[1][2] * b[2]) - b[0] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
              a[0][2] * (a[1][0] * b[2] - b[1] * a[2][0]));
  x[2] = d * (a[0][0] * (a[1][1] * b[2] - b[1] * a[2][1]) - a[0][1] * (a[1][0] * b[2] - b[1] * a[2][0]) +
              b[0] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]));
  return true;
}

/// First and second derivatives of the DoG at (layer, r, c), OpenCV's finite differences and
/// scales (image values in [0, 1]).
struct Derivatives {
  float dD[3];  ///< d/dx, d/dy, d/dlayer
  float dxx, dyy, dss, dxy, dxs, dys;
};

/// D(l, y, x): the DoG value of layer l at row y, column x.
template <class Dog>
Derivatives derivatives(const Dog& D, int layer, int r, int c) {
  const float img_scale = 1.f / 255;
  const float deriv_scale = img_scale * 0.5f, second_scale = img_scale, cross_scale = img_scale * 0.25f;
  Derivatives d;
  d.dD[0] = (D(layer, r, c + 1) - D(layer, r, c - 1)) * deriv_scale;
  d.dD[1] = (D(layer, r + 1, c) - D(layer, r - 1, c)) * deriv_scale;
  d.dD[2] = (D(layer + 1, r, c) - D(layer - 1, r, c)) * deriv_scale;
  const float v2 = D(layer, r, c) * 2;
  d.dxx = (D(layer, r, c + 1) + D(layer, r, c - 1) - v2) * second_scale;
  d.dyy = (D(layer, r + 1, c) + D(layer, r - 1, c) - v2) * second_scale;
  d.dss = (D(layer + 1, r, c) + D(layer - 1, r, c) - v2) * second_scale;
  d.dxy = (D(layer, r + 1, c + 1) - D(layer, r + 1, c - 1) - D(layer, r - 1, c + 1) + D(layer, r - 1, c - 1)) *
          cross_scale;
  d.dxs = (D(layer + 1, r, c + 1) - D(layer + 1, r, c - 1) - D(layer - 1, r, c + 1) + D(layer - 1, r, c - 1)) *
          cross_scale;
  d.dys = (D(layer + 1, r + 1, c) - D(layer + 1, r - 1, c) - D(layer - 1, r + 1, c) + D(layer - 1, r - 1, c)) *
          cross_scale;
  return d;
}

/// The DoG values of layers layer-1..layer+1, rows r-1..r+1, columns c-1..c+1 (cube[l][y][x]),
/// for a point the sweep's rows no longer (or do not yet) hold.
struct DogCube {
  int layer = 0, r = 0, c = 0;
  float v[3][3][3];
  float operator()(int l, int y, int x) const { return v[l - layer + 1][y - r + 1][x - c + 1]; }
};

enum class Interpolated { kKept, kRejected };

/// adjustLocalExtrema: up to 5 Newton steps, then the contrast and edge tests, on the DoG rows the
/// sweep holds; `exact(layer, r, c, &cube)` gives the DoG around a point they do not (such
/// steps counted in *outside).
template <class ExactDog>
Interpolated interpolate(const DogView& view, const ExactDog& exact, const Params& P, int o, Candidate cand,
                         Extremum* out, int* outside) {
  int layer = cand.layer, r = cand.r, c = cand.c;
  float xi = 0, xr = 0, xc = 0;
  DogCube cube;
  bool held = true;
  auto at = [&](int l, int y, int x) { return held ? view.dog(l, y, x) : cube(l, y, x); };
  auto look = [&] {  // the DoG around (layer, r, c)
    held = view.holds(r, c);
    if (!held) {
      exact(layer, r, c, &cube);
      ++*outside;
    }
  };
  int step = 0;
  for (; step < kMaxInterpSteps; ++step) {
    look();
    const Derivatives d = derivatives(at, layer, r, c);
    const float Hm[3][3] = {{d.dxx, d.dxy, d.dxs}, {d.dxy, d.dyy, d.dys}, {d.dxs, d.dys, d.dss}};
    float X[3] = {0, 0, 0};
    if (!solve3(Hm, d.dD, X)) X[0] = X[1] = X[2] = 0;
    xi = -X[2];
    xr = -X[1];
    xc = -X[0];
    if (std::abs(xi) < 0.5f && std::abs(xr) < 0.5f && std::abs(xc) < 0.5f) break;
    const float big = static_cast<float>(INT_MAX / 3);
    if (std::abs(xi) > big || std::abs(xr) > big || std::abs(xc) > big) return Interpolated::kRejected;
    c += cvRoundF(xc);
    r += cvRoundF(xr);
    layer += cvRoundF(xi);
    if (layer < 1 || layer > P.n_layers || c < kBorder || c >= view.w - kBorder || r < kBorder ||
        r >= view.h - kBorder)
      return Interpolated::kRejected;
  }
  if (step >= kMaxInterpSteps) return Interpolated::kRejected;

  const Derivatives d = derivatives(at, layer, r, c);
  const float t = d.dD[0] * xc + d.dD[1] * xr + d.dD[2] * xi;
  const float contr = at(layer, r, c) * (1.f / 255) + t * 0.5f;
  if (std::abs(contr) * P.n_layers < P.contrast) return Interpolated::kRejected;
  const float tr = d.dxx + d.dyy;
  const float det = d.dxx * d.dyy - d.dxy * d.dxy;
  if (det <= 0 || tr * tr * P.edge >= (P.edge + 1) * (P.edge + 1) * det) return Interpolated::kRejected;
  *out = {o, layer, r, c, xc, xr, xi, contr};
  return Interpolated::kKept;
}

// ------------------------------------------------------------------------------------------------
// Scale space.

/// Row m of the doubled image, OpenCV's bilinear resize: wa * input row r0 + wb * input row r1.
struct DoubledRow {
  int r0, r1;
  float wa, wb;
};

DoubledRow doubledRow(int m, int input_rows) {
  const int q = m / 2;
  if (m % 2 == 0 && q > 0) return {q - 1, q, 0.25f, 0.75f};
  if (m % 2 == 1 && q < input_rows - 1) return {q, q + 1, 0.75f, 0.25f};
  return {q, q, 1.f, 0.f};
}

/// Rows [y0, y1] and columns [x0, x1] (inclusive) of a layer.
struct PatchArea {
  int y0, y1, x0, x1;
  int width() const { return x1 - x0 + 1; }
  int height() const { return y1 - y0 + 1; }
  bool contains(const PatchArea& a) const { return a.y0 >= y0 && a.y1 <= y1 && a.x0 >= x0 && a.x1 <= x1; }
};

/// One octave's sweep (sweepOctave): the layers' kernels, lags and halos, the rings of the rows in
/// flight, what the sweep has made so far, the current strip's columns and the candidates waiting
/// for their interpolation.
class OctaveSweep {
 public:
  OctaveSweep(const si::Kernels& K, const Params& P, int o, const cv::Mat& input, const Octave* prev, Octave& oct,
              int n_build, bool detect, const cv::Rect& test_area, Workspace& ws, std::vector<Extremum>* found,
              int* far_steps, int* candidates);
  /// The whole octave, strip by strip.
  void run();

 private:
  static constexpr int kBlock = 4;         // rows per step: the column filter makes 4 rows from 2h + 4
  static constexpr int kStripWidth = 512;  // columns per strip (the last one takes the rest)
  // The interpolation runs kReach rows behind the extremum test, on DoG rows still held: a
  // Newton step may move a candidate that far (columns too: the strips' halos grow by it).
  static constexpr int kReach = 8;
  static constexpr int kMaxMinRing = 8;

  struct PatchMemo {
    PatchArea area{0, -1, 0, -1};
    std::vector<float> v;
  };

  void planLayers();
  void placeLayerRings();
  void placeDetectionRings();
  float* layerRow(int i, int y) const;
  float* dogRow(int k, int y) const { return const_cast<float*>(view_.row(k, y)); }
  float* maxMinRow(int k, int y, int which) const;
  bool made(int i, int y1, int x1) const;
  std::vector<float> exactPatch(int i, const PatchArea& a);
  std::vector<float> doubledInputPatch(const PatchArea& a) const;
  void blurPatch(const Kernel& k, const std::vector<float>& src, const PatchArea& source, const PatchArea& a,
                 std::vector<float>& out) const;
  void exactDogCube(int layer, int r, int c, DogCube* cube);
  void beginStrip(int strip, int n_strips);
  const float* sourceRow(int i, int m);
  void makeBlock(int i, int step);
  void subsampleBlock(int i, int y0, int y1);
  void detectBlock(int step);
  void makeDogRows(int y0, int y1);
  void testRows(int y1);
  void interpolateCandidates(int y1);

  const si::Kernels& K_;
  const Params& P_;
  const int o_;
  const cv::Mat& input_;
  const Octave* prev_;
  Octave& oct_;
  const bool detect_;
  const cv::Rect test_area_;
  Workspace& ws_;
  std::vector<Extremum>* found_;
  int* far_steps_;
  int* candidates_;
  const int W_, H_, S_;
  const int L_;  ///< layers built
  const float thr_;

  // Layer i makes block b - lag[i] at step b: by then layer i-1 has rows up to its last row + h_i.
  std::vector<const Kernel*> kern_;  ///< layer i blurs layer i - 1 by kern_[i]; null: subsampled
  std::vector<int> lag_, halo_;
  int max_h_ = 0;
  /// Per layer: ring_size_ rows of the row filter's output, then (layers not stored) the layer's
  /// own rows, a ring of keep_ rows; at ring_off_ in rings_.
  std::vector<int> ring_size_, keep_;
  std::vector<size_t> ring_off_;
  float* rings_ = nullptr;
  std::vector<const float*> rows_;  ///< the column filter's input rows
  // The doubled input rows, blended and padded for the init blur (octave 0 only).
  int up_pad_ = 0;
  float* up_row_ = nullptr;
  float* blend_ = nullptr;

  int n_dog_ = 0;  ///< DoG layers (0 without detection)
  DogView view_;
  float* maxmin_ = nullptr;
  std::vector<Candidate>& pending_;  ///< this strip's candidates, interpolated from next_pending_ on
  size_t next_pending_ = 0;

  // What the sweep has made of each stored layer so far in this call: every row of columns
  // [0, done_cols[i]) (the strips before this one) and rows [0, done_rows[i]) of columns
  // [0, strip_cols[i]). Anything else in the layer's buffer is a previous call's.
  std::vector<int> done_cols_, done_rows_, strip_cols_;
  // The last patch recomputed of each layer (values exact, so valid for the whole call): the
  // patches of the lower layers made for a higher one serve the lower layers' own requests.
  std::vector<PatchMemo> memo_;

  // The current strip: columns [c0_[i], c1_[i]) of layer i, rows of its row filter made so far.
  std::vector<int> c0_, c1_, filled_;
  int tested_ = 0;  ///< next row of the extremum test
  int test_end_ = 0, tx0_ = 0, tx1_ = 0;
  int dx0_ = 0, dx1_ = 0;  ///< the DoG's columns
};

OctaveSweep::OctaveSweep(const si::Kernels& K, const Params& P, int o, const cv::Mat& input, const Octave* prev,
                         Octave& oct, int n_build, bool detect, const cv::Rect& test_area, Workspace& ws,
                         std::vector<Extremum>* found, int* far_steps, int* candidates)
    : K_(K), P_(P), o_(o), input_(input), prev_(prev), oct_(oct), detect_(detect), test_area_(test_area), ws_(ws),
      found_(found), far_steps_(far_steps), candidates_(candidates), W_(oct.w), H_(oct.h), S_(oct.stride),
      L_(n_build), thr_(static_cast<float>(P.threshold)), pending_(ws.candidates), done_cols_(n_build, 0),
      done_rows_(n_build, 0), strip_cols_(n_build, 0), memo_(n_build) {
  planLayers();
  placeLayerRings();
  placeDetectionRings();
}

void OctaveSweep::planLayers() {
  lag_.assign(L_, 0);
  halo_.assign(L_, 0);
  ring_size_.assign(L_, 0);
  kern_.assign(L_, nullptr);
  if (o_ == 0) kern_[0] = &P_.init;
  for (int i = 1; i < L_; ++i) kern_[i] = &P_.kernels[i];
  for (int i = 0; i < L_; ++i) {
    const int h = kern_[i] ? kern_[i]->h : 0;
    lag_[i] = (i == 0 ? 0 : lag_[i - 1]) + (h + kBlock - 1) / kBlock;
    if (kern_[i]) ring_size_[i] = std::min(2 * h + kBlock, H_);
    max_h_ = std::max(max_h_, h);
  }
  for (int i = L_ - 2; i >= 0; --i) halo_[i] = halo_[i + 1] + kern_[i + 1]->h;
  if (detect_)
    for (int& v : halo_) v += 1 + kReach;
}

void OctaveSweep::placeLayerRings() {
  // Rows of the layers not stored: a row of layer i is read by layer i + 1's row filter right
  // after it is made and by the DoG when the last layer makes that row, kBlock * (lag[L - 1] -
  // lag[i]) rows later.
  keep_.assign(L_, 0);
  for (int i = 0; i < L_; ++i) {
    if (oct_.g[i]) continue;
    keep_[i] = 8;
    while (keep_[i] < kBlock * (lag_[L_ - 1] - lag_[i] + 2)) keep_[i] *= 2;
  }
  size_t ring_samples = 0;
  ring_off_.assign(L_, 0);
  for (int i = 0; i < L_; ++i) {
    ring_off_[i] = ring_samples;
    ring_samples += static_cast<size_t>(ring_size_[i] + keep_[i]) * S_;
  }
  rings_ = ws_.rings.get(ring_samples + 128) + oct_.pad;
  up_pad_ = roundUp(std::max(P_.init.h, 1), 16);
  up_row_ = ws_.temp.get(static_cast<size_t>(W_ + 2 * up_pad_ + 64) + input_.cols + 64);
  blend_ = up_row_ + W_ + 2 * up_pad_ + 32;
  rows_.resize(2 * max_h_ + kBlock);
}

void OctaveSweep::placeDetectionRings() {
  // DoG rows (a ring of `depth` rows per layer, made when the last layer makes the row) and their
  // 3-tap max/min (a ring of 8 rows: rows up to y + 1 exist when the extremum test of row y runs).
  n_dog_ = detect_ ? L_ - 1 : 0;
  int depth = 16;
  while (depth < 2 * kReach + 2 * kBlock + 4) depth *= 2;
  view_.depth = depth;
  view_.stride = S_;
  view_.w = W_;
  view_.h = H_;
  // 16 floats ahead of the first row: dog_row writes d[-1].
  view_.ring = detect_ ? ws_.dog_rows.get(static_cast<size_t>(n_dog_) * depth * S_ + 64) + 16 : nullptr;
  maxmin_ = detect_ ? ws_.maxmin.get(static_cast<size_t>(n_dog_) * 2 * kMaxMinRing * S_ + 64) : nullptr;
  if (detect_) ws_.cols.resize(W_ + 32);
}

/// Layer i, row y.
float* OctaveSweep::layerRow(int i, int y) const {
  if (oct_.g[i]) return oct_.row(i, y);
  return rings_ + ring_off_[i] + static_cast<size_t>(ring_size_[i] + (y & (keep_[i] - 1))) * S_;
}

/// The 3-tap max (which = 0) or min (which = 1) of DoG layer k, row y.
float* OctaveSweep::maxMinRow(int k, int y, int which) const {
  return maxmin_ + (static_cast<size_t>(k * 2 + which) * kMaxMinRing + (y % kMaxMinRing)) * S_;
}

/// Rows [0, y1] of columns [0, x1] of stored layer i are this call's.
bool OctaveSweep::made(int i, int y1, int x1) const {
  return x1 < done_cols_[i] || (x1 < strip_cols_[i] && y1 < done_rows_[i]);
}

/// The exact values of layer i on `a` (inside the octave), for a point the rings do not hold (a
/// Newton step that jumped far; rare): recomputed on a patch with the sweep's kernels, from the
/// nearest layer whose values are there (a stored layer where the sweep has made those rows and
/// columns, the octave below, the input), each output with the same arithmetic as in the sweep.
std::vector<float> OctaveSweep::exactPatch(int i, const PatchArea& a) {
  const int pw = a.width();
  std::vector<float> out(static_cast<size_t>(a.height()) * pw + 64);
  if ((oct_.g[i] && made(i, a.y1, a.x1)) || !kern_[i]) {
    for (int y = a.y0; y <= a.y1; ++y)
      for (int x = a.x0; x <= a.x1; ++x)
        out[static_cast<size_t>(y - a.y0) * pw + x - a.x0] =
            kern_[i] ? oct_.row(i, y)[x] : prev_->row(P_.n_layers, 2 * y)[2 * x];
    return out;
  }
  if (oct_.g[i] && a.y0 < done_rows_[i] && made(i, done_rows_[i] - 1, a.x1)) {
    // The rows the sweep has made read as they are, only the rows below recomputed.
    const int split = done_rows_[i];
    const std::vector<float> below = exactPatch(i, {split, a.y1, a.x0, a.x1});
    for (int y = a.y0; y < split; ++y)
      std::copy_n(oct_.row(i, y) + a.x0, pw, out.begin() + static_cast<size_t>(y - a.y0) * pw);
    std::copy_n(below.begin(), static_cast<size_t>(a.y1 - split + 1) * pw,
                out.begin() + static_cast<size_t>(split - a.y0) * pw);
    return out;
  }
  PatchMemo& m = memo_[i];
  if (m.area.contains(a)) {
    const int mw = m.area.width();
    for (int y = a.y0; y <= a.y1; ++y)
      std::copy_n(m.v.begin() + static_cast<size_t>(y - m.area.y0) * mw + (a.x0 - m.area.x0), pw,
                  out.begin() + static_cast<size_t>(y - a.y0) * pw);
    return out;
  }
  const Kernel& k = *kern_[i];
  const int h = k.h;
  const PatchArea source{std::max(0, a.y0 - h), std::min(H_ - 1, a.y1 + h), std::max(0, a.x0 - h),
                         std::min(W_ - 1, a.x1 + h)};
  const std::vector<float> src = i > 0 ? exactPatch(i - 1, source) : doubledInputPatch(source);
  blurPatch(k, src, source, a, out);
  m.area = a;
  m.v = out;
  return out;
}

/// Octave 0, layer 0 on `a`: the doubled input rows.
std::vector<float> OctaveSweep::doubledInputPatch(const PatchArea& a) const {
  const int sw = a.width();
  std::vector<float> src(static_cast<size_t>(a.height()) * sw + 64, 0.f);
  std::vector<float> full(static_cast<size_t>(W_) + 64), blend_row(static_cast<size_t>(input_.cols) + 64);
  for (int m = a.y0; m <= a.y1; ++m) {
    const DoubledRow d = doubledRow(m, input_.rows);
    K_.upsample_row(input_.ptr<uint8_t>(d.r0), input_.ptr<uint8_t>(d.r1), d.wa, d.wb, blend_row.data() + 16,
                    full.data(), input_.cols, 0, input_.cols);
    std::copy(full.begin() + a.x0, full.begin() + a.x1 + 1, src.begin() + static_cast<size_t>(m - a.y0) * sw);
  }
  return src;
}

/// Kernel k applied to `src` (the layer below on `source`: `a` widened by k.h, clipped to the
/// octave) -> `out` on `a`. Row filter on the source rows (BORDER_REFLECT_101 at the octave's
/// sides), then the column filter (the same at its top and bottom).
void OctaveSweep::blurPatch(const Kernel& k, const std::vector<float>& src, const PatchArea& source,
                            const PatchArea& a, std::vector<float>& out) const {
  const int h = k.h, pw = a.width(), sw = source.width();
  std::vector<float> ext(static_cast<size_t>(pw) + 2 * h + 64);
  std::vector<float> rf(static_cast<size_t>(source.height()) * (pw + 64));
  for (int y = source.y0; y <= source.y1; ++y) {
    for (int t = 0; t < pw + 2 * h; ++t)
      ext[t] = src[static_cast<size_t>(y - source.y0) * sw + reflect101(a.x0 - h + t, W_) - source.x0];
    K_.row_filter(ext.data(), rf.data() + static_cast<size_t>(y - source.y0) * (pw + 64), pw, k.taps.data(), k.n);
  }
  std::vector<const float*> col(2 * h + 1);
  std::vector<float> line(static_cast<size_t>(pw) + 64);
  for (int y = a.y0; y <= a.y1; ++y) {
    for (int j = 0; j <= 2 * h; ++j)
      col[j] = rf.data() + static_cast<size_t>(reflect101(y - h + j, H_) - source.y0) * (pw + 64);
    float* o1 = line.data();
    K_.col_filter(col.data(), &o1, 1, pw, k.centre.data(), h);
    std::copy(line.begin(), line.begin() + pw, out.begin() + static_cast<size_t>(y - a.y0) * pw);
  }
}

/// The DoG around (layer, r, c) from exact patches of the Gaussian layers layer-1..layer+2.
void OctaveSweep::exactDogCube(int layer, int r, int c, DogCube* cube) {
  cube->layer = layer;
  cube->r = r;
  cube->c = c;
  std::vector<float> g[4];
  for (int l = 3; l >= 0; --l) g[l] = exactPatch(layer - 1 + l, {r - 1, r + 1, c - 1, c + 1});  // top first: see memo_
  for (int l = 0; l < 3; ++l)
    for (int k = 0; k < 9; ++k) cube->v[l][k / 3][k % 3] = g[l + 1][k] - g[l][k];
}

void OctaveSweep::run() {
  const int n_strips = std::max(1, (W_ + kStripWidth / 2) / kStripWidth);
  const int n_blocks = (H_ + kBlock - 1) / kBlock;
  for (int strip = 0; strip < n_strips; ++strip) {
    beginStrip(strip, n_strips);
    for (int step = 0; step < n_blocks + lag_[L_ - 1]; ++step) {
      for (int i = 0; i < L_; ++i) makeBlock(i, step);
      if (detect_) detectBlock(step);
    }
  }
}

/// The columns, the extremum test's range and the candidates of strip `strip`.
void OctaveSweep::beginStrip(int strip, int n_strips) {
  const int sx0 = strip * kStripWidth, sx1 = strip + 1 == n_strips ? W_ : sx0 + kStripWidth;
  // Columns [c0[i], c1[i]) of layer i: each reads columns [c0[i] - h, c1[i] + h) of layer i - 1,
  // which this strip has made (the halos), so every column made is exact. (Not rounded to a
  // vector boundary: the columns below c0 of a layer kept as a ring were not made here.)
  c0_.assign(L_, 0);
  c1_.assign(L_, 0);
  filled_.assign(L_, 0);
  for (int i = 0; i < L_; ++i) {
    c0_[i] = std::max(0, sx0 - halo_[i]);
    c1_[i] = std::min(W_, sx1 + halo_[i]);
    if (strip > 0) done_cols_[i] = strip_cols_[i];
    strip_cols_[i] = c1_[i];
    done_rows_[i] = 0;
  }
  tested_ = std::max(kBorder, test_area_.y);
  test_end_ = std::min(H_ - kBorder, test_area_.y + test_area_.height);
  tx0_ = std::max({kBorder, sx0, test_area_.x});
  tx1_ = std::min({W_ - kBorder, sx1, test_area_.x + test_area_.width});
  // The DoG on the last layer's exact columns.
  dx0_ = L_ > 1 ? c0_[L_ - 1] : 0;
  dx1_ = L_ > 1 ? c1_[L_ - 1] : 0;
  view_.col_lo = dx0_;
  view_.col_hi = dx1_;
  pending_.clear();
  next_pending_ = 0;
}

/// Row m of the layer that layer i blurs, on the strip's columns of layer i widened by its kernel.
const float* OctaveSweep::sourceRow(int i, int m) {
  if (i > 0) return layerRow(i - 1, m);
  // Octave 0, layer 0: row m of the doubled input (OpenCV's bilinear resize coefficients),
  // the columns the init blur reads.
  const DoubledRow d = doubledRow(m, input_.rows);
  float* out = up_row_ + up_pad_;
  const int h = P_.init.h;
  const int u0 = std::max(0, c0_[0] - h) / 2, u1 = std::min(input_.cols, (c1_[0] + h + 1) / 2 + 1);
  K_.upsample_row(input_.ptr<uint8_t>(d.r0), input_.ptr<uint8_t>(d.r1), d.wa, d.wb, blend_ + 16, out, input_.cols,
                  u0, u1);
  if (c0_[0] - h < 0) fillPad(out, W_, up_pad_, true);
  if (c1_[0] + h > W_) fillPad(out, W_, up_pad_, false);
  return out;
}

/// The block of layer i due at `step` (kBlock rows, the strip's columns): the row filter on the
/// source rows it needs, into the layer's filter ring, then the column filter into its rows.
void OctaveSweep::makeBlock(int i, int step) {
  const int y0 = (step - lag_[i]) * kBlock;
  if (y0 < 0 || y0 >= H_) return;
  const int y1 = std::min(H_, y0 + kBlock);
  if (!kern_[i]) {
    subsampleBlock(i, y0, y1);
    return;
  }
  const int x0 = c0_[i], n = c1_[i] - c0_[i];
  const Kernel& k = *kern_[i];
  float* ring = rings_ + ring_off_[i];
  const int need = std::min(H_ - 1, y1 - 1 + k.h);
  while (filled_[i] <= need) {
    const int m = filled_[i]++;
    K_.row_filter(sourceRow(i, m) + x0 - k.h, ring + static_cast<size_t>(m % ring_size_[i]) * S_ + x0, n,
                  k.taps.data(), k.n);
  }
  for (int j = 0; j < 2 * k.h + (y1 - y0); ++j)
    rows_[j] = ring + static_cast<size_t>(reflect101(y0 + j - k.h, H_) % ring_size_[i]) * S_ + x0;
  float* outs[kBlock];
  for (int y = y0; y < y1; ++y) outs[y - y0] = layerRow(i, y) + x0;
  K_.col_filter(rows_.data(), outs, y1 - y0, n, k.centre.data(), k.h);
  done_rows_[i] = y1;
  for (int y = y0; y < y1; ++y) {
    if (x0 == 0) fillPad(layerRow(i, y), W_, oct_.pad, true);
    if (c1_[i] == W_) fillPad(layerRow(i, y), W_, oct_.pad, false);
  }
}

/// Octave o > 0, layer 0, rows [y0, y1): every second pixel of layer n_layers of the octave below.
void OctaveSweep::subsampleBlock(int i, int y0, int y1) {
  const int x0 = c0_[i];
  for (int y = y0; y < y1; ++y) {
    const float* src = prev_->row(P_.n_layers, 2 * y);
    float* dst = layerRow(i, y);
    for (int x = x0; x < c1_[i]; ++x) dst[x] = src[2 * x];
    if (x0 == 0) fillPad(dst, W_, oct_.pad, true);
    if (c1_[i] == W_) fillPad(dst, W_, oct_.pad, false);
  }
}

/// The last layer's newest block: the DoG rows of every layer and their 3-tap max/min, the
/// extremum test of the rows whose 3x3x3 neighbourhoods are now complete, then the
/// interpolation of the candidates kReach rows above.
void OctaveSweep::detectBlock(int step) {
  const int y0 = (step - lag_[L_ - 1]) * kBlock;
  if (y0 < 0 || y0 >= H_) return;
  const int y1 = std::min(H_, y0 + kBlock);
  makeDogRows(y0, y1);
  testRows(y1);
  interpolateCandidates(y1);
}

void OctaveSweep::makeDogRows(int y0, int y1) {
  for (int y = y0; y < y1; ++y)
    for (int k = 0; k < n_dog_; ++k) {
      K_.dog_row(layerRow(k, y) + dx0_, layerRow(k + 1, y) + dx0_, dogRow(k, y) + dx0_, maxMinRow(k, y, 0) + dx0_,
                 maxMinRow(k, y, 1) + dx0_, dx1_ - dx0_);
    }
}

/// The extremum test of the rows up to y1 - 2 (rows up to y1 - 1 exist), candidates into pending_.
void OctaveSweep::testRows(int y1) {
  for (; tested_ < std::min(y1 - 1, test_end_); ++tested_) {
    const int yy = tested_;
    if (tx0_ >= tx1_) continue;
    for (int layer = 1; layer <= P_.n_layers; ++layer) {
      const float* mx[9];
      const float* mn[9];
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
          mx[3 * a + b] = maxMinRow(layer - 1 + a, yy - 1 + b, 0);
          mn[3 * a + b] = maxMinRow(layer - 1 + a, yy - 1 + b, 1);
        }
      const int n = K_.extrema_row(dogRow(layer, yy), mx, mn, tx0_, tx1_, thr_, ws_.cols.data());
      for (int q = 0; q < n; ++q) pending_.push_back({layer, yy, ws_.cols[q]});
      *candidates_ += n;
    }
  }
}

/// The interpolation of the pending candidates kReach rows above y1 - 1 (all of them at the
/// octave's last row), kept extrema into *found_.
void OctaveSweep::interpolateCandidates(int y1) {
  view_.row_hi = y1 - 1;
  view_.row_lo = y1 - view_.depth;
  const bool last = y1 == H_;
  auto exact = [this](int layer, int r, int c, DogCube* cube) { exactDogCube(layer, r, c, cube); };
  for (; next_pending_ < pending_.size() && (last || pending_[next_pending_].r + kReach <= view_.row_hi);
       ++next_pending_) {
    Extremum x;
    if (interpolate(view_, exact, P_, o_, pending_[next_pending_], &x, far_steps_) == Interpolated::kKept)
      found_->push_back(x);
  }
}

/// Builds layers 0..n_build-1 of octave `o` in top-to-bottom sweeps over vertical strips,
/// kBlock rows at a time, with OpenCV's arithmetic. Layers 1..n_layers are stored (Octave); the
/// others are kept as rings of their newest rows (the next layer's filter and the DoG read them).
/// When `detect`, also the DoG rows (a ring), their extremum test at layers 1..n_layers in
/// `test_area` (octave px) and the interpolation of the candidates found (counted in
/// *candidates; extrema appended to *found; Newton steps at points out of the DoG rows and
/// columns still held run on exactly recomputed patches, counted in *far_steps). Octave 0 starts
/// from the 8-bit input (doubled, then blurred by params.init), octave o > 0 from every second
/// pixel of layer n_layers of `prev`. Strips keep the rows in flight (the wavefront's lag times
/// the layers) in L2: layer i of a strip is computed on the strip widened by the columns the later
/// layers read (their kernels' half-widths, plus, for the DoG, the 3-tap max/min and the
/// interpolation's moves), so every pixel gets the same arithmetic as in one full-width sweep.
void sweepOctave(const si::Kernels& K, const Params& P, int o, const cv::Mat& input, const Octave* prev,
                 Octave& oct, int n_build, bool detect, const cv::Rect& test_area, Workspace& ws,
                 std::vector<Extremum>* found, int* far_steps, int* candidates) {
  OctaveSweep(K, P, o, input, prev, oct, n_build, detect, test_area, ws, found, far_steps, candidates).run();
}

/// The gradient window of radius >= `radius` around (r, c) of `layer` (see GradientWindow): the
/// thread's current one when it is that, else a new empty one.
GradientWindow& gradientWindow(const Octave& oct, int layer, int r, int c, int radius, KeypointScratch& s) {
  GradientWindow& w = s.window;
  if (w.generation == oct.generation && w.layer == layer && w.r == r && w.c == c && w.radius >= radius) return w;
  // Columns -radius - 16 .. radius + 16 (the kernels' vector loads run past the window).
  const int pitch = roundUp(2 * radius + 1 + 32, 16);
  const size_t floats = static_cast<size_t>(2 * radius + 1) * pitch + 64;
  float* mag = s.window_mag.get(floats);
  float* ori = s.window_ori.get(floats);
  if (s.window_mag.size() > s.window_zeroed) {  // lanes past a row's samples are read, never used
    std::fill(mag, mag + s.window_mag.size(), 0.f);
    std::fill(ori, ori + s.window_ori.size(), 0.f);
    s.window_zeroed = s.window_mag.size();
  }
  const ptrdiff_t centre = static_cast<ptrdiff_t>(radius) * pitch + radius + 16;
  w.p.mag = mag + centre;
  w.p.ori = ori + centre;
  w.p.pitch = pitch;
  w.p.i0 = std::max(-radius, 1 - r);
  w.p.i1 = std::min(radius, oct.h - 2 - r);
  w.p.j0 = std::max(-radius, 1 - c);
  w.p.j1 = std::min(radius, oct.w - 2 - c);
  w.generation = oct.generation;
  w.layer = layer;
  w.r = r;
  w.c = c;
  w.radius = radius;
  w.img = oct.row(layer, r) + c;
  w.stride = oct.stride;
  w.lo.assign(2 * radius + 1, 1);
  w.hi.assign(2 * radius + 1, 0);
  return w;
}

/// Makes sure the samples of row i, columns [ja, jb] (clipped to the window), are computed.
void coverRow(const si::Kernels& K, GradientWindow& w, int i, int ja, int jb) {
  ja = std::max(ja, w.p.j0);
  jb = std::min(jb, w.p.j1);
  if (i < w.p.i0 || i > w.p.i1 || ja > jb) return;
  int& lo = w.lo[i + w.radius];
  int& hi = w.hi[i + w.radius];
  auto compute = [&](int a, int b) {
    const ptrdiff_t o = static_cast<ptrdiff_t>(i) * w.p.pitch + a;
    K.gradient_span(w.img + static_cast<ptrdiff_t>(i) * w.stride + a, w.stride, const_cast<float*>(w.p.mag) + o,
                    const_cast<float*>(w.p.ori) + o, b - a + 1);
  };
  if (lo > hi) {
    compute(ja, jb);
    lo = ja;
    hi = jb;
    return;
  }
  if (ja < lo) {
    compute(ja, lo - 1);
    lo = ja;
  }
  if (jb > hi) {
    compute(hi + 1, jb);
    hi = jb;
  }
}

/// calcSIFTDescriptor's window radius for a keypoint of sigma `scl` (octave px).
int descriptorRadius(const Octave& oct, float scl) {
  const float hist_width = kDescrSclFactor * scl;
  const int radius = cvRoundF(hist_width * 1.4142135623730951f * (kDescrWidth + 1) * 0.5f);
  return std::min(radius, static_cast<int>(std::sqrt(static_cast<double>(oct.w) * oct.w +
                                                      static_cast<double>(oct.h) * oct.h)));
}

float keypointScale(const Params& P, int layer, float xi) {
  return P.sigma * std::pow(2.f, (layer + xi) / P.n_layers);
}

/// The keypoints (one per orientation peak) of an interpolated extremum, appended to *out. With
/// `descriptor_window`, the gradient window is made large enough for the descriptors too
/// (describeSpot then grows it instead of starting another).
void orientations(const si::Kernels& K, const Params& P, const Octave& oct, const Extremum& e,
                  bool descriptor_window, KeypointScratch& s, std::vector<Kp>* out) {
  const int o = e.octave;
  Kp base;
  cv::KeyPoint& kpt = base.kp;
  kpt.pt.x = (e.c + e.xc) * (1 << o);
  kpt.pt.y = (e.r + e.xr) * (1 << o);
  kpt.octave = o + (e.layer << 8) + (cvRoundD((e.xi + 0.5) * 255) << 16);
  kpt.size = keypointScale(P, e.layer, e.xi) * (1 << o) * 2;
  kpt.response = std::abs(e.contr);
  base.octave = o;
  base.layer = e.layer;
  base.ptf_x = e.c + e.xc;
  base.ptf_y = e.r + e.xr;
  base.scl = kpt.size * 0.5f / (1 << o);

  const float scl_octv = kpt.size * 0.5f / (1 << o);
  const int radius = cvRoundF(kOriRadius * scl_octv);
  const float sigma = kOriSigFactor * scl_octv;
  GradientWindow& w = gradientWindow(oct, e.layer, e.r, e.c,
                                     descriptor_window ? std::max(radius, descriptorRadius(oct, base.scl)) : radius, s);
  for (int i = -radius; i <= radius; ++i) coverRow(K, w, i, -radius, radius);
  const si::GradientPatch& p = w.p;
  float raw[kOriBins + 4];
  float* temp = raw + 2;
  if (!p.empty()) {
    K.orientation_hist(p, radius, sigma, kOriBins, temp, s.gauss.get(2 * radius + 64));
  } else {
    std::fill(temp, temp + kOriBins, 0.f);
  }
  constexpr int n = kOriBins;
  temp[-1] = temp[n - 1];
  temp[-2] = temp[n - 2];
  temp[n] = temp[0];
  temp[n + 1] = temp[1];
  float hist[kOriBins];
  K.orientation_smooth(temp, hist, n);
  float omax = hist[0];
  for (int i = 1; i < n; ++i) omax = std::max(omax, hist[i]);
  const float mag_thr = omax * kOriPeakRatio;
  for (int j = 0; j < n; ++j) {
    const int l = j > 0 ? j - 1 : n - 1;
    const int r2 = j < n - 1 ? j + 1 : 0;
    if (hist[j] > hist[l] && hist[j] > hist[r2] && hist[j] >= mag_thr) {
      float bin = j + 0.5f * (hist[l] - hist[r2]) / (hist[l] - 2 * hist[j] + hist[r2]);
      bin = bin < 0 ? n + bin : bin >= n ? bin - n : bin;
      Kp k = base;
      k.kp.angle = 360.f - (360.f / n) * bin;
      if (std::abs(k.kp.angle - 360.f) < FLT_EPSILON) k.kp.angle = 0.f;
      out->push_back(k);
    }
  }
}

/// calcSIFTDescriptor for every keypoint of one spot (same octave, layer, position, size), on one
/// gradient window grown as each descriptor needs. dst rows are written as CV_32F integers 0..255.
void describeSpot(const si::Kernels& K, const Octave& oct, const Kp* kps, int count, KeypointScratch& s,
                  float* const* dst) {
  const Kp& k0 = kps[0];
  const int pr = cvRoundF(k0.ptf_y), pc = cvRoundF(k0.ptf_x);
  const float hist_width = kDescrSclFactor * k0.scl;
  const int radius = descriptorRadius(oct, k0.scl);
  GradientWindow& w = gradientWindow(oct, k0.layer, pr, pc, radius, s);
  const si::GradientPatch& p = w.p;
  si::DescriptorScratch ds;
  ds.weights = s.weights.get(si::kDescrBlock * 8 * 16 + 64);
  s.index.resize(si::kDescrBlock * 16 + 16);
  s.bits.resize(si::kDescrBlock);
  ds.index = s.index.data();
  ds.bits = s.bits.data();
  ds.gauss = s.gauss.get(2 * radius + 64);
  ds.slots = s.slots();
  ds.sum = s.sum.get(si::kDescrSlotFloats + 64);
  for (int q = 0; q < count; ++q) {
    float ori = 360.f - kps[q].kp.angle;
    if (std::abs(ori - 360.f) < FLT_EPSILON) ori = 0.f;
    const float cos_t = std::cos(ori * static_cast<float>(CV_PI / 180)) / hist_width;
    const float sin_t = std::sin(ori * static_cast<float>(CV_PI / 180)) / hist_width;
    float raw[kDescrLen];
    if (!p.empty()) {
      // The samples this descriptor reads (rows max(p.i0, -radius)..), then its histogram.
      const int i0 = std::max(p.i0, -radius), i1 = std::min(p.i1, radius);
      s.columns_a.resize(2 * radius + 1);
      s.columns_b.resize(2 * radius + 1);
      K.descriptor_columns(radius, cos_t, sin_t, p, s.columns_a.data(), s.columns_b.data());
      for (int i = i0; i <= i1; ++i) coverRow(K, w, i, s.columns_a[i - i0], s.columns_b[i - i0]);
      K.descriptor_hist(p, radius, cos_t, sin_t, ori, ds, raw);
    } else {
      std::fill(raw, raw + kDescrLen, 0.f);
    }
    K.descriptor_finish(raw, dst[q]);
  }
}

/// Runs body(begin, end) over [0, n) in chunks on up to `threads` threads (1 = inline).
template <class F>
void parallelChunks(int n, int threads, int chunk, F body) {
  const int chunks = (n + chunk - 1) / chunk;
  if (threads == 1 || chunks <= 1) {
    body(0, n);
    return;
  }
  cv::parallel_for_(cv::Range(0, chunks), [&](const cv::Range& r) {
    body(r.start * chunk, std::min(n, r.end * chunk));
  });
}

bool strongerFirst(const cv::KeyPoint& a, const cv::KeyPoint& b) {
  if (a.response != b.response) return a.response > b.response;
  if (a.pt.y != b.pt.y) return a.pt.y < b.pt.y;
  if (a.pt.x != b.pt.x) return a.pt.x < b.pt.x;
  if (a.size != b.size) return a.size < b.size;
  return a.angle < b.angle;
}

/// A moment of the wall clock and of the calling thread's CPU time (ms), for the stage times.
struct StageTime {
  double wall, cpu;
  static StageTime now() {
    timespec c{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c);
    return {std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count(),
            1e3 * static_cast<double>(c.tv_sec) + 1e-6 * static_cast<double>(c.tv_nsec)};
  }
};
double wallMs(StageTime a, StageTime b) { return b.wall - a.wall; }
double cpuMs(StageTime a, StageTime b) { return b.cpu - a.cpu; }

/// Keypoint size of octave o (cv::SIFT convention, work-image px): sigma 2^((layer+xi)/n) 2^o,
/// layer + xi in (0.5, n + 0.5).
void octaveSizeRange(const Params& P, int o, double* lo, double* hi) {
  *lo = P.sigma * std::pow(2., 0.5 / P.n_layers) * std::ldexp(1., o) * 0.999;
  *hi = P.sigma * std::pow(2., (P.n_layers + 0.5) / P.n_layers) * std::ldexp(1., o) * 1.001;
}

/// Octave sizes (doubled input: firstOctave = -1) in ws.octaves, down to the last octave whose
/// keypoints can be as small as call.max_size (with `prune`; else all of them).
void sizeOctaves(const cv::Mat& gray8, const Params& P, const FastSiftCall& call, bool prune, Workspace& ws) {
  const int W0 = gray8.cols * 2, H0 = gray8.rows * 2;
  const int n_octaves = cvRoundD(std::log(static_cast<double>(std::min(W0, H0))) / std::log(2.) - 2) + 1;
  int last_octave = n_octaves - 1;
  if (prune) {
    while (last_octave >= 0) {
      double lo, hi;
      octaveSizeRange(P, last_octave, &lo, &hi);
      if (lo <= call.max_size) break;
      --last_octave;
    }
  }
  ws.octaves.resize(std::max(0, last_octave + 1));
  int max_h = P.init.h;
  for (const Kernel& k : P.kernels) max_h = std::max(max_h, k.h);
  const int pad = roundUp(std::max(max_h, 1), 16);
  for (int o = 0, w = W0, h = H0; o <= last_octave; ++o, w /= 2, h /= 2) {
    Octave& oct = ws.octaves[o];
    oct.w = w;
    oct.h = h;
    oct.pad = pad;
    oct.stride = roundUp(w + 2 * pad + 32, 16);
  }
}

/// Layers 1..n_layers of every octave placed in the workspace's pyramid buffer (the sweep keeps
/// the others as rings), and a new generation for each octave.
void placeStoredLayers(const Params& P, Workspace& ws) {
  size_t total = 0;
  for (const Octave& oct : ws.octaves) total += static_cast<size_t>(P.n_layers) * oct.h * oct.stride + 64;
  float* mem = ws.pyramid.get(total + 64);
  for (Octave& oct : ws.octaves) {
    oct.g.assign(P.n_layers + 3, nullptr);
    oct.generation = ++generation;
    const size_t plane = static_cast<size_t>(oct.h) * oct.stride;
    for (int i = 1; i <= P.n_layers; ++i, mem += plane) oct.g[i] = mem + oct.pad;
    mem += 64;
  }
}

/// Per octave: whether it can hold keypoints of a size in [call.min_size, call.max_size] (always
/// without `prune`).
std::vector<bool> searchedOctaves(const Params& P, const FastSiftCall& call, bool prune, size_t n_octaves) {
  std::vector<bool> search(n_octaves, true);
  for (size_t o = 0; o < n_octaves; ++o) {
    double lo, hi;
    octaveSizeRange(P, static_cast<int>(o), &lo, &hi);
    if (prune) search[o] = hi >= call.min_size && lo <= call.max_size;
  }
  return search;
}

/// The extremum test where keypoints are wanted: call.roi (work px) in octave px, widened by 4
/// px (an extremum can move that far while it is interpolated); the whole octave without a roi.
cv::Rect testArea(const FastSiftCall& call, bool prune, int o, const Octave& oct) {
  cv::Rect test_area(0, 0, oct.w, oct.h);
  if (call.roi.area() > 0 && prune) {
    const double to_oct = 2.0 / (1 << o);  // octave 0 is the doubled image
    const int x0 = static_cast<int>(std::floor(call.roi.x * to_oct)) - 4;
    const int y0 = static_cast<int>(std::floor(call.roi.y * to_oct)) - 4;
    const int x1 = static_cast<int>(std::ceil((call.roi.x + call.roi.width) * to_oct)) + 4;
    const int y1 = static_cast<int>(std::ceil((call.roi.y + call.roi.height) * to_oct)) + 4;
    test_area = cv::Rect(x0, y0, x1 - x0, y1 - y0) & test_area;
  }
  return test_area;
}

/// Scale space and extrema, octave by octave: every octave of ws.octaves built as far as a search
/// or a later octave needs it, the octaves in `search` searched. Returns the extrema sorted by
/// octave, layer, row and column, one per spot; stage times and counts added to *stats.
std::vector<Extremum> findExtrema(const si::Kernels& K, const Params& P, const cv::Mat& gray8,
                                  const FastSiftCall& call, bool prune, const std::vector<bool>& search,
                                  Workspace& ws, FastSiftStats* stats) {
  std::vector<Extremum> extrema;
  const int last_octave = static_cast<int>(ws.octaves.size()) - 1;
  for (int o = 0; o <= last_octave; ++o) {
    Octave& oct = ws.octaves[o];
    const bool detect = search[o] && oct.w > 2 * kBorder && oct.h > 2 * kBorder;
    // Layers above n_layers only feed the DoG; an octave not searched needs layers 0..n_layers
    // (layer n_layers is the next octave's base), and only if a later octave is built.
    const int n_build = detect ? P.n_layers + 3 : (o < last_octave ? P.n_layers + 1 : 0);
    if (n_build == 0) continue;
    const auto t0 = StageTime::now();
    ws.candidates.clear();
    const cv::Rect test_area = testArea(call, prune, o, oct);
    const size_t first = extrema.size();
    int far_steps = 0, candidates = 0;
    sweepOctave(K, P, o, gray8, o > 0 ? &ws.octaves[o - 1] : nullptr, oct, n_build, detect && test_area.area() > 0,
                test_area, ws, &extrema, &far_steps, &candidates);
    const auto t1 = StageTime::now();
    stats->scale_space_ms += wallMs(t0, t1);
    stats->scale_space_cpu_ms += cpuMs(t0, t1);
    ++stats->octaves_built;
    if (!detect) continue;
    ++stats->octaves_searched;
    stats->candidates += candidates;
    stats->far_steps += far_steps;
    // Several candidates can converge on the same spot: cv::SIFT keeps one (removeDuplicatedSorted).
    std::sort(extrema.begin() + first, extrema.end());
    extrema.erase(std::unique(extrema.begin() + first, extrema.end(),
                              [](const Extremum& a, const Extremum& b) { return a.sameSpot(b); }),
                  extrema.end());
    const auto t1e = StageTime::now();
    stats->localise_ms += wallMs(t1, t1e);
    stats->localise_cpu_ms += cpuMs(t1, t1e);
  }
  return extrema;
}

/// What the keypoint stages read.
struct KeypointStage {
  const si::Kernels& K;
  const Params& P;
  const std::vector<Octave>& octaves;
  const FastSiftCall& call;
  bool fused;        ///< no strongest-N cut: every keypoint described with its orientation
  bool size_filter;  ///< keypoints outside [call.min_size, call.max_size] dropped
  /// Size in cv::SIFT's convention (firstOctave folded in).
  bool wanted(const Kp& k) const {
    const double size = k.kp.size * 0.5f;
    return !size_filter || (size >= call.min_size && size <= call.max_size);
  }
};

/// The keypoints of extrema [b, e) into `part` (and, fused, their descriptors).
void orientChunk(const KeypointStage& st, const std::vector<Extremum>& extrema, int b, int e, KeypointPart& part) {
  KeypointScratch& s = keypointScratch();
  float* rows[64];
  for (int q = b; q < e; ++q) {
    const Extremum& x = extrema[q];
    const Octave& oct = st.octaves[x.octave];
    const size_t first = part.kps.size();
    orientations(st.K, st.P, oct, x, st.fused, s, &part.kps);
    size_t kept = first;
    for (size_t i = first; i < part.kps.size(); ++i)
      if (st.wanted(part.kps[i])) part.kps[kept++] = part.kps[i];
    part.kps.resize(kept);
    if (!st.fused || kept == first) continue;
    const int cnt = static_cast<int>(kept - first);
    part.desc.resize(part.kps.size() * kDescrLen);
    for (int i = 0; i < cnt; ++i) rows[i] = part.desc.data() + (first + i) * kDescrLen;
    for (int i = 0; i < cnt; i += 64)
      describeSpot(st.K, oct, &part.kps[first + i], std::min(64, cnt - i), s, rows + i);
  }
}

/// Orientation and descriptors, in spatial order (extrema are sorted by octave, layer, row,
/// column) so that neighbouring windows share the gradient rows in cache: the keypoints (and,
/// fused, descriptors) in `parts`, one part per chunk of extrema.
void orientExtrema(const KeypointStage& st, const std::vector<Extremum>& extrema, int threads,
                   std::vector<KeypointPart>& parts) {
  const int ne = static_cast<int>(extrema.size());
  constexpr int kChunk = 32;
  // Kept from call to call (cleared, not freed): a frame allocates nothing here once warm.
  if (parts.size() < static_cast<size_t>((ne + kChunk - 1) / kChunk + 1)) parts.resize((ne + kChunk - 1) / kChunk + 1);
  for (KeypointPart& part : parts) {
    part.kps.clear();
    part.desc.clear();
  }
  parallelChunks(ne, threads, kChunk,
                 [&](int b, int e) { orientChunk(st, extrema, b, e, parts[b / kChunk]); });
}

/// The keypoints of all parts, in order, in cv::SIFT's convention (firstOctave = -1 folded into
/// octave, position and size); fused: each one's descriptor in *desc_of.
void gatherKeypoints(const std::vector<KeypointPart>& parts, bool fused, std::vector<Kp>* kps,
                     std::vector<const float*>* desc_of) {
  for (const KeypointPart& part : parts) {
    for (size_t i = 0; i < part.kps.size(); ++i) {
      kps->push_back(part.kps[i]);
      if (fused) desc_of->push_back(part.desc.data() + i * kDescrLen);
    }
  }
  for (Kp& k : *kps) {
    k.kp.octave = (k.kp.octave & ~255) | ((k.kp.octave - 1) & 255);
    k.kp.pt *= 0.5f;
    k.kp.size *= 0.5f;
  }
}

/// Indices of kps strongest first (strongerFirst), cut to max_features when > 0.
std::vector<int> strongestFirstOrder(const std::vector<Kp>& kps, int max_features) {
  std::vector<int> order(kps.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return strongerFirst(kps[a].kp, kps[b].kp); });
  if (max_features > 0 && static_cast<int>(order.size()) > max_features) order.resize(max_features);
  return order;
}

/// Where each spot (same octave, layer, position, size) starts in kps[kept[...]], and kept.size().
std::vector<int> spotStarts(const std::vector<Kp>& kps, const std::vector<int>& kept) {
  std::vector<int> spot_start;
  for (size_t i = 0; i < kept.size(); ++i) {
    const Kp& k = kps[kept[i]];
    const Kp* p = i ? &kps[kept[i - 1]] : nullptr;
    if (!p || k.octave != p->octave || k.layer != p->layer || k.ptf_x != p->ptf_x || k.ptf_y != p->ptf_y ||
        k.scl != p->scl)
      spot_start.push_back(static_cast<int>(i));
  }
  spot_start.push_back(static_cast<int>(kept.size()));
  return spot_start;
}

/// Descriptors of the keypoints kept (kps[order[q]] into descriptors row q), spot by spot in
/// spatial order (kps is in that order).
void describeKept(const KeypointStage& st, const std::vector<Kp>& kps, const std::vector<int>& order, int threads,
                  cv::Mat* descriptors) {
  const int nk = static_cast<int>(order.size());
  std::vector<int> kept(order);
  std::sort(kept.begin(), kept.end());
  std::vector<int> row_of(kps.size(), -1);
  for (int q = 0; q < nk; ++q) row_of[order[q]] = q;
  const std::vector<int> spot_start = spotStarts(kps, kept);
  const int ns = static_cast<int>(spot_start.size()) - 1;
  parallelChunks(ns, threads, 32, [&](int b, int e) {
    KeypointScratch& s = keypointScratch();
    std::vector<Kp> group;
    float* rows[64];
    for (int sp = b; sp < e; ++sp) {
      group.clear();
      for (int i = spot_start[sp]; i < spot_start[sp + 1]; ++i) group.push_back(kps[kept[i]]);
      const int cnt = static_cast<int>(group.size());
      for (int i = 0; i < cnt; ++i) rows[i] = descriptors->ptr<float>(row_of[kept[spot_start[sp] + i]]);
      for (int i = 0; i < cnt; i += 64)
        describeSpot(st.K, st.octaves[group[0].octave], &group[i], std::min(64, cnt - i), s, rows + i);
    }
  });
}

}  // namespace

void fastSiftDetectAndCompute(const cv::Mat& gray8, const SiftOptions& opt, const FastSiftCall& call,
                              std::vector<cv::KeyPoint>* keypoints, cv::Mat* descriptors) {
  CV_Assert(gray8.type() == CV_8UC1 && !gray8.empty());
  FastSiftStats stats;
  const si::Kernels& K = kernelsFor(call.isa);
  const Params P = makeParams(opt);
  Workspace& ws = workspace();
  const bool prune = opt.max_features == 0;
  sizeOctaves(gray8, P, call, prune, ws);
  placeStoredLayers(P, ws);
  const std::vector<bool> search = searchedOctaves(P, call, prune, ws.octaves.size());
  const std::vector<Extremum> extrema = findExtrema(K, P, gray8, call, prune, search, ws, &stats);
  stats.extrema = static_cast<int>(extrema.size());

  const KeypointStage st{K, P, ws.octaves, call, /*fused=*/opt.max_features == 0,
                         /*size_filter=*/prune && (call.min_size > 0 || call.max_size < 1e30)};
  const auto t2 = StageTime::now();
  orientExtrema(st, extrema, call.threads, ws.parts);
  std::vector<Kp> kps;
  std::vector<const float*> desc_of;  // fused: each keypoint's descriptor
  gatherKeypoints(ws.parts, st.fused, &kps, &desc_of);
  const std::vector<int> order = strongestFirstOrder(kps, opt.max_features);
  const int nk = static_cast<int>(order.size());
  const auto t4 = StageTime::now();
  descriptors->create(nk, kDescrLen, CV_32F);
  stats.describe_ms = wallMs(t2, t4);
  stats.describe_cpu_ms = cpuMs(t2, t4);
  if (st.fused) {
    for (int q = 0; q < nk; ++q) std::memcpy(descriptors->ptr<float>(q), desc_of[order[q]], kDescrLen * sizeof(float));
  } else {
    describeKept(st, kps, order, call.threads, descriptors);
  }
  const auto t5 = StageTime::now();
  if (!st.fused) {  // the kept keypoints' descriptors
    stats.describe_ms += wallMs(t4, t5);
    stats.describe_cpu_ms += cpuMs(t4, t5);
  }
  keypoints->resize(nk);
  for (int q = 0; q < nk; ++q) (*keypoints)[q] = kps[order[q]].kp;
  const auto t6 = StageTime::now();
  stats.output_ms = wallMs(t4, t6) - (st.fused ? 0 : wallMs(t4, t5));
  stats.output_cpu_ms = cpuMs(t4, t6) - (st.fused ? 0 : cpuMs(t4, t5));
  stats.keypoints = nk;
  if (call.stats) *call.stats = stats;
}

}  // namespace refgrasp::detector
