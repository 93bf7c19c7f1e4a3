#pragma once
// Reading image files from untrusted input: the file must be a regular file, its format one of
// PNG, JPEG, BMP, PNM (P1-P6), TIFF or WebP (found by its signature, not its name), and its
// declared size within a pixel-count limit, all checked from the header BEFORE decoding, so a
// small file declaring 20000x20000 pixels is refused instead of allocating gigabytes.
// The decoders' own messages (libpng, libjpeg) never reach stderr: they become the one-line
// error; a truncated file is reported as "truncated" and any libjpeg warning (corrupt data) makes
// the image unusable rather than silently half-decoded.
#include <cstdint>
#include <string>
#include <vector>
#include <opencv2/core.hpp>

namespace refgrasp {

/// Default pixel-count limit (width x height): 2^25 (33.5 Mpx: 8192x4096, a 32 MP photo).
constexpr int64_t kDefaultMaxImagePixels = int64_t{1} << 25;

struct ImageLimits {
  int64_t max_pixels = kDefaultMaxImagePixels;  ///< width x height, > 0
  /// The default, or $REFGRASP_MAX_IMAGE_PIXELS when set to a positive integer.
  static ImageLimits fromEnvironment();
};

/// Header facts (no decoding).
struct ImageHeader {
  std::string format;     ///< "PNG", "JPEG", "BMP", "PNM", "TIFF", "WebP"
  int64_t width = 0, height = 0;
};

enum class ImageMode {
  kGray,       ///< 8-bit, 1 channel (colour converted)
  kColor,      ///< 8-bit BGR
  kAnyColor,   ///< 8-bit gray or BGR, as stored
  kUnchanged,  ///< as stored (depth and channels, alpha kept)
};

/// A decoded image, or the problem with an empty image.
struct ImageRead {
  cv::Mat image;
  std::string error;    ///< "<file>: <problem>", one line ("" when ok)
  std::string problem;  ///< the problem alone
  bool ok() const { return error.empty(); }
};

/// Reads and decodes `path` (never throws; errors name the file).
ImageRead readImage(const std::string& path, ImageMode mode,
                    const ImageLimits& limits = ImageLimits::fromEnvironment());

/// Decodes bytes already in memory; `name` is the file named in errors.
ImageRead decodeImage(const std::string& name, const std::string& bytes, ImageMode mode,
                      const ImageLimits& limits = ImageLimits::fromEnvironment());

/// Encodes `image` in memory (the format from the path's extension, OpenCV's imwrite params) and
/// writes the bytes; returns "" or the problem ("no encoder for '.xyz'", "No space left on
/// device"). The encoders never write the file themselves, so libpng's and libjpeg's own messages
/// on a failed write (a full disk) never reach stderr.
std::string writeImageFile(const std::string& path, const cv::Mat& image,
                           const std::vector<int>& params = {});

/// The header of an image in memory; returns "" on success, else the problem (no file name).
std::string probeImageHeader(const std::string& bytes, ImageHeader* header);

}  // namespace refgrasp
