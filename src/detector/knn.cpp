#include "detector/knn.h"

#include <algorithm>
#include <climits>

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
// Eight scene rows per lane group; each reference row is one pass. Dot products with the 8-bit
// VNNI instruction (u8 scene x s8 reference, exact int32 sums); the nearest/second-nearest
// bookkeeping is vectorised across the eight scene rows.
__attribute__((target("avx2,avx512f,avx512vl,avx512bw,avx512vnni"))) void knnBlocksVnni(
    const cv::Mat& S8, const std::vector<int>& sn2, const IntegerDescriptors& ref, int b0, int b1, NearestTwo* out) {
  const int ns = S8.rows, nr = ref.lo_s8.rows;
  alignas(32) uint8_t pad[8][kDim];
  for (int blk = b0; blk < b1; ++blk) {
    const int i0 = blk * 8;
    const uint8_t* rows[8];
    for (int q = 0; q < 8; ++q) {
      if (i0 + q < ns) {
        rows[q] = S8.ptr<uint8_t>(i0 + q);
      } else {
        std::fill(pad[q], pad[q] + kDim, 0);
        rows[q] = pad[q];
      }
    }
    alignas(32) int n2[8];
    for (int q = 0; q < 8; ++q) n2[q] = i0 + q < ns ? sn2[i0 + q] : 0;
    const __m256i sn = _mm256_load_si256(reinterpret_cast<const __m256i*>(n2));
    __m256i d1 = _mm256_set1_epi32(INT_MAX), d2 = _mm256_set1_epi32(INT_MAX);
    __m256i best = _mm256_set1_epi32(-1), second = _mm256_set1_epi32(-1);
    for (int j = 0; j < nr; ++j) {
      const __m256i* lo = reinterpret_cast<const __m256i*>(ref.lo_s8.ptr<int8_t>(j));
      const __m256i l0 = _mm256_loadu_si256(lo), l1 = _mm256_loadu_si256(lo + 1),
                    l2 = _mm256_loadu_si256(lo + 2), l3 = _mm256_loadu_si256(lo + 3);
      __m256i acc[8];
      for (int q = 0; q < 8; ++q) {
        const __m256i* s = reinterpret_cast<const __m256i*>(rows[q]);
        __m256i a = _mm256_dpbusd_epi32(_mm256_setzero_si256(), _mm256_loadu_si256(s), l0);
        a = _mm256_dpbusd_epi32(a, _mm256_loadu_si256(s + 1), l1);
        a = _mm256_dpbusd_epi32(a, _mm256_loadu_si256(s + 2), l2);
        acc[q] = _mm256_dpbusd_epi32(a, _mm256_loadu_si256(s + 3), l3);
      }
      if (ref.has_hi[j]) {
        const __m256i* hi = reinterpret_cast<const __m256i*>(ref.hi_s8.ptr<int8_t>(j));
        for (int q = 0; q < 8; ++q) {
          const __m256i* s = reinterpret_cast<const __m256i*>(rows[q]);
          __m256i a = _mm256_setzero_si256();
          for (int k = 0; k < 4; ++k) a = _mm256_dpbusd_epi32(a, _mm256_loadu_si256(s + k), _mm256_loadu_si256(hi + k));
          acc[q] = _mm256_add_epi32(acc[q], _mm256_slli_epi32(a, 7));
        }
      }
      const __m256i h01 = _mm256_hadd_epi32(acc[0], acc[1]), h23 = _mm256_hadd_epi32(acc[2], acc[3]);
      const __m256i h45 = _mm256_hadd_epi32(acc[4], acc[5]), h67 = _mm256_hadd_epi32(acc[6], acc[7]);
      const __m256i h03 = _mm256_hadd_epi32(h01, h23), h47 = _mm256_hadd_epi32(h45, h67);
      const __m256i dot = _mm256_add_epi32(_mm256_permute2x128_si256(h03, h47, 0x20),
                                           _mm256_permute2x128_si256(h03, h47, 0x31));
      const __m256i d = _mm256_sub_epi32(_mm256_add_epi32(sn, _mm256_set1_epi32(ref.norm2[j])),
                                         _mm256_slli_epi32(dot, 1));
      const __m256i closer = _mm256_cmpgt_epi32(d1, d), closer2 = _mm256_cmpgt_epi32(d2, d);
      const __m256i jv = _mm256_set1_epi32(j);
      second = _mm256_blendv_epi8(_mm256_blendv_epi8(second, jv, closer2), best, closer);
      d2 = _mm256_blendv_epi8(_mm256_min_epi32(d2, d), d1, closer);
      best = _mm256_blendv_epi8(best, jv, closer);
      d1 = _mm256_min_epi32(d1, d);
    }
    alignas(32) int vb[8], vs[8], v1[8], v2[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(vb), best);
    _mm256_store_si256(reinterpret_cast<__m256i*>(vs), second);
    _mm256_store_si256(reinterpret_cast<__m256i*>(v1), d1);
    _mm256_store_si256(reinterpret_cast<__m256i*>(v2), d2);
    for (int q = 0; q < 8 && i0 + q < ns; ++q) out[i0 + q] = {vb[q], v1[q], v2[q], vs[q]};
  }
}
#endif

bool cpuHas(KnnKernel k) {
#ifdef REFGRASP_HAVE_X86
  static const bool avx2 = __builtin_cpu_supports("avx2");
  static const bool vnni = __builtin_cpu_supports("avx512vnni") && __builtin_cpu_supports("avx512vl") &&
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
  d.lo_s8.create(d.s16.size(), CV_8S);
  d.hi_s8.create(d.s16.size(), CV_8S);
  d.has_hi.assign(d.s16.rows, 0);
  for (int i = 0; i < d.s16.rows; ++i)
    for (int k = 0; k < kDim; ++k) {
      const int v = d.s16.at<int16_t>(i, k);
      d.lo_s8.at<int8_t>(i, k) = static_cast<int8_t>(v & 127);
      d.hi_s8.at<int8_t>(i, k) = static_cast<int8_t>(v >> 7);
      d.has_hi[i] |= v >= 128;
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
  if (kernel == KnnKernel::kVnni && ref.lo_s8.rows != R.rows) kernel = KnnKernel::kAvx2;  // no byte split
  if (!cpuHas(kernel)) kernel = KnnKernel::kScalar;
#ifdef REFGRASP_HAVE_X86
  if (kernel == KnnKernel::kVnni) {
    cv::Mat S8;
    S.convertTo(S8, CV_8U);
    const int nblocks = (S.rows + 7) / 8;
    cv::parallel_for_(cv::Range(0, nblocks), [&](const cv::Range& rg) {
      knnBlocksVnni(S8, sn2, ref, rg.start, rg.end, out.data());
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
