#include "detector/object.h"

#include <cmath>
#include <filesystem>

#include "core/error.h"
#include "core/geometry.h"
#include "core/image_io.h"
#include "core/yaml.h"

namespace refgrasp::detector {
namespace fs = std::filesystem;

namespace {

constexpr double kMinRegionAreaPx2 = 16.0;
// A pattern outline is a few to a few hundred points; the simplicity test is quadratic.
constexpr size_t kMaxRegionPoints = 1000;

double cross2(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// Proper or touching intersection of segments ab and cd.
bool segmentsIntersect(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                       const Eigen::Vector2d& c, const Eigen::Vector2d& d) {
  const double d1 = cross2(b - a, c - a), d2 = cross2(b - a, d - a);
  const double d3 = cross2(d - c, a - c), d4 = cross2(d - c, b - c);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0)))
    return true;
  auto onSeg = [](const Eigen::Vector2d& p, const Eigen::Vector2d& q, const Eigen::Vector2d& r) {
    return std::min(p.x(), q.x()) <= r.x() && r.x() <= std::max(p.x(), q.x()) &&
           std::min(p.y(), q.y()) <= r.y() && r.y() <= std::max(p.y(), q.y());
  };
  return (d1 == 0 && onSeg(a, b, c)) || (d2 == 0 && onSeg(a, b, d)) ||
         (d3 == 0 && onSeg(c, d, a)) || (d4 == 0 && onSeg(c, d, b));
}

bool isSimplePolygon(const std::vector<Eigen::Vector2d>& p) {
  const size_t n = p.size();
  for (size_t i = 0; i < n; ++i)
    for (size_t j = i + 1; j < n; ++j) {
      if (j == i + 1 || (i == 0 && j == n - 1)) continue;  // adjacent edges share a vertex
      if (segmentsIntersect(p[i], p[(i + 1) % n], p[j], p[(j + 1) % n])) return false;
    }
  return true;
}

}  // namespace

ObjectModel makeObjectModel(const std::string& name, const cv::Mat& reference_gray,
                            const std::optional<Intrinsics>& camera,
                            const std::optional<Pose>& reference_cMo,
                            std::vector<Eigen::Vector2d> polygon,
                            const Eigen::Vector3d& plane_normal_o, double plane_offset_m,
                            const std::string& source) {
  const std::string where = source.empty() ? "object '" + name + "'" : source;
  auto fail = [&](const std::string& field, const std::string& problem) {
    throw ConfigError(where, field, problem);
  };
  if (reference_gray.empty()) fail("reference_image", "empty image");
  if (reference_gray.type() != CV_8UC1) fail("reference_image", "expected 8-bit grayscale");
  const int W = reference_gray.cols, H = reference_gray.rows;
  if (camera) {
    try {
      camera->check();
    } catch (const std::invalid_argument& e) {
      fail("camera", e.what());
    }
    if (camera->width != W || camera->height != H)
      fail("camera", "size " + std::to_string(camera->width) + "x" +
                         std::to_string(camera->height) + " differs from the reference image " +
                         std::to_string(W) + "x" + std::to_string(H));
  }
  if (reference_cMo) {
    if (!camera) fail("camera", "required when reference_pose is given");
    if (!reference_cMo->isFinite()) fail("reference_pose", "must be finite");
  }
  if (!plane_normal_o.allFinite() || !std::isfinite(plane_offset_m))
    fail("pattern_plane", "must be finite");
  if (plane_normal_o.norm() < 1e-12) fail("pattern_plane.normal", "must be non-zero");

  if (polygon.empty()) {
    polygon = {{-0.5, -0.5}, {W - 0.5, -0.5}, {W - 0.5, H - 0.5}, {-0.5, H - 0.5}};
  } else {
    if (polygon.size() < 3) fail("pattern_region", "needs at least 3 points");
    if (polygon.size() > kMaxRegionPoints)
      fail("pattern_region", std::to_string(polygon.size()) + " points, more than the limit of " +
                                 std::to_string(kMaxRegionPoints));
    for (size_t i = 0; i < polygon.size(); ++i)
      if (!polygon[i].allFinite())
        fail("pattern_region", "point " + std::to_string(i) + " is not finite");
    if (!isSimplePolygon(polygon)) fail("pattern_region", "polygon is self-intersecting");
    if (std::abs(signedArea(polygon)) < kMinRegionAreaPx2)
      fail("pattern_region", "polygon area below 16 px^2");
    // The outline may run past the image (a cropped reference); features come from the part
    // inside it, so that part must not be empty.
    const auto inside = clipToBox(polygon, {-0.5, -0.5}, {W - 0.5, H - 0.5});
    if (std::abs(signedArea(inside)) < kMinRegionAreaPx2)
      fail("pattern_region", "polygon lies outside the " + std::to_string(W) + "x" +
                                 std::to_string(H) + " image (less than 16 px^2 inside it)");
  }

  ObjectModel m;
  m.name = name;
  m.source = source;
  m.reference = reference_gray.clone();
  m.camera = camera;
  m.reference_cMo = reference_cMo;
  m.pattern_polygon_px = polygon;
  m.plane_normal_o = plane_normal_o;
  m.plane_offset_m = plane_offset_m;
  if (polygon.size() == 4) {
    for (int i = 0; i < 4; ++i) m.corners_px[i] = polygon[i];
  } else {
    Eigen::Vector2d lo = polygon[0], hi = polygon[0];
    for (const auto& p : polygon) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    m.corners_px = {lo, Eigen::Vector2d(hi.x(), lo.y()), hi, Eigen::Vector2d(lo.x(), hi.y())};
  }
  if (reference_cMo) {
    std::array<Eigen::Vector2d, 4> und;
    for (int i = 0; i < 4; ++i) und[i] = camera->undistortPixel(m.corners_px[i]);
    m.target = makePlanarTarget(camera->K(), *reference_cMo, plane_normal_o, plane_offset_m, und);
    if (!m.target)
      fail("pattern_plane", "the pattern corners' viewing rays do not meet the plane in front of "
                            "the reference camera");
  }
  return m;
}

