#include "core/camera.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "core/error.h"
#include "core/yaml.h"

namespace refgrasp {

Intrinsics Intrinsics::pinhole(int width, int height, double f, double cx, double cy) {
  Intrinsics c;
  c.width = width;
  c.height = height;
  c.fx = c.fy = f;
  c.cx = cx;
  c.cy = cy;
  return c;
}

Eigen::Matrix3d Intrinsics::K() const {
  Eigen::Matrix3d K;
  K << fx, 0, cx, 0, fy, cy, 0, 0, 1;
  return K;
}

bool Intrinsics::hasDistortion() const {
  for (double d : dist)
    if (d != 0.0) return true;
  return false;
}

void Intrinsics::check() const {
  refgrasp::check(width > 0 && height > 0, "camera", "image size must be positive");
  refgrasp::check(std::isfinite(fx) && std::isfinite(fy) && fx > 0 && fy > 0, "camera",
                  "focal lengths must be positive and finite");
  refgrasp::check(std::isfinite(cx) && std::isfinite(cy), "camera",
                  "principal point must be finite");
  for (double d : dist) refgrasp::check(std::isfinite(d), "camera", "distortion must be finite");
}

Eigen::Vector2d Intrinsics::distortNormalized(const Eigen::Vector2d& xn) const {
  const double x = xn.x(), y = xn.y();
  const double r2 = x * x + y * y;
  const double k1 = dist[0], k2 = dist[1], p1 = dist[2], p2 = dist[3], k3 = dist[4];
  const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
  const double xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
  const double yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
  return {fx * xd + cx, fy * yd + cy};
}

Eigen::Vector2d Intrinsics::project(const Eigen::Vector3d& Xc) const {
  return distortNormalized(Eigen::Vector2d(Xc.x() / Xc.z(), Xc.y() / Xc.z()));
}

Eigen::Vector2d Intrinsics::undistortToNormalized(const Eigen::Vector2d& px) const {
  const Eigen::Vector2d xd((px.x() - cx) / fx, (px.y() - cy) / fy);
  if (!hasDistortion()) return xd;
  // Fixed-point iteration as in OpenCV's undistortPoints, then Newton polish.
  Eigen::Vector2d x = xd;
  const double k1 = dist[0], k2 = dist[1], p1 = dist[2], p2 = dist[3], k3 = dist[4];
  for (int i = 0; i < 20; ++i) {
    const double r2 = x.squaredNorm();
    const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
    const double dx = 2 * p1 * x.x() * x.y() + p2 * (r2 + 2 * x.x() * x.x());
    const double dy = p1 * (r2 + 2 * x.y() * x.y()) + 2 * p2 * x.x() * x.y();
    x = Eigen::Vector2d((xd.x() - dx) / radial, (xd.y() - dy) / radial);
  }
  for (int i = 0; i < 5; ++i) {
    const Eigen::Vector2d f = distortNormalized(x) - px;
    Eigen::Matrix2d J;
    const double h = 1e-7;
    for (int k = 0; k < 2; ++k) {
      Eigen::Vector2d xp = x;
      xp[k] += h;
      J.col(k) = (distortNormalized(xp) - distortNormalized(x)) / h;
    }
    x -= J.inverse() * f;
  }
  return x;
}

Eigen::Vector2d Intrinsics::undistortPixel(const Eigen::Vector2d& px) const {
  const Eigen::Vector2d xn = undistortToNormalized(px);
  return {fx * xn.x() + cx, fy * xn.y() + cy};
}

namespace {

Intrinsics loadRosYaml(const std::string& path) {
  const YamlFile f(path);
  const YAML::Node& r = f.root();
  Intrinsics c;
  c.width = f.integer(r, "image_width");
  c.height = f.integer(r, "image_height");
  if (c.width <= 0) f.fail("image_width", "must be positive");
  if (c.height <= 0) f.fail("image_height", "must be positive");
  const auto K = f.numbers(r, "camera_matrix.data", 9);
  c.fx = K[0];
  c.cx = K[2];
  c.fy = K[4];
  c.cy = K[5];
  if (c.fx <= 0 || c.fy <= 0) f.fail("camera_matrix.data", "focal lengths must be positive");
  if (f.has(r, "distortion_coefficients")) {
    const std::string model = f.string(r, "distortion_model", "plumb_bob");
    if (model != "plumb_bob" && model != "rational_polynomial")
      f.fail("distortion_model", "unsupported model '" + model + "' (use plumb_bob)");
    const auto d = f.numbers(r, "distortion_coefficients.data");
    if (d.size() != 0 && d.size() != 4 && d.size() != 5 && d.size() != 8)
      f.fail("distortion_coefficients.data", "expected 0, 4, 5 or 8 numbers");
    if (d.size() == 8 && (d[5] != 0 || d[6] != 0 || d[7] != 0))
      f.fail("distortion_coefficients.data", "rational terms k4..k6 are not supported");
    for (size_t i = 0; i < std::min<size_t>(5, d.size()); ++i) c.dist[i] = d[i];
  }
  return c;
}

// Minimal reader for ViSP's camera XML (vpXmlParserCamera): no attributes, no nesting surprises.
std::string xmlTag(const std::string& text, const std::string& tag, bool* found) {
  const std::regex re("<" + tag + ">\\s*([^<]*?)\\s*</" + tag + ">");
  std::smatch m;
  *found = std::regex_search(text, m, re);
  return *found ? m[1].str() : std::string();
}

double xmlNumber(const std::string& path, const std::string& text, const std::string& tag) {
  bool found = false;
  const std::string s = xmlTag(text, tag, &found);
  if (!found) throw ConfigError(path, tag, "missing");
  try {
    size_t used = 0;
    const double v = std::stod(s, &used);
    if (used != s.size() || !std::isfinite(v)) throw std::invalid_argument(s);
    return v;
  } catch (const std::exception&) {
    throw ConfigError(path, tag, "expected a number, got '" + s + "'");
  }
}

Intrinsics loadVispXml(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError(path, "cannot open for reading");
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  const size_t cam_begin = text.find("<camera>");
  const size_t cam_end = text.find("</camera>");
  if (cam_begin == std::string::npos || cam_end == std::string::npos || cam_end < cam_begin)
    throw ConfigError(path, "no <camera> element (expected ViSP camera XML)");
  const std::string cam = text.substr(cam_begin, cam_end - cam_begin);
  Intrinsics c;
  c.width = static_cast<int>(xmlNumber(path, cam, "image_width"));
  c.height = static_cast<int>(xmlNumber(path, cam, "image_height"));
  if (c.width <= 0 || c.height <= 0) throw ConfigError(path, "image_width", "must be positive");
  // ViSP writes one <model> per projection type: perspectiveProjWithoutDistortion and
  // perspectiveProjWithDistortion. Prefer the latter: its kud maps undistorted to distorted
  // normalised coordinates with one radial term, exactly OpenCV's k1.
  std::string chosen;
  bool with_distortion = false;
  size_t pos = 0;
  while ((pos = cam.find("<model>", pos)) != std::string::npos) {
    const size_t end = cam.find("</model>", pos);
    if (end == std::string::npos) throw ConfigError(path, "model", "unterminated <model>");
    const std::string model = cam.substr(pos, end - pos);
    bool found = false;
    const std::string type = xmlTag(model, "type", &found);
    if (!found) throw ConfigError(path, "model.type", "missing");
    if (type == "perspectiveProjWithDistortion") {
      chosen = model;
      with_distortion = true;
    } else if (type == "perspectiveProjWithoutDistortion") {
      if (chosen.empty()) chosen = model;
    } else {
      throw ConfigError(path, "model.type",
                        "unsupported projection model '" + type +
                            "' (use perspectiveProjWithDistortion or "
                            "perspectiveProjWithoutDistortion)");
    }
    pos = end;
  }
  if (chosen.empty()) throw ConfigError(path, "model", "missing");
  c.fx = xmlNumber(path, chosen, "px");
  c.fy = xmlNumber(path, chosen, "py");
  c.cx = xmlNumber(path, chosen, "u0");
  c.cy = xmlNumber(path, chosen, "v0");
  if (c.fx <= 0 || c.fy <= 0) throw ConfigError(path, "px", "focal lengths must be positive");
  if (with_distortion) c.dist[0] = xmlNumber(path, chosen, "kud");
  return c;
}

}  // namespace

Intrinsics loadCameraFile(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw ConfigError(path, "file not found");
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext == ".xml" || ext == ".XML") return loadVispXml(path);
  return loadRosYaml(path);
}

