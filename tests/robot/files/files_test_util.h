#pragma once
// Helpers for the file-source and recording tests: scratch folders, seeded frames.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <random>
#include <sstream>
#include <string>

#include "common/noise_image.h"
#include "common/temp_dir.h"
#include "core/camera.h"
#include "robot/camera.h"

namespace refgrasp::testing_util {

/// An empty scratch folder named after the running test (removed first if it exists).
inline std::filesystem::path testDir(const std::string& suffix = "") {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::filesystem::path d = refgrasp::testing::tempDir("refgrasp_test_files") /
                                  (std::string(info->name()) + suffix);
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d.parent_path());
  return d;
}

inline std::string readText(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// A small pinhole camera (w x h, f = w).
inline Intrinsics smallCamera(int w = 64, int h = 48) {
  return Intrinsics::pinhole(w, h, w, (w - 1) / 2.0, (h - 1) / 2.0);
}

inline StereoRig smallRig(int w = 64, int h = 48) {
  StereoRig rig;
  rig.left = smallCamera(w, h);
  rig.right = smallCamera(w, h);
  rig.right.cx += 0.25;
  rig.lMr = Pose::fromRotationVector({0.001, -0.002, 0.0005}, {0.12, 0.0, 0.0});
  return rig;
}

using refgrasp::testing::noiseImage;  // seeded uniform noise (common/noise_image.h)

inline bool identical(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return false;
  for (int r = 0; r < a.rows; ++r)
    if (std::memcmp(a.ptr(r), b.ptr(r), a.cols * a.elemSize()) != 0) return false;
  return true;
}

}  // namespace refgrasp::testing_util
