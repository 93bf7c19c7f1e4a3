#pragma once
// Test helpers for hostile input: the one-line ConfigError a call throws, hostile
// images in memory, and variants of the shipped config files.
#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "common/app_run.h"
#include "common/noise_image.h"
#include "core/error.h"

namespace refgrasp::testing {

/// what() of the ConfigError `f` throws (checked to be one line); "(no error)" if none.
template <class F>
std::string configErrorOf(F f) {
  try {
    f();
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    return e.what();
  }
  return "(no error)";
}

inline std::string encodeImage(const std::string& ext, const cv::Mat& img) {
  std::vector<uchar> buf;
  EXPECT_TRUE(cv::imencode(ext, img, buf));
  return std::string(buf.begin(), buf.end());
}

/// A small PNG whose IHDR declares w x h pixels (a decompression "bomb" in its header).
inline std::string pngDeclaring(uint32_t w, uint32_t h) {
  std::mt19937_64 rng(16);
  std::string png = encodeImage(".png", noiseImage(rng, 16, 16));
  for (int i = 0; i < 4; ++i) {
    png[16 + i] = static_cast<char>(w >> (24 - 8 * i));
    png[20 + i] = static_cast<char>(h >> (24 - 8 * i));
  }
  return png;
}

/// A JPEG with garbage after its APP0 segment: libjpeg warns "3 extraneous bytes before marker
/// 0x.." and decodes anyway.
inline std::string corruptJpeg(const std::string& jpg) {
  const size_t at = 4 + (static_cast<unsigned char>(jpg[4]) << 8 | static_cast<unsigned char>(jpg[5]));
  return jpg.substr(0, at) + "abc" + jpg.substr(at);
}

inline std::string replaceAll(std::string s, const std::string& from, const std::string& to) {
  for (size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size()))
    s.replace(at, from.size(), to);
  return s;
}

/// The shipped file `rel` (config/...) with its relative paths made absolute and the first `from`
/// replaced by `to`, written to `dest`; returns dest.
inline std::string shippedVariant(const std::string& rel, const std::filesystem::path& dest,
                                  const std::string& from, const std::string& to) {
  const std::string src = REFGRASP_SOURCE_DIR;
  std::string s = readFile(src + "/" + rel);
  s = replaceAll(s, "../../media/", src + "/media/");
  s = replaceAll(s, "../objects/", src + "/config/objects/");
  s = replaceAll(s, "stereo_rig: cameras/", "stereo_rig: " + src + "/config/cameras/");
  const size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) s.replace(at, from.size(), to);
  std::ofstream(dest) << s;
  return dest.string();
}

}  // namespace refgrasp::testing
