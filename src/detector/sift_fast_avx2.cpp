// AVX2 + FMA kernels of the fast SIFT (8 lanes). Compiled with -mavx2 -mfma (CMakeLists.txt);
// see sift_fast_kernels.h for the rules of these translation units.
#include "detector/sift_fast_kernels.h"

#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>

#include <cstdint>

namespace refgrasp::detector::sift_internal {
namespace {

constexpr const char* kIsaName = "avx2";



struct V {
  static constexpr int N = 8;
  using F = __m256;
  using I = __m256i;
  using M = __m256;
  using IM = __m256i;
  static F load(const float* p) { return _mm256_loadu_ps(p); }
  static void store(float* p, F v) { _mm256_storeu_ps(p, v); }
  static void istore(int32_t* p, I v) { _mm256_storeu_si256(reinterpret_cast<__m256i*>(p), v); }
  static F load_u8(const uint8_t* p) {
    return _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(p))));
  }
  static F set1(float x) { return _mm256_set1_ps(x); }
  static I seti(int32_t x) { return _mm256_set1_epi32(x); }
  static F iota_f() { return _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7); }
  static I iota_i() { return _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7); }
  static F add(F a, F b) { return _mm256_add_ps(a, b); }
  static F sub(F a, F b) { return _mm256_sub_ps(a, b); }
  static F mul(F a, F b) { return _mm256_mul_ps(a, b); }
  static F div(F a, F b) { return _mm256_div_ps(a, b); }
  static F fma(F a, F b, F c) { return _mm256_fmadd_ps(a, b, c); }
  static F min(F a, F b) { return _mm256_min_ps(a, b); }
  static F max(F a, F b) { return _mm256_max_ps(a, b); }
  static F abs(F a) { return _mm256_and_ps(a, _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff))); }
  static F sqrt(F a) { return _mm256_sqrt_ps(a); }
  static F floor(F a) { return _mm256_floor_ps(a); }
  static I to_int(F a) { return _mm256_cvtps_epi32(a); }
  static F to_float(I a) { return _mm256_cvtepi32_ps(a); }
  static F pow2(I n) { return _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_add_epi32(n, _mm256_set1_epi32(127)), 23)); }
  static I iadd(I a, I b) { return _mm256_add_epi32(a, b); }
  static I isub(I a, I b) { return _mm256_sub_epi32(a, b); }
  static I imul(I a, I b) { return _mm256_mullo_epi32(a, b); }
  static I iand(I a, I b) { return _mm256_and_si256(a, b); }
  static M gt(F a, F b) { return _mm256_cmp_ps(a, b, _CMP_GT_OQ); }
  static M lt(F a, F b) { return _mm256_cmp_ps(a, b, _CMP_LT_OQ); }
  static M ge(F a, F b) { return _mm256_cmp_ps(a, b, _CMP_GE_OQ); }
  static M le(F a, F b) { return _mm256_cmp_ps(a, b, _CMP_LE_OQ); }
  static IM ilt(I a, I b) { return _mm256_cmpgt_epi32(b, a); }
  static IM ige(I a, I b) { return _mm256_xor_si256(_mm256_cmpgt_epi32(b, a), _mm256_set1_epi32(-1)); }
  static M mand(M a, M b) { return _mm256_and_ps(a, b); }
  static M mor(M a, M b) { return _mm256_or_ps(a, b); }
  static F select(M m, F a, F b) { return _mm256_blendv_ps(b, a, m); }
  static I iselect(IM m, I a, I b) { return _mm256_blendv_epi8(b, a, m); }
  static uint32_t bits(M m) { return static_cast<uint32_t>(_mm256_movemask_ps(m)); }
  static M first_lanes(int n) {
    return _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(n), iota_i()));
  }
  static void interleave(F lo, F hi, float* out) {
    const F u0 = _mm256_unpacklo_ps(lo, hi), u1 = _mm256_unpackhi_ps(lo, hi);
    _mm256_storeu_ps(out, _mm256_permute2f128_ps(u0, u1, 0x20));
    _mm256_storeu_ps(out + 8, _mm256_permute2f128_ps(u0, u1, 0x31));
  }
  /// 8x8 transpose: lane l's a..h at out[aos(l) ..] = out[8 l ..].
  static void transpose8(F a, F b, F c, F d, F e, F f, F g, F h, float* out) {
    const F t0 = _mm256_unpacklo_ps(a, b), t1 = _mm256_unpackhi_ps(a, b);
    const F t2 = _mm256_unpacklo_ps(c, d), t3 = _mm256_unpackhi_ps(c, d);
    const F t4 = _mm256_unpacklo_ps(e, f), t5 = _mm256_unpackhi_ps(e, f);
    const F t6 = _mm256_unpacklo_ps(g, h), t7 = _mm256_unpackhi_ps(g, h);
    // x_p / y_p: (a..d) / (e..h) of lanes p and 4 + p.
    const F x0 = _mm256_shuffle_ps(t0, t2, 0x44), x1 = _mm256_shuffle_ps(t0, t2, 0xEE);
    const F x2 = _mm256_shuffle_ps(t1, t3, 0x44), x3 = _mm256_shuffle_ps(t1, t3, 0xEE);
    const F y0 = _mm256_shuffle_ps(t4, t6, 0x44), y1 = _mm256_shuffle_ps(t4, t6, 0xEE);
    const F y2 = _mm256_shuffle_ps(t5, t7, 0x44), y3 = _mm256_shuffle_ps(t5, t7, 0xEE);
    _mm256_storeu_ps(out, _mm256_permute2f128_ps(x0, y0, 0x20));
    _mm256_storeu_ps(out + 8, _mm256_permute2f128_ps(x1, y1, 0x20));
    _mm256_storeu_ps(out + 16, _mm256_permute2f128_ps(x2, y2, 0x20));
    _mm256_storeu_ps(out + 24, _mm256_permute2f128_ps(x3, y3, 0x20));
    _mm256_storeu_ps(out + 32, _mm256_permute2f128_ps(x0, y0, 0x31));
    _mm256_storeu_ps(out + 40, _mm256_permute2f128_ps(x1, y1, 0x31));
    _mm256_storeu_ps(out + 48, _mm256_permute2f128_ps(x2, y2, 0x31));
    _mm256_storeu_ps(out + 56, _mm256_permute2f128_ps(x3, y3, 0x31));
  }
  static constexpr int aos(int l) { return 8 * l; }
  /// See the scalar add8: one 8-float add.
  static void add8(float* slot, const float* w) {
    _mm256_storeu_ps(slot, _mm256_add_ps(_mm256_loadu_ps(slot), _mm256_loadu_ps(w)));
  }
};

#include "detector/sift_fast_kernels.inl"

}  // namespace

const Kernels& avx2Kernels() { return kTable; }

}  // namespace refgrasp::detector::sift_internal

#else  // not compiled for this instruction set (not x86): never chosen at run time
namespace refgrasp::detector::sift_internal {
const Kernels& avx2Kernels() { return scalarKernels(); }
}  // namespace refgrasp::detector::sift_internal
#endif
