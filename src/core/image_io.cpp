#include "core/image_io.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "core/error.h"
#include "core/file.h"

namespace refgrasp {
namespace {

// Bounds-checked big/little-endian reads; false when past the end.
struct Bytes {
  const std::string& s;
  bool has(size_t pos, size_t n) const { return pos <= s.size() && n <= s.size() - pos; }
  uint32_t u8(size_t p) const { return static_cast<unsigned char>(s[p]); }
  uint32_t be16(size_t p) const { return u8(p) << 8 | u8(p + 1); }
  uint32_t le16(size_t p) const { return u8(p) | u8(p + 1) << 8; }
  uint32_t be32(size_t p) const { return be16(p) << 16 | be16(p + 2); }
  uint32_t le32(size_t p) const { return le16(p) | le16(p + 2) << 16; }
  uint64_t le64(size_t p) const { return le32(p) | uint64_t{le32(p + 4)} << 32; }
  uint64_t be64(size_t p) const { return uint64_t{be32(p)} << 32 | be32(p + 4); }
  bool starts(const char* sig, size_t n) const { return has(0, n) && std::memcmp(s.data(), sig, n) == 0; }
};

std::string probePng(const Bytes& b, ImageHeader* h) {
  if (!b.has(8, 25) || std::memcmp(b.s.data() + 12, "IHDR", 4) != 0)
    return "truncated PNG (no complete IHDR header)";
  h->width = b.be32(16);
  h->height = b.be32(20);
  // The chunk chain must reach IEND: a file cut short is "truncated" before any decoding.
  size_t pos = 8;
  while (b.has(pos, 8)) {
    const uint64_t len = b.be32(pos);
    const bool iend = std::memcmp(b.s.data() + pos + 4, "IEND", 4) == 0;
    if (len > 0x7fffffffu) return "corrupt PNG (chunk length out of range)";
    if (!b.has(pos, 12 + len)) break;
    pos += 12 + len;
    if (iend) return "";
  }
  return "truncated PNG (the file ends before its IEND chunk)";
}

std::string probeJpeg(const Bytes& b, ImageHeader* h) {
  size_t pos = 2;
  while (true) {
    while (b.has(pos, 1) && b.u8(pos) != 0xFF) ++pos;  // garbage between markers: libjpeg warns
    while (b.has(pos, 1) && b.u8(pos) == 0xFF) ++pos;  // fill bytes
    if (!b.has(pos, 1)) return "truncated JPEG (no frame header)";
    const uint32_t m = b.u8(pos++);
    if (m == 0xD8 || m == 0x01 || (m >= 0xD0 && m <= 0xD7)) continue;  // no length
    if (m == 0xD9 || m == 0xDA) return "corrupt JPEG (no frame header before the image data)";
    if (!b.has(pos, 2)) return "truncated JPEG (no frame header)";
    const uint32_t len = b.be16(pos);
    if (len < 2) return "corrupt JPEG (marker length below 2)";
    const bool sof = m >= 0xC0 && m <= 0xCF && m != 0xC4 && m != 0xC8 && m != 0xCC;
    if (sof) {
      if (!b.has(pos, 7)) return "truncated JPEG (incomplete frame header)";
      h->height = b.be16(pos + 3);
      h->width = b.be16(pos + 5);
      if (h->height == 0) return "unsupported JPEG (height given after the scan, DNL)";
      // Decoding from memory, libjpeg pads a cut file silently: the end-of-image marker must be
      // there (trailing bytes after it are allowed).
      const size_t eoi = b.s.rfind("\xff\xd9");
      if (eoi == std::string::npos || eoi < pos + len) return "truncated JPEG (no end-of-image marker)";
      return "";
    }
    pos += len;
  }
}

std::string probeBmp(const Bytes& b, ImageHeader* h) {
  if (!b.has(0, 26)) return "truncated BMP header";
  const uint32_t info = b.le32(14);
  if (info == 12) {  // OS/2 BITMAPCOREHEADER
    h->width = b.le16(18);
    h->height = b.le16(20);
  } else {
    h->width = static_cast<int32_t>(b.le32(18));
    h->height = static_cast<int32_t>(b.le32(22));  // negative: top-down rows
    if (h->height < 0) h->height = -h->height;
  }
  return "";
}

// PNM: "P<digit>", then width and height as decimal numbers separated by whitespace or comments.
std::string probePnm(const Bytes& b, ImageHeader* h) {
  size_t pos = 2;
  int64_t v[2] = {0, 0};
  for (int64_t& x : v) {
    while (b.has(pos, 1)) {
      const char c = b.s[pos];
      if (c == '#') {
        while (b.has(pos, 1) && b.s[pos] != '\n' && b.s[pos] != '\r') ++pos;
      } else if (std::isspace(static_cast<unsigned char>(c))) {
        ++pos;
      } else {
        break;
      }
    }
    if (!b.has(pos, 1) || !std::isdigit(static_cast<unsigned char>(b.s[pos])))
      return "corrupt PNM header (no image size)";
    while (b.has(pos, 1) && std::isdigit(static_cast<unsigned char>(b.s[pos]))) {
      x = x * 10 + (b.s[pos++] - '0');
      if (x > (int64_t{1} << 40)) return "corrupt PNM header (size out of range)";
    }
  }
  h->width = v[0];
  h->height = v[1];
  return "";
}

std::string probeTiff(const Bytes& b, ImageHeader* h) {
  const bool le = b.s[0] == 'I';
  const auto u16 = [&](size_t p) { return le ? b.le16(p) : b.be16(p); };
  const auto u32 = [&](size_t p) { return le ? b.le32(p) : b.be32(p); };
  const auto u64 = [&](size_t p) { return le ? b.le64(p) : b.be64(p); };
  const bool big = u16(2) == 43;
  const size_t entry = big ? 20 : 12;
  const uint64_t ifd = big ? (b.has(8, 8) ? u64(8) : 0) : u32(4);
  if (ifd == 0 || !b.has(ifd, big ? 8 : 2)) return "truncated TIFF (no image directory)";
  const uint64_t n = big ? u64(ifd) : u16(ifd);
  const size_t first = ifd + (big ? 8 : 2);
  bool w = false, hh = false;
  for (uint64_t i = 0; i < n && b.has(first + i * entry, entry); ++i) {
    const size_t e = first + i * entry;
    const uint32_t tag = u16(e), type = u16(e + 2);
    const size_t value = e + (big ? 12 : 8);
    if (tag != 256 && tag != 257) continue;
    int64_t v = 0;
    if (type == 3)
      v = u16(value);
    else if (type == 4)
      v = u32(value);
    else if (type == 16 && big)
      v = static_cast<int64_t>(std::min<uint64_t>(u64(value), uint64_t{1} << 40));
    else
      return "corrupt TIFF (image size of an unexpected type)";
    (tag == 256 ? h->width : h->height) = v;
    (tag == 256 ? w : hh) = true;
  }
  if (!w || !hh) return "corrupt TIFF (no image width or length)";
  return "";
}

std::string probeWebp(const Bytes& b, ImageHeader* h) {
  if (!b.has(12, 8)) return "truncated WebP header";
  const char* chunk = b.s.data() + 12;
  const size_t d = 20;
  if (std::memcmp(chunk, "VP8 ", 4) == 0) {
    if (!b.has(d, 10)) return "truncated WebP header";
    h->width = b.le16(d + 6) & 0x3fff;
    h->height = b.le16(d + 8) & 0x3fff;
  } else if (std::memcmp(chunk, "VP8L", 4) == 0) {
    if (!b.has(d, 5)) return "truncated WebP header";
    const uint32_t bits = b.le32(d + 1);
    h->width = (bits & 0x3fff) + 1;
    h->height = ((bits >> 14) & 0x3fff) + 1;
  } else if (std::memcmp(chunk, "VP8X", 4) == 0) {
    if (!b.has(d, 10)) return "truncated WebP header";
    h->width = (b.le32(d + 4) & 0xffffff) + 1;
    h->height = (b.le32(d + 7) & 0xffffff) + 1;
  } else {
    return "unsupported WebP chunk";
  }
  return "";
}

// The decoders print to stderr (libpng's default handlers, libjpeg's output_message). While one
// decodes, file descriptor 2 points at a memory file; what they wrote becomes part of our error.
// Process-wide, hence the mutex: stderr written by another thread in that window is captured too.
// REFGRASP_DECODER_MESSAGES=show leaves stderr alone (debugging a crash inside a decoder).
class DecoderMessages {
 public:
  DecoderMessages() {
    static const bool show = [] {
      const char* e = std::getenv("REFGRASP_DECODER_MESSAGES");
      return e && std::string(e) == "show";
    }();
    if (show || sink() < 0) return;
    std::fflush(stderr);
    saved_ = ::dup(2);
    if (saved_ >= 0 && ::dup2(sink(), 2) < 0) {
      ::close(saved_);
      saved_ = -1;
    }
  }
  ~DecoderMessages() { restore(); }
  /// Restores stderr; the text written meanwhile.
  std::string take() {
    if (saved_ < 0) return "";
    restore();
    std::string text;
    const off_t size = ::lseek(sink(), 0, SEEK_END);
    if (size > 0) {
      text.resize(static_cast<size_t>(std::min<off_t>(size, 4096)));
      const ssize_t n = ::pread(sink(), &text[0], text.size(), 0);
      text.resize(n > 0 ? static_cast<size_t>(n) : 0);
    }
    if (::ftruncate(sink(), 0) != 0) { /* next capture appends: harmless */ }
    ::lseek(sink(), 0, SEEK_SET);
    return text;
  }

