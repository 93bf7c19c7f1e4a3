#include "reference/definition_text.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "core/error.h"
#include "detector/object.h"

namespace refgrasp::reference::detail {

namespace fs = std::filesystem;

void refuse(const std::string& what) { throw std::invalid_argument(what); }

void checkInImage(const Eigen::Vector2d& p, const Intrinsics& cam, const std::string& what) {
  if (!p.allFinite()) refuse(what + ": points must be finite numbers");
  if (p.x() < -0.5 || p.y() < -0.5 || p.x() > cam.width - 0.5 || p.y() > cam.height - 0.5)
    refuse(what + ": (" + yamlNumber(p.x()) + ", " + yamlNumber(p.y()) + ") is outside the " +
           std::to_string(cam.width) + "x" + std::to_string(cam.height) + " image");
}

std::string yamlNumber(double v) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.10g", v);
  return buf;
}

// oneLine's escapes \n, \t, \xNN are YAML's own: a name or path with ':', '#' or a newline
// stays one value.
std::string yamlQuoted(const std::string& s) {
  std::string quoted;
  for (const char c : s) {
    if (c == '"' || c == '\\') quoted += '\\';
    quoted += c;
  }
  return "\"" + oneLine(quoted, size_t{1} << 40) + "\"";
}

std::string relativeTo(const std::string& path, const fs::path& dir) {
  std::error_code ec;
  const fs::path rel = fs::relative(fs::absolute(path), fs::absolute(dir.empty() ? "." : dir), ec);
  return ec || rel.empty() ? fs::absolute(path).string() : rel.string();
}

std::string yamlPose(const Pose& pose) {
  const Eigen::Vector3d t = pose.t, rv = pose.rotationVector();
  const auto triple = [](const Eigen::Vector3d& v) {
    return "[" + yamlNumber(v.x()) + ", " + yamlNumber(v.y()) + ", " + yamlNumber(v.z()) + "]";
  };
  return "{translation: " + triple(t) + ", rotation_vector: " + triple(rv) + "}";
}

std::ofstream openDefinition(const std::string& yaml_path) {
  const fs::path dir = fs::path(yaml_path).parent_path();
  std::error_code ec;
  if (!dir.empty()) fs::create_directories(dir, ec);
  std::ofstream out(yaml_path);
  if (!out) throw OutputError(yaml_path, std::string("cannot open for writing: ") + std::strerror(errno));
  return out;
}

void finishDefinition(std::ofstream& out, const std::string& yaml_path) {
  if (!out.flush()) throw OutputError(yaml_path, std::string("write failed: ") + std::strerror(errno));
  out.close();
  detector::loadObjectDefinition(yaml_path);
}

cv::Mat checkCanvas(const cv::Mat& photo) {
  cv::Mat img;
  if (photo.channels() == 1)
    cv::cvtColor(photo, img, cv::COLOR_GRAY2BGR);
  else
    img = photo.clone();
  return img;
}

int checkThickness(const cv::Mat& canvas) { return std::max(1, canvas.cols / 400); }

}  // namespace refgrasp::reference::detail
