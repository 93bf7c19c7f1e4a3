// AVX-512 kernels of the fast SIFT (16 lanes). Compiled with -mavx512f -mavx512dq -mavx512bw
// -mavx512vl -mavx2 -mfma (CMakeLists.txt); see sift_fast_kernels.h for the rules of these
// translation units.
#include "detector/sift_fast_kernels.h"

#if defined(__AVX512F__) && defined(__AVX512DQ__) && defined(__AVX512BW__) && defined(__AVX512VL__)
#include <immintrin.h>

#include <cstdint>

namespace refgrasp::detector::sift_internal {
namespace {

constexpr const char* kIsaName = "avx512";

/// transpose8's layout: lane l = 4 m + p (128-bit lane m, position p) at kAos[l]; see transpose8.
constexpr int8_t kAos[16] = {0, 32, 64, 96, 8, 40, 72, 104, 16, 48, 80, 112, 24, 56, 88, 120};


struct V {
  static constexpr int N = 16;
  using F = __m512;
  using I = __m512i;
  using M = __mmask16;
  using IM = __mmask16;
  static F load(const float* p) { return _mm512_loadu_ps(p); }
  static void store(float* p, F v) { _mm512_storeu_ps(p, v); }
  static void istore(int32_t* p, I v) { _mm512_storeu_si512(p, v); }
  static F load_u8(const uint8_t* p) {
    return _mm512_cvtepi32_ps(_mm512_cvtepu8_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p))));
  }
  static F set1(float x) { return _mm512_set1_ps(x); }
  static I seti(int32_t x) { return _mm512_set1_epi32(x); }
  static F iota_f() { return _mm512_setr_ps(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15); }
  static I iota_i() { return _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15); }
  static F add(F a, F b) { return _mm512_add_ps(a, b); }
  static F sub(F a, F b) { return _mm512_sub_ps(a, b); }
  static F mul(F a, F b) { return _mm512_mul_ps(a, b); }
  static F div(F a, F b) { return _mm512_div_ps(a, b); }
  static F fma(F a, F b, F c) { return _mm512_fmadd_ps(a, b, c); }
  static F min(F a, F b) { return _mm512_min_ps(a, b); }
  static F max(F a, F b) { return _mm512_max_ps(a, b); }
  static F abs(F a) { return _mm512_abs_ps(a); }
  static F sqrt(F a) { return _mm512_sqrt_ps(a); }
  static F floor(F a) { return _mm512_roundscale_ps(a, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC); }
  static I to_int(F a) { return _mm512_cvtps_epi32(a); }
  static F to_float(I a) { return _mm512_cvtepi32_ps(a); }
  static F pow2(I n) { return _mm512_castsi512_ps(_mm512_slli_epi32(_mm512_add_epi32(n, _mm512_set1_epi32(127)), 23)); }
  static I iadd(I a, I b) { return _mm512_add_epi32(a, b); }
  static I isub(I a, I b) { return _mm512_sub_epi32(a, b); }
  static I imul(I a, I b) { return _mm512_mullo_epi32(a, b); }
  static I iand(I a, I b) { return _mm512_and_si512(a, b); }
  static M gt(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_GT_OQ); }
  static M lt(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_LT_OQ); }
  static M ge(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_GE_OQ); }
  static M le(F a, F b) { return _mm512_cmp_ps_mask(a, b, _CMP_LE_OQ); }
  static IM ilt(I a, I b) { return _mm512_cmplt_epi32_mask(a, b); }
  static IM ige(I a, I b) { return _mm512_cmpge_epi32_mask(a, b); }
  static M mand(M a, M b) { return static_cast<M>(a & b); }
  static M mor(M a, M b) { return static_cast<M>(a | b); }
  static F select(M m, F a, F b) { return _mm512_mask_blend_ps(m, b, a); }
  static I iselect(IM m, I a, I b) { return _mm512_mask_blend_epi32(m, b, a); }
  static uint32_t bits(M m) { return static_cast<uint32_t>(m); }
  static M first_lanes(int n) {
    return n >= 16 ? static_cast<M>(0xffff) : n <= 0 ? static_cast<M>(0) : static_cast<M>((1u << n) - 1);
  }
  static void interleave(F lo, F hi, float* out) {
    const I i0 = _mm512_setr_epi32(0, 16, 1, 17, 2, 18, 3, 19, 4, 20, 5, 21, 6, 22, 7, 23);
    const I i1 = _mm512_setr_epi32(8, 24, 9, 25, 10, 26, 11, 27, 12, 28, 13, 29, 14, 30, 15, 31);
    _mm512_storeu_ps(out, _mm512_permutex2var_ps(lo, i0, hi));
    _mm512_storeu_ps(out + 16, _mm512_permutex2var_ps(lo, i1, hi));
  }
  /// Lane l's a..h at out[aos(l) ..], 8 contiguous floats: 4x4 transposes within each 128-bit
  /// lane (x_p, y_p: a..d, e..h of the lanes 4 m + p), then lanes 4 m + p and 4 (m + 1) + p
  /// paired: [x_p.m0 y_p.m0 x_p.m1 y_p.m1] at 32 p, [x_p.m2 y_p.m2 x_p.m3 y_p.m3] at 32 p + 16.
  static void transpose8(F a, F b, F c, F d, F e, F f, F g, F h, float* out) {
    const F t0 = _mm512_unpacklo_ps(a, b), t1 = _mm512_unpackhi_ps(a, b);
    const F t2 = _mm512_unpacklo_ps(c, d), t3 = _mm512_unpackhi_ps(c, d);
    const F t4 = _mm512_unpacklo_ps(e, f), t5 = _mm512_unpackhi_ps(e, f);
    const F t6 = _mm512_unpacklo_ps(g, h), t7 = _mm512_unpackhi_ps(g, h);
    const F x[4] = {_mm512_shuffle_ps(t0, t2, 0x44), _mm512_shuffle_ps(t0, t2, 0xEE),
                    _mm512_shuffle_ps(t1, t3, 0x44), _mm512_shuffle_ps(t1, t3, 0xEE)};
    const F y[4] = {_mm512_shuffle_ps(t4, t6, 0x44), _mm512_shuffle_ps(t4, t6, 0xEE),
                    _mm512_shuffle_ps(t5, t7, 0x44), _mm512_shuffle_ps(t5, t7, 0xEE)};
    const __m512i lo = _mm512_setr_epi32(0, 1, 2, 3, 16, 17, 18, 19, 4, 5, 6, 7, 20, 21, 22, 23);
    const __m512i hi = _mm512_setr_epi32(8, 9, 10, 11, 24, 25, 26, 27, 12, 13, 14, 15, 28, 29, 30, 31);
    for (int p = 0; p < 4; ++p) {
      _mm512_storeu_ps(out + 32 * p, _mm512_permutex2var_ps(x[p], lo, y[p]));
      _mm512_storeu_ps(out + 32 * p + 16, _mm512_permutex2var_ps(x[p], hi, y[p]));
    }
  }
  static int aos(int l) { return kAos[l]; }
  /// See the scalar add8: one 8-float add.
  static void add8(float* slot, const float* w) {
    _mm256_storeu_ps(slot, _mm256_add_ps(_mm256_loadu_ps(slot), _mm256_loadu_ps(w)));
  }
};

#include "detector/sift_fast_kernels.inl"

}  // namespace

const Kernels& avx512Kernels() { return kTable; }

}  // namespace refgrasp::detector::sift_internal

#else  // not compiled for this instruction set (not x86): never chosen at run time
namespace refgrasp::detector::sift_internal {
const Kernels& avx512Kernels() { return scalarKernels(); }
}  // namespace refgrasp::detector::sift_internal
#endif
