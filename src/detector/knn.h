#pragma once
// Exact nearest and second-nearest neighbours of SIFT descriptors (the global matching of paper
// III-B), on integer copies of the descriptors: OpenCV SIFT descriptors are CV_32F with integer
// values 0..255, so squared L2 distances are exact integers. Scalar, AVX2 and AVX-512 VNNI
// kernels, all giving the identical answer.
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

namespace refgrasp::detector {

/// Descriptors prepared for the integer kernels; row i is descriptor i of the input.
struct IntegerDescriptors {
  cv::Mat s16;             ///< CV_16S, N x 128
  std::vector<int> norm2;  ///< squared L2 norms of the rows
  /// Reference side of the AVX-512 VNNI kernel (made with byte_split, else empty): rows padded
  /// to t_rows (a multiple of 64) with zeros, in blocks of 16 rows; block b, dimension group g
  /// (4 dimensions) holds at byte (b * 32 + g) * 64 + 4 * lane the 4 values of row 16 b + lane.
  /// bias[j] = norm2[j] - 256 * sum of row j (padding: 2^30, farther than any real row).
  std::vector<uint8_t> t_u8;
  std::vector<int> bias;
  int t_rows = 0;
  int rows() const { return s16.rows; }
};

/// From OpenCV SIFT descriptors (CV_32F, N x 128).
IntegerDescriptors integerDescriptors(const cv::Mat& descriptors, bool byte_split);

/// Squared L2 distance of two 128-element integer descriptors.
int squaredDistance(const int16_t* a, const int16_t* b);

/// Nearest and second-nearest reference descriptor of one query descriptor; squared L2 distances
/// of the integer-valued SIFT descriptors (exact).
struct NearestTwo {
  int best = -1;            ///< index into the reference rows, -1 when there is none
  int d1 = 2147483647;      ///< squared distance to best
  int d2 = 2147483647;      ///< squared distance to the second nearest
  int second = -1;          ///< index of the second nearest
};
/// Implementations of the global 2-NN; all exact and identical in result. kAuto takes the
/// fastest the CPU has (AVX-512 VNNI 8-bit dot products, 16 reference rows a register, else
/// AVX2, else scalar).
enum class KnnKernel { kAuto, kScalar, kAvx2, kVnni };
bool knnKernelAvailable(KnnKernel kernel);

/// For every query row, its two nearest reference rows; multithreaded. kVnni on a reference
/// made without byte_split runs kAvx2; a kernel the CPU lacks falls back to kScalar.
std::vector<NearestTwo> nearestTwo(const IntegerDescriptors& reference, const IntegerDescriptors& query,
                                   KnnKernel kernel = KnnKernel::kAuto);

}  // namespace refgrasp::detector