 private:
  static int sink() {
    static const int fd = [] {
      int f = ::memfd_create("refgrasp_decoder_messages", MFD_CLOEXEC);
      if (f < 0) {
        std::FILE* t = std::tmpfile();
        f = t ? ::dup(::fileno(t)) : -1;
        if (t) std::fclose(t);
      }
      return f;
    }();
    return fd;
  }
  void restore() {
    if (saved_ < 0 || restored_) return;
    std::fflush(stderr);
    ::dup2(saved_, 2);
    ::close(saved_);
    restored_ = true;
  }
  int saved_ = -1;
  bool restored_ = false;
};

std::mutex& decodeMutex() {
  static std::mutex m;
  return m;
}

// The decoder's lines joined into one, without the ones that do not matter.
// libpng's warnings (e.g. an sRGB profile it knows to be wrong) do not make an image unusable.
std::string decoderText(const std::string& text) {
  std::string out;
  size_t a = 0;
  while (a < text.size()) {
    size_t e = text.find('\n', a);
    if (e == std::string::npos) e = text.size();
    const std::string line = text.substr(a, e - a);
    a = e + 1;
    if (line.empty() || line.rfind("libpng warning:", 0) == 0) continue;
    out += (out.empty() ? "" : "; ") + line;
  }
  return oneLine(out, 200);
}

int cvFlags(ImageMode mode) {
  switch (mode) {
    case ImageMode::kGray: return cv::IMREAD_GRAYSCALE;
    case ImageMode::kColor: return cv::IMREAD_COLOR;
    case ImageMode::kAnyColor: return cv::IMREAD_ANYCOLOR;
    case ImageMode::kUnchanged: return cv::IMREAD_UNCHANGED;
  }
  return cv::IMREAD_UNCHANGED;
}

}  // namespace

ImageLimits ImageLimits::fromEnvironment() {
  ImageLimits l;
  if (const char* e = std::getenv("REFGRASP_MAX_IMAGE_PIXELS"); e && *e) {
    char* end = nullptr;
    const long long v = std::strtoll(e, &end, 10);
    if (end && *end == '\0' && v > 0) l.max_pixels = v;
  }
  return l;
}

std::string probeImageHeader(const std::string& bytes, ImageHeader* h) {
  const Bytes b{bytes};
  std::string problem;
  if (b.starts("\x89PNG\r\n\x1a\n", 8)) {
    h->format = "PNG";
    problem = probePng(b, h);
  } else if (b.starts("\xff\xd8\xff", 3)) {
    h->format = "JPEG";
    problem = probeJpeg(b, h);
  } else if (b.starts("BM", 2)) {
    h->format = "BMP";
    problem = probeBmp(b, h);
  } else if (b.has(0, 3) && b.s[0] == 'P' && b.s[1] >= '1' && b.s[1] <= '6' &&
             std::isspace(static_cast<unsigned char>(b.s[2]))) {
    h->format = "PNM";
    problem = probePnm(b, h);
  } else if (b.starts("II*\0", 4) || b.starts("MM\0*", 4) || b.starts("II+\0", 4) ||
             b.starts("MM\0+", 4)) {
    h->format = "TIFF";
    problem = probeTiff(b, h);
  } else if (b.has(0, 12) && std::memcmp(bytes.data(), "RIFF", 4) == 0 &&
             std::memcmp(bytes.data() + 8, "WEBP", 4) == 0) {
    h->format = "WebP";
    problem = probeWebp(b, h);
  } else {
    return bytes.empty() ? "empty file, not an image"
                         : "not an image in a supported format (PNG, JPEG, BMP, PNM, TIFF, WebP)";
  }
  if (problem.empty() && (h->width <= 0 || h->height <= 0))
    problem = h->format + " header declares an empty image (" + std::to_string(h->width) + "x" +
              std::to_string(h->height) + ")";
  return problem;
}

ImageRead decodeImage(const std::string& name, const std::string& bytes, ImageMode mode,
                      const ImageLimits& limits) {
  ImageRead r;
  const auto fail = [&](const std::string& problem) {
    r.image.release();
    r.problem = problem;
    r.error = oneLine(name, 1000) + ": " + problem;
    return r;
  };
  ImageHeader h;
  if (const std::string p = probeImageHeader(bytes, &h); !p.empty()) return fail(p);
  const std::string size = std::to_string(h.width) + "x" + std::to_string(h.height);
  // Beyond int: OpenCV cannot even hold it; beyond the limit: refused before any allocation.
  if (h.width > (1 << 30) || h.height > (1 << 30) || h.width * h.height > limits.max_pixels)
    return fail(h.format + " declares " + size + " pixels, more than the limit of " +
                std::to_string(limits.max_pixels) + " pixels (REFGRASP_MAX_IMAGE_PIXELS)");
  if (bytes.size() > static_cast<size_t>(INT32_MAX)) return fail("file too large for a decoder");
  std::string messages;
  {
    const std::lock_guard<std::mutex> lock(decodeMutex());
    DecoderMessages capture;
    try {
      const cv::Mat buf(1, static_cast<int>(bytes.size()), CV_8UC1,
                        const_cast<char*>(bytes.data()));
      r.image = cv::imdecode(buf, cvFlags(mode));
    } catch (const cv::Exception& e) {
      r.image.release();
      messages = e.err + "\n";
    } catch (const std::bad_alloc&) {
      r.image.release();
      messages = "out of memory\n";
    }
    messages = capture.take() + messages;
  }
  const std::string said = decoderText(messages);
  const std::string detail = said.empty() ? "" : " (" + said + ")";
  if (h.format == "JPEG" && said.find("Premature end of JPEG file") != std::string::npos)
    return fail("truncated JPEG" + detail);
  if (r.image.empty()) return fail("cannot decode the " + h.format + " image (corrupt)" + detail);
  if (h.format == "JPEG" && !said.empty()) return fail("corrupt JPEG" + detail);
  const bool as_declared = (r.image.cols == h.width && r.image.rows == h.height) ||
                           (r.image.cols == h.height && r.image.rows == h.width);  // EXIF rotation
  if (!as_declared)
    return fail(h.format + " decoded as " + std::to_string(r.image.cols) + "x" +
                std::to_string(r.image.rows) + ", its header declares " + size);
  return r;
}

ImageRead readImage(const std::string& path, ImageMode mode, const ImageLimits& limits) {
  // The compressed file of an image within the limit: far below 8 bytes per pixel.
  const uint64_t max_bytes = static_cast<uint64_t>(limits.max_pixels) * 8 + (1 << 20);
  try {
    return decodeImage(path, readRegularFile(path, max_bytes), mode, limits);
  } catch (const ConfigError& e) {
    ImageRead r;
    r.error = e.what();
    r.problem = e.problem();
    return r;
  }
}

std::string writeImageFile(const std::string& path, const cv::Mat& image, const std::vector<int>& params) {
  const size_t dot = path.find_last_of("./");
  const std::string ext = dot == std::string::npos || path[dot] != '.' ? "" : path.substr(dot);
  std::vector<uchar> bytes;
  try {
    if (ext.empty() || !cv::imencode(ext, image, bytes, params)) return "no encoder for '" + ext + "'";
  } catch (const cv::Exception& e) {
    return "cannot encode the image: " + e.err;
  }
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return std::strerror(errno);
  errno = 0;
  const bool written = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  int err = errno;
  const bool closed = std::fclose(f) == 0;
  if (!err) err = errno;
  if (written && closed) return "";
  return err ? std::strerror(err) : "I/O error";
}

}  // namespace refgrasp
