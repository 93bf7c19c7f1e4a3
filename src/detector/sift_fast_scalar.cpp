// Scalar kernels of the fast SIFT: one lane, the reference every vector path must match bit for
// bit (see sift_fast_kernels.h for the rules of these translation units).
#include <cstdint>
#include <cstring>

#include "detector/sift_fast_kernels.h"

namespace refgrasp::detector::sift_internal {
namespace {

constexpr const char* kIsaName = "scalar";

struct V {
  static constexpr int N = 1;
  using F = float;
  using I = int32_t;
  using M = bool;
  using IM = bool;
  static F load(const float* p) { return *p; }
  static void store(float* p, F v) { *p = v; }
  static void istore(int32_t* p, I v) { *p = v; }
  static F load_u8(const uint8_t* p) { return static_cast<float>(*p); }
  static F set1(float x) { return x; }
  static I seti(int32_t x) { return x; }
  static F iota_f() { return 0.f; }
  static I iota_i() { return 0; }
  static F add(F a, F b) { return a + b; }
  static F sub(F a, F b) { return a - b; }
  static F mul(F a, F b) { return a * b; }
  static F div(F a, F b) { return a / b; }
  static F fma(F a, F b, F c) { return __builtin_fmaf(a, b, c); }
  static F min(F a, F b) { return a < b ? a : b; }  // as minps: the second operand on ties
  static F max(F a, F b) { return a > b ? a : b; }
  static F abs(F a) { return __builtin_fabsf(a); }
  static F sqrt(F a) { return __builtin_sqrtf(a); }
  static F floor(F a) { return __builtin_floorf(a); }
  static I to_int(F a) { return static_cast<I>(__builtin_lrintf(a)); }  // nearest even
  static F to_float(I a) { return static_cast<float>(a); }
  static F pow2(I n) {
    const int32_t bits = (n + 127) << 23;
    float f;
    std::memcpy(&f, &bits, sizeof f);
    return f;
  }
  static I iadd(I a, I b) { return a + b; }
  static I isub(I a, I b) { return a - b; }
  static I imul(I a, I b) { return a * b; }
  static I iand(I a, I b) { return a & b; }
  static M gt(F a, F b) { return a > b; }
  static M lt(F a, F b) { return a < b; }
  static M ge(F a, F b) { return a >= b; }
  static M le(F a, F b) { return a <= b; }
  static IM ilt(I a, I b) { return a < b; }
  static IM ige(I a, I b) { return a >= b; }
  static M mand(M a, M b) { return a && b; }
  static M mor(M a, M b) { return a || b; }
  static F select(M m, F a, F b) { return m ? a : b; }
  static I iselect(IM m, I a, I b) { return m ? a : b; }
  static uint32_t bits(M m) { return m ? 1u : 0u; }
  static M first_lanes(int n) { return n > 0; }
  static void interleave(F lo, F hi, float* out) {
    out[0] = lo;
    out[1] = hi;
  }
  static void transpose8(F a, F b, F c, F d, F e, F f, F g, F h, float* out) {
    out[0] = a, out[1] = b, out[2] = c, out[3] = d, out[4] = e, out[5] = f, out[6] = g, out[7] = h;
  }
  static constexpr int aos(int) { return 0; }
  /// Adds a descriptor sample's weights w_k, k = dr * 4 + dc * 2 + do, to its slot: slot[k] += w_k
  /// (see kDescrSlotFloats).
  static void add8(float* slot, const float* w) {
    for (int k = 0; k < 8; ++k) slot[k] += w[k];
  }
};

#include "detector/sift_fast_kernels.inl"

}  // namespace

const Kernels& scalarKernels() { return kTable; }

}  // namespace refgrasp::detector::sift_internal
