#include "core/camera.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "core/error.h"
#include "core/file.h"
#include "core/image_io.h"
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

// ROS camera_info YAML, as camera_calibration_parsers writes it.
const std::set<std::string> kRosKeys = {"image_width", "image_height", "camera_name",
                                        "camera_matrix", "distortion_model",
                                        "distortion_coefficients", "rectification_matrix",
                                        "projection_matrix"};

// {rows, cols, data}: data of rows x cols numbers when rows and cols are given.
std::vector<double> rosMatrix(const YamlFile& f, const std::string& field, int n) {
  const YAML::Node m = f.get(f.root(), field);
  if (m.IsDefined() && !m.IsNull()) f.onlyKeys(m, field, {"rows", "cols", "data"});
  const auto data = f.numbers(f.root(), field + ".data", n);
  if (f.has(f.root(), field + ".rows") || f.has(f.root(), field + ".cols")) {
    const int rows = f.integer(f.root(), field + ".rows"), cols = f.integer(f.root(), field + ".cols");
    if (rows < 0 || cols < 0 || static_cast<size_t>(rows) * static_cast<size_t>(cols) != data.size())
      f.fail(field, "rows x cols (" + std::to_string(rows) + " x " + std::to_string(cols) +
                        ") differs from the " + std::to_string(data.size()) + " numbers of data");
  }
  return data;
}

Intrinsics loadRosYaml(const std::string& path) {
  const YamlFile f(path);
  const YAML::Node& r = f.root();
  f.onlyKeys(r, "", kRosKeys);
  Intrinsics c;
  c.width = f.integer(r, "image_width");
  c.height = f.integer(r, "image_height");
  if (c.width <= 0) f.fail("image_width", "must be positive");
  if (c.height <= 0) f.fail("image_height", "must be positive");
  f.string(r, "camera_name", "");
  const auto K = rosMatrix(f, "camera_matrix", 9);
  // K = [fx s cx; 0 fy cy; 0 0 1]: a transposed (column-major) matrix or a skew is an error,
  // not something to half-read.
  if (K[3] != 0 || K[6] != 0 || K[7] != 0 || K[8] != 1)
    f.fail("camera_matrix.data", "not [fx, 0, cx, 0, fy, cy, 0, 0, 1] (row-major, upper-triangular, "
                                 "last row 0 0 1)");
  if (K[1] != 0) f.fail("camera_matrix.data", "skew (element 1) is not supported, must be 0");
  c.fx = K[0];
  c.cx = K[2];
  c.fy = K[4];
  c.cy = K[5];
  if (c.fx <= 0 || c.fy <= 0) f.fail("camera_matrix.data", "focal lengths must be positive");
  if (f.has(r, "distortion_coefficients")) {
    const std::string model = f.string(r, "distortion_model", "plumb_bob");
    if (model != "plumb_bob" && model != "rational_polynomial")
      f.fail("distortion_model", "unsupported model '" + model + "' (use plumb_bob)");
    const auto d = rosMatrix(f, "distortion_coefficients", -1);
    if (d.size() != 0 && d.size() != 4 && d.size() != 5 && d.size() != 8)
      f.fail("distortion_coefficients.data", "expected 0, 4, 5 or 8 numbers");
    if (d.size() == 8 && (d[5] != 0 || d[6] != 0 || d[7] != 0))
      f.fail("distortion_coefficients.data", "rational terms k4..k6 are not supported");
    for (size_t i = 0; i < std::min<size_t>(5, d.size()); ++i) c.dist[i] = d[i];
  } else {
    f.string(r, "distortion_model", "");
  }
  if (f.has(r, "rectification_matrix")) rosMatrix(f, "rectification_matrix", 9);
  if (f.has(r, "projection_matrix")) rosMatrix(f, "projection_matrix", 12);
  return c;
}

// A minimal XML reader for ViSP's camera files: elements with text, comments, a prolog; no
// attributes, entities, CDATA or DOCTYPE (vpXmlParserCamera writes none). Bounded depth.
struct XmlElement {
  std::string name, text;
  int line = 0;
  std::vector<XmlElement> children;
};

class XmlReader {
 public:
  XmlReader(const std::string& path, const std::string& text) : path_(path), s_(text) {}

