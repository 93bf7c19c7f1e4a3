#include "detector/knn.h"

#include <algorithm>
#include <climits>
#include <cstring>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define REFGRASP_HAVE_X86 1
#endif

namespace refgrasp::detector {
namespace {

constexpr int kDim = 128;

void knnRowsScalar(const cv::Mat& S, const std::vector<int>& sn2, const cv::Mat& R,
                   const std::vector<int>& rn2, int s0, int s1, NearestTwo* out) {
  for (int i = s0; i < s1; ++i) {
    const int16_t* s = S.ptr<int16_t>(i);
    NearestTwo nn;
    for (int j = 0; j < R.rows; ++j) {
      const int16_t* r = R.ptr<int16_t>(j);
      int dot = 0;
      for (int k = 0; k < kDim; ++k) dot += s[k] * r[k];
      const int d = sn2[i] + rn2[j] - 2 * dot;
      if (d < nn.d2) {
        if (d < nn.d1) {
          nn.d2 = nn.d1;
          nn.second = nn.best;
          nn.d1 = d;
          nn.best = j;
        } else {
          nn.d2 = d;
          nn.second = j;
        }
      }
    }
    out[i] = nn;
  }
}

#ifdef REFGRASP_HAVE_X86
// Exact integer dot products, four scene rows per pass over a reference row.
__attribute__((target("avx2"))) void knnRowsAvx2(const cv::Mat& S, const std::vector<int>& sn2,
                                                 const cv::Mat& R, const std::vector<int>& rn2,
                                                 int s0, int s1, NearestTwo* out) {
  int i = s0;
  for (; i + 4 <= s1; i += 4) {
    const __m256i* s[4];
    for (int q = 0; q < 4; ++q) s[q] = reinterpret_cast<const __m256i*>(S.ptr<int16_t>(i + q));
    NearestTwo nn[4];
    for (int j = 0; j < R.rows; ++j) {
      const __m256i* r = reinterpret_cast<const __m256i*>(R.ptr<int16_t>(j));
      __m256i acc[4] = {_mm256_setzero_si256(), _mm256_setzero_si256(), _mm256_setzero_si256(),
                        _mm256_setzero_si256()};
      for (int k = 0; k < 8; ++k) {
        const __m256i rv = _mm256_loadu_si256(r + k);
        for (int q = 0; q < 4; ++q)
          acc[q] = _mm256_add_epi32(acc[q], _mm256_madd_epi16(rv, _mm256_loadu_si256(s[q] + k)));
      }
      // Horizontal sums of the four accumulators.
      const __m256i h01 = _mm256_hadd_epi32(acc[0], acc[1]);
      const __m256i h23 = _mm256_hadd_epi32(acc[2], acc[3]);
      const __m256i h = _mm256_hadd_epi32(h01, h23);
      const __m128i sum = _mm_add_epi32(_mm256_castsi256_si128(h), _mm256_extracti128_si256(h, 1));
      alignas(16) int dots[4];
      _mm_store_si128(reinterpret_cast<__m128i*>(dots), sum);
      for (int q = 0; q < 4; ++q) {
        const int d = sn2[i + q] + rn2[j] - 2 * dots[q];
        if (d < nn[q].d2) {
          if (d < nn[q].d1) {
            nn[q].d2 = nn[q].d1;
            nn[q].second = nn[q].best;
            nn[q].d1 = d;
            nn[q].best = j;
          } else {
            nn[q].d2 = d;
            nn[q].second = j;
          }
        }
      }
    }
    for (int q = 0; q < 4; ++q) out[i + q] = nn[q];
  }
  if (i < s1) knnRowsScalar(S, sn2, R, rn2, i, s1, out);
}
#endif

#ifdef REFGRASP_HAVE_X86
// AVX-512 VNNI: 16 reference rows in the lanes of a register, four scene rows at a time. The
// reference is stored transposed (IntegerDescriptors::t_u8: per block of 16 rows and group of 4
// dimensions, the 4 bytes of each row), the scene as s8 values - 128, so one vpdpbusd adds 4
// exact products of 16 pairs: sum_k r[k] (s[k] - 128) = r.s - 128 sum_k r[k], and
// |s - r|^2 = |s|^2 + bias_r - 2 * that sum with bias_r = |r|^2 - 256 sum_k r[k] (exact int32).
// Each lane keeps the nearest and second nearest of its rows (strictly closer wins: the first
// index among equals, as the scalar loop); the 16 lanes are merged by (distance, index).
__attribute__((target("avx2,avx512f,avx512bw,avx512vnni"))) void knnVnni512(
    const cv::Mat& S8, const std::vector<int>& sn2, const IntegerDescriptors& ref, int g0, int g1,
    NearestTwo* out) {
  const int ns = S8.rows, nr = ref.s16.rows, nblk = ref.t_rows / 16;
  constexpr int kBlockBytes = 16 * kDim;
  alignas(64) int8_t pad[kDim];
  std::fill(pad, pad + kDim, 0);
  alignas(64) int st_d1[4][16], st_d2[4][16], st_b1[4][16], st_b2[4][16];
  const __m512i iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  for (int g = g0; g < g1; ++g) {
    const int8_t* srow[4];
    __m512i sn[4];
    for (int q = 0; q < 4; ++q) {
      const int i = 4 * g + q;
      srow[q] = i < ns ? S8.ptr<int8_t>(i) : pad;
      sn[q] = _mm512_set1_epi32(i < ns ? sn2[i] : 0);
      _mm512_store_si512(st_d1[q], _mm512_set1_epi32(INT_MAX));
      _mm512_store_si512(st_d2[q], _mm512_set1_epi32(INT_MAX));
      _mm512_store_si512(st_b1[q], _mm512_set1_epi32(-1));
      _mm512_store_si512(st_b2[q], _mm512_set1_epi32(-1));
    }
    for (int rb = 0; rb < nblk; rb += 4) {  // t_rows is a multiple of 64
      const uint8_t* base = ref.t_u8.data() + static_cast<size_t>(rb) * kBlockBytes;
      __m512i acc[4][4];
      for (int q = 0; q < 4; ++q)
        for (int b = 0; b < 4; ++b) acc[q][b] = _mm512_setzero_si512();
      for (int k = 0; k < kDim / 4; ++k) {
        __m512i r[4];
        for (int b = 0; b < 4; ++b) r[b] = _mm512_loadu_si512(base + b * kBlockBytes + k * 64);
        for (int q = 0; q < 4; ++q) {
          int32_t word;
          std::memcpy(&word, srow[q] + 4 * k, 4);
          const __m512i sv = _mm512_set1_epi32(word);
          for (int b = 0; b < 4; ++b) acc[q][b] = _mm512_dpbusd_epi32(acc[q][b], r[b], sv);
        }
      }
      for (int q = 0; q < 4; ++q) {
        __m512i d1 = _mm512_load_si512(st_d1[q]), d2 = _mm512_load_si512(st_d2[q]);
        __m512i b1 = _mm512_load_si512(st_b1[q]), b2 = _mm512_load_si512(st_b2[q]);
        for (int b = 0; b < 4; ++b) {
          const int j0 = (rb + b) * 16;
          const __m512i d = _mm512_sub_epi32(_mm512_add_epi32(sn[q], _mm512_loadu_si512(ref.bias.data() + j0)),
                                             _mm512_add_epi32(acc[q][b], acc[q][b]));
          const __m512i jv = _mm512_add_epi32(_mm512_set1_epi32(j0), iota);
          const __mmask16 c1 = _mm512_cmplt_epi32_mask(d, d1), c2 = _mm512_cmplt_epi32_mask(d, d2);
          b2 = _mm512_mask_blend_epi32(c1, _mm512_mask_blend_epi32(c2, b2, jv), b1);
          d2 = _mm512_mask_blend_epi32(c1, _mm512_mask_blend_epi32(c2, d2, d), d1);
          b1 = _mm512_mask_blend_epi32(c1, b1, jv);
          d1 = _mm512_mask_blend_epi32(c1, d1, d);
        }
        _mm512_store_si512(st_d1[q], d1);
        _mm512_store_si512(st_d2[q], d2);
        _mm512_store_si512(st_b1[q], b1);
        _mm512_store_si512(st_b2[q], b2);
      }
    }
    for (int q = 0; q < 4 && 4 * g + q < ns; ++q) {
      NearestTwo nn;
      auto offer = [&](int d, int j) {  // (d, j) ordered lexicographically, padding rows skipped
        if (j < 0 || j >= nr) return;
        if (d < nn.d1 || (d == nn.d1 && j < nn.best)) {
          nn.d2 = nn.d1;
          nn.second = nn.best;
          nn.d1 = d;
          nn.best = j;
        } else if (d < nn.d2 || (d == nn.d2 && j < nn.second)) {
          nn.d2 = d;
          nn.second = j;
        }
      };
      for (int l = 0; l < 16; ++l) {
        offer(st_d1[q][l], st_b1[q][l]);
        offer(st_d2[q][l], st_b2[q][l]);
      }
      out[4 * g + q] = nn;
    }
  }
}
#endif

bool cpuHas(KnnKernel k) {
#ifdef REFGRASP_HAVE_X86
  static const bool avx2 = __builtin_cpu_supports("avx2");
  static const bool vnni = __builtin_cpu_supports("avx512vnni") && __builtin_cpu_supports("avx512f") &&
                           __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx2");
  if (k == KnnKernel::kAvx2) return avx2;
  if (k == KnnKernel::kVnni) return vnni;
#endif
  return k == KnnKernel::kScalar || k == KnnKernel::kAuto;
}

}  // namespace

int squaredDistance(const int16_t* a, const int16_t* b) {
  int s = 0;
  for (int k = 0; k < kDim; ++k) {
    const int d = a[k] - b[k];
    s += d * d;
  }
  return s;
}

IntegerDescriptors integerDescriptors(const cv::Mat& desc, bool byte_split) {
  IntegerDescriptors d;
  desc.convertTo(d.s16, CV_16S);
  d.norm2.resize(d.s16.rows);
  for (int i = 0; i < d.s16.rows; ++i) {
    const int16_t* r = d.s16.ptr<int16_t>(i);
    int s = 0;
    for (int k = 0; k < kDim; ++k) s += r[k] * r[k];
    d.norm2[i] = s;
  }
  if (!byte_split) return d;
  const int n = d.s16.rows;
  d.t_rows = (n + 63) / 64 * 64;
  d.t_u8.assign(static_cast<size_t>(d.t_rows) * kDim, 0);
  d.bias.assign(d.t_rows, 1 << 30);  // padding rows: farther than any real one (<= 2^25)
  for (int i = 0; i < n; ++i) {
    const int16_t* r = d.s16.ptr<int16_t>(i);
    int sum = 0;
    for (int k = 0; k < kDim; ++k) {
      const int v = std::clamp<int>(r[k], 0, 255);
      sum += v;
      d.t_u8[static_cast<size_t>(i / 16) * 16 * kDim + (k / 4) * 64 + (i % 16) * 4 + k % 4] = static_cast<uint8_t>(v);
    }
    d.bias[i] = d.norm2[i] - 256 * sum;
  }
  return d;
}

bool knnKernelAvailable(KnnKernel kernel) { return cpuHas(kernel); }

std::vector<NearestTwo> nearestTwo(const IntegerDescriptors& ref, const IntegerDescriptors& scene,
                                   KnnKernel kernel) {
  const cv::Mat& S = scene.s16;
  const std::vector<int>& sn2 = scene.norm2;
  const cv::Mat& R = ref.s16;
  const std::vector<int>& rn2 = ref.norm2;
  std::vector<NearestTwo> out(S.rows);
  if (R.rows == 0 || S.rows == 0) return out;
  if (kernel == KnnKernel::kAuto) {
    kernel = cpuHas(KnnKernel::kVnni) ? KnnKernel::kVnni
             : cpuHas(KnnKernel::kAvx2) ? KnnKernel::kAvx2 : KnnKernel::kScalar;
  }
  if (kernel == KnnKernel::kVnni && ref.t_rows < R.rows) kernel = KnnKernel::kAvx2;  // no byte split
  if (!cpuHas(kernel)) kernel = KnnKernel::kScalar;
#ifdef REFGRASP_HAVE_X86
  if (kernel == KnnKernel::kVnni) {
    cv::Mat S8(S.rows, kDim, CV_8S);
    for (int i = 0; i < S.rows; ++i) {
      const int16_t* a = S.ptr<int16_t>(i);
      int8_t* b = S8.ptr<int8_t>(i);
      for (int k = 0; k < kDim; ++k) b[k] = static_cast<int8_t>(std::clamp<int>(a[k], 0, 255) - 128);
    }
    const int groups = (S.rows + 3) / 4;
    cv::parallel_for_(cv::Range(0, groups), [&](const cv::Range& rg) {
      knnVnni512(S8, sn2, ref, rg.start, rg.end, out.data());
    }, 8);
    return out;
  }
#endif
  const int chunk = 64;
  const int nchunks = (S.rows + chunk - 1) / chunk;
  cv::parallel_for_(cv::Range(0, nchunks), [&](const cv::Range& rg) {
    for (int c = rg.start; c < rg.end; ++c) {
      const int s0 = c * chunk, s1 = std::min(S.rows, s0 + chunk);
#ifdef REFGRASP_HAVE_X86
      if (kernel == KnnKernel::kAvx2) {
        knnRowsAvx2(S, sn2, R, rn2, s0, s1, out.data());
        continue;
      }
#endif
      knnRowsScalar(S, sn2, R, rn2, s0, s1, out.data());
    }
  });
  return out;
}

}  // namespace refgrasp::detector
