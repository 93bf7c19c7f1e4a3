#pragma once
// The SIMD kernels of the fast SIFT (sift_fast.h): one table of plain function pointers per
// instruction set. Each table lives in its own translation unit compiled for that instruction set
// (sift_fast_scalar.cpp, sift_fast_avx2.cpp, sift_fast_avx512.cpp, see CMakeLists.txt), all built
// from the one generic source sift_fast_kernels.inl.
//
// Every kernel computes exactly the same floating-point operations whatever the vector width
// (explicit fused multiply-adds, no contraction left to the compiler, the same summation order),
// so the three tables give bit-identical results; the test SiftFast.EveryDispatchPathAgrees
// checks it.
//
// Rule for the per-ISA translation units: they include nothing but this header, <immintrin.h>
// and C headers, and define everything in an anonymous namespace. An inline function or template
// shared with other translation units (anything from the C++ standard library) would be emitted
// there with AVX-512 instructions and could be picked by the linker for the whole program.
#include <cstddef>
#include <cstdint>

namespace refgrasp::detector::sift_internal {

/// Gradients around one keypoint, computed from its Gaussian image into a window: sample (i, j)
/// is image row r + i, column c + j, at mag[i * pitch + j] (mag points at (r, c)). Only rows
/// i0..i1 and columns j0..j1 (inclusive offsets) exist: 0 < row < rows-1, 0 < col < cols-1 (and
/// within a row only the columns the window was computed for: see gradientPatch).
struct GradientPatch {
  const float* mag = nullptr;  ///< sqrt(dx^2 + dy^2), dx = I(r, c+1) - I(r, c-1), dy = I(r-1, c) - I(r+1, c)
  const float* ori = nullptr;  ///< atan2(dy, dx) in degrees, [0, 360] (OpenCV's fastAtan2 polynomial)
  int pitch = 0;
  int i0 = 0, i1 = -1, j0 = 0, j1 = -1;
  bool empty() const { return i0 > i1 || j0 > j1; }
};

/// Scratch memory of one descriptor computation (no allocation per keypoint): kDescrBlock
/// vectors of samples between the vector pass and the scatter pass, and the sample sums.
constexpr int kDescrBlock = 32;
/// The descriptor's sample sums: one slot of 8 floats per (top-left cell, first orientation bin)
/// of a sample's trilinear footprint, i.e. per (rr, cc, o0) with rr, cc = 0..4 (the sample's
/// top-left cell of the 4x4 grid plus a border row/column: r0 + 1, c0 + 1) and o0 = 0..7, at
/// ((rr * 5 + cc) * 8 + o0) * 8; float k = dr * 4 + dc * 2 + do of a slot is the weight that
/// goes to cell (rr + dr, cc + dc), bin o0 + do (mod 8). A sample is then one 8-float add; the
/// slots are folded into the 4x4x8 histogram once per descriptor. kDescrCopies interleaved copies
/// (a power of two; the sample in column j uses copy j mod kDescrCopies) so that consecutive
/// samples, which mostly share a slot, do not wait on each other's stores.
constexpr int kDescrSlotFloats = 25 * 8 * 8;
constexpr int kDescrCopies = 4;
struct DescriptorScratch {
  float* weights = nullptr;  ///< kDescrBlock x 8 x 16 floats
  int32_t* index = nullptr;  ///< kDescrBlock x 16 ints
  uint32_t* bits = nullptr;  ///< kDescrBlock lane masks
  float* gauss = nullptr;    ///< 2 x radius + 48 floats (the separable Gaussian weight)
  /// kDescrCopies x kDescrSlotFloats floats, all zero on entry and left all zero on return
  /// (cleared as they are read: no clearing pass per descriptor).
  float* slots = nullptr;
  float* sum = nullptr;      ///< kDescrSlotFloats floats: the copies summed
};

struct Kernels {
  const char* name;
  /// out[x] = k[n-1]*in[x+n-1] + (... + (k[1]*in[x+1] + k[0]*in[x])), one rounding per fused
  /// multiply-add, left to right; `in` holds width + n - 1 samples.
  void (*row_filter)(const float* in, float* out, int width, const float* k, int n);
  /// Output rows q = 0..n_out-1: out[q][x] = kc[h]*(rows[q][x] + rows[q+2h][x]) + (... +
  /// (kc[1]*(rows[q+h-1][x] + rows[q+h+1][x]) + kc[0]*rows[q+h][x])), fused multiply-adds; kc[j]
  /// is the tap at distance j from the centre; rows has 2h + n_out entries.
  void (*col_filter)(const float* const* rows, float* const* out, int n_out, int width, const float* kc,
                     int h);
  /// Columns [2 m0, 2 m1) of the 2x up-sampling of one 8-bit row of width w (OpenCV's bilinear
  /// resize, exact in float): out[2m] = .25 a[m-1] + .75 a[m], out[2m+1] = .75 a[m] + .25 a[m+1]
  /// with a = wa*row0 + wb*row1 (weights 1, .75 or .25) clamped at the row's ends (out[0] = a[0],
  /// out[2w-1] = a[w-1]); a is written to blend[m0-1 .. m1].
  void (*upsample_row)(const uint8_t* row0, const uint8_t* row1, float wa, float wb, float* blend,
                       float* out, int w, int m0, int m1);
  /// d[x] = b[x] - a[x]; mx/mn: max/min of d[x-1..x+1] for x in [1, width-1) (a[-1] and b[-1]
  /// are read: rows are padded). Writes d[-1 .. width + 16).
  void (*dog_row)(const float* a, const float* b, float* d, float* mx, float* mn, int width);
  /// Scale-space extremum test at columns [c0, c1) of the middle DoG row: |v| > thr and v >= the
  /// 3x3x3 maximum (v > 0) or v <= the 3x3x3 minimum (v < 0). mx[k]/mn[k], k = 0..8: 3-tap
  /// max/min rows of the DoG layers below, at and above, rows y-1, y, y+1 (k = 3*layer + row).
  /// Writes the columns found to cols, returns their count.
  int (*extrema_row)(const float* centre, const float* const* mx, const float* const* mn, int c0,
                     int c1, float thr, int32_t* cols);
  /// Gradient magnitude and angle (see GradientPatch) of the n pixels p[0 .. n-1] of an image
  /// with row stride `stride` into mag[0 .. n-1], ori[0 .. n-1]; writes may run up to 15 floats
  /// past n (and reads 16 past p[n]).
  void (*gradient_span)(const float* p, int stride, float* mag, float* ori, int n);
  /// OpenCV's orientation histogram (n bins, unsmoothed) of the patch samples with |i|, |j| <=
  /// radius, weighted by exp(-(i^2 + j^2) / (2 sigma^2)); hist has n floats (cleared here);
  /// gauss: scratch of 2 x radius + 48 floats.
  void (*orientation_hist)(const GradientPatch& p, int radius, float sigma, int n, float* hist,
                           float* gauss);
  /// OpenCV's smoothing of the orientation histogram: temp[-2 .. n+1] (the n bins and their
  /// wrapped neighbours) -> hist[0 .. n-1].
  void (*orientation_smooth)(const float* temp, float* hist, int n);
  /// The columns the descriptor histogram reads in each row of its window (rows max(p.i0,
  /// -radius)..min(p.i1, radius), entry k for row i0 + k): [ja[k], jb[k]], ja > jb for none.
  void (*descriptor_columns)(int radius, float cos_t, float sin_t, const GradientPatch& p, int* ja, int* jb);
  /// OpenCV's raw descriptor histogram (before the 0.2 clip and normalisation) in its order:
  /// raw[(row * 4 + col) * 8 + bin], 128 floats; cos_t, sin_t are cos/sin of the descriptor
  /// angle divided by the histogram width; ori_deg the descriptor angle in degrees.
  void (*descriptor_hist)(const GradientPatch& p, int radius, float cos_t, float sin_t,
                          float ori_deg, const DescriptorScratch& s, float* raw);
  /// OpenCV's descriptor from the raw histogram (128 floats, clipped in place): 0.2 clip,
  /// normalisation to 512, rounded and clamped to 0..255, as floats in out.
  void (*descriptor_finish)(float* raw, float* out);
};

const Kernels& scalarKernels();
const Kernels& avx2Kernels();    ///< only call when the CPU has AVX2 + FMA
const Kernels& avx512Kernels();  ///< only call when the CPU has AVX-512 F/BW/DQ/VL

}  // namespace refgrasp::detector::sift_internal