  XmlElement document() {
    skipMisc();
    if (!at("<")) fail("no root element (expected ViSP camera XML)");
    XmlElement root = element(0);
    skipMisc();
    if (pos_ < s_.size()) fail("text after the root element");
    return root;
  }

 private:
  [[noreturn]] void fail(const std::string& problem) {
    throw ConfigError(path_, "line " + std::to_string(line()) + ": " + problem);
  }
  // Line of pos_ (pos_ only moves forward: counted incrementally).
  int line() {
    line_ += static_cast<int>(std::count(s_.begin() + counted_, s_.begin() + pos_, '\n'));
    counted_ = pos_;
    return line_;
  }
  bool at(const char* t) const { return s_.compare(pos_, std::strlen(t), t) == 0; }
  void skipSpace() {
    while (pos_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[pos_]))) ++pos_;
  }
  void skipPast(const char* end, const char* what) {
    const size_t e = s_.find(end, pos_);
    if (e == std::string::npos) fail(std::string("unterminated ") + what);
    pos_ = e + std::strlen(end);
  }
  // Whitespace, comments and <?...?> between elements.
  void skipMisc() {
    while (true) {
      skipSpace();
      if (at("<!--")) {
        skipPast("-->", "comment");
      } else if (at("<?")) {
        skipPast("?>", "<?...?>");
      } else if (at("<!")) {
        fail("DOCTYPE and CDATA are not supported");
      } else {
        return;
      }
    }
  }
  std::string name() {
    const size_t a = pos_;
    while (pos_ < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[pos_])) ||
                                s_[pos_] == '_' || s_[pos_] == '-' || s_[pos_] == '.' || s_[pos_] == ':'))
      ++pos_;
    if (pos_ == a) fail("expected an element name");
    return s_.substr(a, pos_ - a);
  }
  XmlElement element(int depth) {
    if (depth > 16) fail("elements nested deeper than 16");
    XmlElement e;
    e.line = line();
    ++pos_;  // '<'
    e.name = name();
    skipSpace();
    if (at("/>")) {
      pos_ += 2;
      return e;
    }
    if (!at(">")) fail("<" + e.name + ">: attributes are not supported");
    ++pos_;
    while (true) {
      const size_t text_end = s_.find('<', pos_);
      if (text_end == std::string::npos) fail("<" + e.name + "> is not closed");
      e.text += s_.substr(pos_, text_end - pos_);
      pos_ = text_end;
      if (at("</")) {
        pos_ += 2;
        const std::string closing = name();
        if (closing != e.name) fail("</" + closing + "> closes <" + e.name + ">");
        skipSpace();
        if (!at(">")) fail("</" + closing + ": expected '>'");
        ++pos_;
        return e;
      }
      if (at("<!--") || at("<?") || at("<!")) {
        skipMisc();
        continue;
      }
      if (++elements_ > 10000) fail("more than 10000 elements");
      e.children.push_back(element(depth + 1));
    }
  }

  std::string path_;
  const std::string& s_;
  size_t pos_ = 0, counted_ = 0;
  int line_ = 1, elements_ = 0;
};

std::string trimmed(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(" \t\r\n") - a + 1);
}

// The children of `e` by name: each at most once, each in `known` (a typo gets "did you mean").
std::map<std::string, const XmlElement*> xmlFields(const std::string& path, const XmlElement& e,
                                                  const std::string& where,
                                                  const std::set<std::string>& known) {
  std::map<std::string, const XmlElement*> out;
  for (const XmlElement& c : e.children) {
    const std::string field = where + "." + c.name;
    if (!known.count(c.name)) throw ConfigError(path, field, "unknown element" + didYouMean(c.name, known));
    if (c.name != "model" && !out.emplace(c.name, &c).second)
      throw ConfigError(path, field, "given twice (line " + std::to_string(c.line) + ")");
  }
  return out;
}

double xmlNumber(const std::string& path, const std::map<std::string, const XmlElement*>& fields,
                 const std::string& where, const std::string& tag) {
  const auto it = fields.find(tag);
  if (it == fields.end()) throw ConfigError(path, where + "." + tag, "missing");
  const std::string s = trimmed(it->second->text);
  try {
    size_t used = 0;
    const double v = std::stod(s, &used);
    if (used != s.size() || !std::isfinite(v)) throw std::invalid_argument(s);
    return v;
  } catch (const std::exception&) {
    throw ConfigError(path, where + "." + tag, "expected a finite number, got '" + s + "'");
  }
}