Intrinsics textureCamera(const cv::Mat& texture, double width_m, double z_ref_m) {
  const double f = texture.cols * z_ref_m / width_m;
  return Intrinsics::pinhole(texture.cols, texture.rows, f, (texture.cols - 1) / 2.0,
                             (texture.rows - 1) / 2.0);
}

ObjectModel textureObject(const std::string& name, const cv::Mat& texture_gray, double width_m,
                          double z_ref_m) {
  return makeObjectModel(name, texture_gray, textureCamera(texture_gray, width_m, z_ref_m),
                         Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, z_ref_m)));
}

ObjectModel cylinderObject(const std::string& name, const cv::Mat& label_gray, double radius_m,
                           double label_width_m, double label_height_m, std::vector<Eigen::Vector2d> polygon,
                           const std::string& source) {
  const std::string where = source.empty() ? "object '" + name + "'" : source;
  if (label_gray.empty()) throw ConfigError(where, "reference_image", "empty image");
  const CylinderLabel label{radius_m, label_width_m, label_height_m, label_gray.cols, label_gray.rows};
  label.check(where);
  // The flat label seen square-on from z_ref: f = W z / w across, H z / h down (a label's pixels
  // need not be square on the surface).
  constexpr double z_ref = 0.5;
  Intrinsics cam = Intrinsics::pinhole(label_gray.cols, label_gray.rows, label_gray.cols * z_ref / label_width_m,
                                       (label_gray.cols - 1) / 2.0, (label_gray.rows - 1) / 2.0);
  cam.fy = label_gray.rows * z_ref / label_height_m;
  ObjectModel m = makeObjectModel(name, label_gray, cam, Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, z_ref)),
                                  std::move(polygon), Eigen::Vector3d::UnitZ(), 0, source);
  m.cylinder = label;
  return m;
}