void saveCameraFile(const std::string& path, const Intrinsics& c, const std::string& name) {
  std::ofstream out(path);
  if (!out) throw ConfigError(path, "cannot open for writing");
  out.precision(10);
  out << "image_width: " << c.width << "\nimage_height: " << c.height
      << "\ncamera_name: " << name << "\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [" << c.fx
      << ", 0, " << c.cx << ", 0, " << c.fy << ", " << c.cy << ", 0, 0, 1]\n"
      << "distortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: ["
      << c.dist[0] << ", " << c.dist[1] << ", " << c.dist[2] << ", " << c.dist[3] << ", "
      << c.dist[4] << "]\n"
      << "rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n"
      << "projection_matrix:\n  rows: 3\n  cols: 4\n  data: [" << c.fx << ", 0, " << c.cx
      << ", 0, 0, " << c.fy << ", " << c.cy << ", 0, 0, 0, 1, 0]\n";
}

StereoRig loadStereoRig(const std::string& path) {
  const YamlFile f(path);
  StereoRig rig;
  const auto loadEye = [&](const char* field) {
    const std::string cam = f.resolve(f.string(f.root(), field));
    try {
      return loadCameraFile(cam);
    } catch (const ConfigError& e) {
      throw ConfigError(path, field, e.what());
    }
  };
  rig.left = loadEye("left");
  rig.right = loadEye("right");
  rig.lMr = f.pose(f.root(), "right_in_left");
  if (rig.baseline() <= 0) f.fail("right_in_left.translation", "baseline must be non-zero");
  return rig;
}

void saveStereoRig(const std::string& path, const StereoRig& rig, const std::string& left_file,
                   const std::string& right_file) {
  std::ofstream out(path);
  if (!out) throw ConfigError(path, "cannot open for writing");
  out.precision(17);
  const Eigen::Vector3d t = rig.lMr.t, r = rig.lMr.rotationVector();
  out << "left: " << left_file << "\nright: " << right_file << "\nright_in_left:\n"
      << "  translation: [" << t.x() << ", " << t.y() << ", " << t.z() << "]\n"
      << "  rotation_vector: [" << r.x() << ", " << r.y() << ", " << r.z() << "]\n";
  if (!out.flush()) throw ConfigError(path, "write failed");
}

}  // namespace refgrasp