Intrinsics loadVispXml(const std::string& path) {
  const std::string text = readRegularFile(path, kMaxConfigFileBytes);
  const XmlElement root = XmlReader(path, text).document();
  const XmlElement* cam = root.name == "camera" ? &root : nullptr;
  for (const XmlElement& c : root.children)
    if (!cam && c.name == "camera") cam = &c;
  if (!cam) throw ConfigError(path, "no <camera> element (expected ViSP camera XML)");
  static const std::set<std::string> kCameraTags = {
      "name", "image_width", "image_height", "subsampling_width", "subsampling_height",
      "full_width", "full_height", "model", "additional_information"};
  const auto fields = xmlFields(path, *cam, "camera", kCameraTags);
  Intrinsics c;
  const double w = xmlNumber(path, fields, "camera", "image_width");
  const double h = xmlNumber(path, fields, "camera", "image_height");
  if (w <= 0 || h <= 0 || w != std::floor(w) || h != std::floor(h) || w > 1e9 || h > 1e9)
    throw ConfigError(path, "camera.image_width", "image size must be positive integers");
  c.width = static_cast<int>(w);
  c.height = static_cast<int>(h);
  // ViSP writes one <model> per projection type: perspectiveProjWithoutDistortion and
  // perspectiveProjWithDistortion. Prefer the latter: its kud maps undistorted to distorted
  // normalised coordinates with one radial term, exactly OpenCV's k1.
  const XmlElement* chosen = nullptr;
  bool with_distortion = false;
  std::set<std::string> types;
  for (const XmlElement& m : cam->children) {
    if (m.name != "model") continue;
    const auto mf = xmlFields(path, m, "camera.model",
                              {"type", "px", "py", "u0", "v0", "kud", "kdu", "k1", "k2", "k3", "k4", "k5"});
    const auto t = mf.find("type");
    if (t == mf.end()) throw ConfigError(path, "camera.model.type", "missing");
    const std::string type = trimmed(t->second->text);
    if (!types.insert(type).second)
      throw ConfigError(path, "camera.model", "two models of type " + type);
    if (type == "perspectiveProjWithDistortion") {
      chosen = &m;
      with_distortion = true;
    } else if (type == "perspectiveProjWithoutDistortion") {
      if (!chosen) chosen = &m;
    } else {
      throw ConfigError(path, "camera.model.type",
                        "unsupported projection model '" + type +
                            "' (use perspectiveProjWithDistortion or "
                            "perspectiveProjWithoutDistortion)");
    }
  }
  if (!chosen) throw ConfigError(path, "camera.model", "missing");
  const auto mf = xmlFields(path, *chosen, "camera.model",
                            {"type", "px", "py", "u0", "v0", "kud", "kdu", "k1", "k2", "k3", "k4", "k5"});
  c.fx = xmlNumber(path, mf, "camera.model", "px");
  c.fy = xmlNumber(path, mf, "camera.model", "py");
  c.cx = xmlNumber(path, mf, "camera.model", "u0");
  c.cy = xmlNumber(path, mf, "camera.model", "v0");
  if (c.fx <= 0 || c.fy <= 0) throw ConfigError(path, "camera.model.px", "focal lengths must be positive");
  if (with_distortion) c.dist[0] = xmlNumber(path, mf, "camera.model", "kud");
  return c;
}

}  // namespace

Intrinsics loadCameraFile(const std::string& path) {
  if (const std::string p = regularFileProblem(path, kMaxConfigFileBytes); !p.empty())
    throw ConfigError(path, p);
  const std::string ext = std::filesystem::path(path).extension().string();
  Intrinsics c = ext == ".xml" || ext == ".XML" ? loadVispXml(path) : loadRosYaml(path);
  // Every consumer allocates images of this size (renderer, undistortion, checks).
  if (static_cast<int64_t>(c.width) * c.height > kDefaultMaxImagePixels)
    throw ConfigError(path, "image size " + std::to_string(c.width) + "x" + std::to_string(c.height) +
                                " is more than the " + std::to_string(kDefaultMaxImagePixels) +
                                "-pixel limit of an image");
  return c;
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
  f.onlyKeys(f.root(), "", {"left", "right", "right_in_left"});
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