namespace {

// A canonical name for a definition file, to find cycles among several-view definitions.
std::string canonicalPath(const std::string& path) {
  std::error_code ec;
  const fs::path c = fs::weakly_canonical(fs::path(path), ec);
  return ec ? path : c.string();
}

std::vector<Eigen::Vector2d> readPolygon(const YamlFile& f, const YAML::Node& r) {
  std::vector<Eigen::Vector2d> polygon;
  if (!f.has(r, "pattern_region")) return polygon;
  const YAML::Node seq = f.get(r, "pattern_region");
  if (!seq.IsSequence()) f.fail("pattern_region", "expected a list of [u, v] points");
  if (seq.size() > kMaxRegionPoints)
    f.fail("pattern_region", std::to_string(seq.size()) + " points, more than the limit of " +
                                 std::to_string(kMaxRegionPoints));
  for (size_t i = 0; i < seq.size(); ++i) {
    const std::string field = "pattern_region[" + std::to_string(i) + "]";
    if (!seq[i].IsSequence() || seq[i].size() != 2) f.fail(field, "expected [u, v]");
    Eigen::Vector2d p;
    for (int k = 0; k < 2; ++k) {
      if (!seq[i][k].IsScalar()) f.fail(field, "expected two numbers");
      try {
        p[k] = seq[i][k].as<double>();
      } catch (const YAML::Exception&) {
        f.fail(field, "expected two numbers");
      }
    }
    if (!p.allFinite()) f.fail(field, "must be finite");
    polygon.push_back(p);
  }
  return polygon;
}

cv::Mat readReference(const YamlFile& f, const YAML::Node& r) {
  const std::string image_path = f.resolve(f.string(r, "reference_image"));
  const ImageRead image = readImage(image_path, ImageMode::kGray);
  if (!image.ok()) f.fail("reference_image", image.error);
  return image.image;
}

ObjectModel loadPlanar(const YamlFile& f, const std::string& name) {
  const YAML::Node& r = f.root();
  f.onlyKeys(r, "", {"name", "reference_image", "camera", "reference_pose", "pattern_region",
                     "pattern_plane", "pattern_region_exact"});
  const cv::Mat reference = readReference(f, r);
  std::optional<Intrinsics> camera;
  if (f.has(r, "camera")) {
    try {
      camera = loadCameraFile(f.resolve(f.string(r, "camera")));
    } catch (const ConfigError& e) {
      f.fail("camera", e.what());
    }
  }
  std::optional<Pose> ref_cMo;
  if (f.has(r, "reference_pose")) ref_cMo = f.pose(r, "reference_pose");
  const std::vector<Eigen::Vector2d> polygon = readPolygon(f, r);
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double offset = 0;
  if (f.has(r, "pattern_plane")) {
    f.onlyKeys(f.get(r, "pattern_plane"), "pattern_plane", {"normal", "offset"});
    if (f.has(r, "pattern_plane.normal")) normal = f.vec3(r, "pattern_plane.normal");
    offset = f.number(r, "pattern_plane.offset", 0.0);
  }
  ObjectModel m = makeObjectModel(name, reference, camera, ref_cMo, polygon, normal, offset, f.path());
  m.pattern_region_exact = f.boolean(r, "pattern_region_exact", true);
  return m;
}

ObjectModel loadCylinder(const YamlFile& f, const std::string& name) {
  const YAML::Node& r = f.root();
  f.onlyKeys(r, "", {"name", "reference_image", "cylinder", "pattern_region", "pattern_region_exact"});
  f.onlyKeys(f.get(r, "cylinder"), "cylinder", {"radius_m", "label_size_m"});
  const double radius = f.number(r, "cylinder.radius_m");
  const std::vector<double> size = f.numbers(r, "cylinder.label_size_m", 2);
  const cv::Mat label = readReference(f, r);
  const std::vector<Eigen::Vector2d> polygon = readPolygon(f, r);
  ObjectModel m = cylinderObject(name, label, radius, size[0], size[1], polygon, f.path());
  m.pattern_region_exact = f.boolean(r, "pattern_region_exact", true);
  return m;
}

ObjectModel loadDefinition(const std::string& path, std::vector<std::string>* stack);

ObjectModel loadViews(const YamlFile& f, const std::string& name, std::vector<std::string>* stack) {
  const YAML::Node& r = f.root();
  f.onlyKeys(r, "", {"name", "views"});
  const YAML::Node seq = f.get(r, "views");
  if (!seq.IsSequence() || seq.size() == 0) f.fail("views", "expected a non-empty list of {definition, oMv}");
  constexpr size_t kMaxViews = 64;
  if (seq.size() > kMaxViews)
    f.fail("views", std::to_string(seq.size()) + " views, more than the limit of " + std::to_string(kMaxViews));
  ObjectModel m;
  m.name = name;
  m.source = f.path();
  for (size_t i = 0; i < seq.size(); ++i) {
    const std::string field = "views[" + std::to_string(i) + "]";
    f.onlyKeys(seq[i], field, {"definition", "oMv"});
    std::string def;
    ObjectView v;
    try {  // the accessors name fields relative to the list entry
      def = f.resolve(f.string(seq[i], "definition"));
      v.oMv = f.pose(seq[i], "oMv");
    } catch (const ConfigError& e) {
      f.fail(field + "." + e.field(), e.problem());
    }
    const std::string def_field = field + ".definition";
    const std::string canonical = canonicalPath(def);
    for (const std::string& s : *stack)
      if (s == canonical) f.fail(def_field, "cycle: " + def + " includes " + f.path());
    std::shared_ptr<ObjectModel> view;
    try {
      view = std::make_shared<ObjectModel>(loadDefinition(def, stack));
    } catch (const ConfigError& e) {
      f.fail(def_field, e.what());
    }
    if (view->isMultiView())
      f.fail(def_field, def + " has views of its own (a view is planar with reference_pose, or a cylinder)");
    if (!view->has3d())
      f.fail(def_field, def + " has no metric geometry (a view is planar with reference_pose, or a cylinder)");
    v.name = view->name;
    for (const ObjectView& o : m.views)
      if (o.name == v.name) f.fail(def_field, "a second view named '" + v.name + "' (view names must differ)");
    v.model = view;
    m.views.push_back(std::move(v));
  }
  return m;
}

ObjectModel loadDefinition(const std::string& path, std::vector<std::string>* stack) {
  const YamlFile f(path);
  const YAML::Node& r = f.root();
  const std::string name = f.string(r, "name", fs::path(path).stem().string());
  stack->push_back(canonicalPath(path));
  ObjectModel m = f.has(r, "views")      ? loadViews(f, name, stack)
                  : f.has(r, "cylinder") ? loadCylinder(f, name)
                                         : loadPlanar(f, name);
  stack->pop_back();
  return m;
}

}  // namespace

ObjectModel loadObjectDefinition(const std::string& path) {
  std::vector<std::string> stack;
  return loadDefinition(path, &stack);
}

}  // namespace refgrasp::detector
