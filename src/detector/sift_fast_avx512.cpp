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

/// transpose8's layout: the first four weights of lane l at kAos[l] (4x4 blocks per 128 bits).
constexpr int8_t kAos[16] = {0, 16, 32, 48, 4, 20, 36, 52, 8, 24, 40, 56, 12, 28, 44, 60};


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
  /// 4x4 transposes within each 128-bit lane: sample l's weights a..d at aos_lo(l), e..h at aos_hi(l).
  static void transpose4(F a, F b, F c, F d, float* out) {
    const F t0 = _mm512_unpacklo_ps(a, b), t1 = _mm512_unpackhi_ps(a, b);
    const F t2 = _mm512_unpacklo_ps(c, d), t3 = _mm512_unpackhi_ps(c, d);
    _mm512_storeu_ps(out, _mm512_shuffle_ps(t0, t2, 0x44));
    _mm512_storeu_ps(out + N, _mm512_shuffle_ps(t0, t2, 0xEE));
    _mm512_storeu_ps(out + 2 * N, _mm512_shuffle_ps(t1, t3, 0x44));
    _mm512_storeu_ps(out + 3 * N, _mm512_shuffle_ps(t1, t3, 0xEE));
  }
  static void transpose8(F a, F b, F c, F d, F e, F f, F g, F h, float* out) {
    transpose4(a, b, c, d, out);
    transpose4(e, f, g, h, out + 4 * N);
  }
  static int aos_lo(int l) { return kAos[l]; }
  static int aos_hi(int l) { return 4 * N + aos_lo(l); }
  /// See the scalar add_sample: [lo | hi] permuted to (w000, w010, .., w100, w110) and
  /// (w001, w011, .., w101, w111), lanes 2..5 zero.
  static void add_sample(float* a, float* b, const float* lo, const float* hi) {
    const __m256 w = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(lo)), _mm_loadu_ps(hi), 1);
    const __m256i ia = _mm256_setr_epi32(0, 2, 0, 0, 0, 0, 4, 6), ib = _mm256_setr_epi32(1, 3, 1, 1, 1, 1, 5, 7);
    const __m256 m = _mm256_castsi256_ps(_mm256_setr_epi32(-1, -1, 0, 0, 0, 0, -1, -1));
    _mm256_storeu_ps(a, _mm256_add_ps(_mm256_loadu_ps(a), _mm256_and_ps(_mm256_permutevar8x32_ps(w, ia), m)));
    _mm256_storeu_ps(b, _mm256_add_ps(_mm256_loadu_ps(b), _mm256_and_ps(_mm256_permutevar8x32_ps(w, ib), m)));
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
