#include "robot/sim/scenario.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <set>

#include "core/cylinder.h"
#include "core/error.h"
#include "core/image_io.h"
#include "core/yaml.h"

namespace refgrasp::sim {

std::vector<TexturedPlane> boxFaces(const Eigen::Vector3d& size_m, const Eigen::Vector3d& centre,
                                    const std::array<cv::Mat, 6>& textures,
                                    const std::array<Eigen::Vector3d, 6>& rows) {
  std::vector<TexturedPlane> faces;
  for (int i = 0; i < 6; ++i) {
    const int axis = i / 2;
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    n[axis] = i % 2 ? 1 : -1;  // outward normal
    // Face frame: z inward (texture seen from outside), y along the rows, x = y x z.
    const Eigen::Vector3d z = -n, y = rows[static_cast<size_t>(i)].normalized(), x = y.cross(z);
    Eigen::Matrix3d R;
    R << x, y, z;
    const auto extent = [&](const Eigen::Vector3d& d) { return std::abs(d.dot(size_m)); };
    faces.push_back({textures[static_cast<size_t>(i)], extent(x), extent(y),
                     Pose(R, centre + n * size_m[axis] / 2)});
  }
  return faces;
}

Solid cylinderSolid(double radius_m, double height_m) {
  Eigen::Matrix3d R;  // x_s = x_o, y_s = -z_o, z_s = y_o
  R << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  return {Pose(R, Eigen::Vector3d(0, 0, radius_m)), Eigen::Vector3d(radius_m, radius_m, height_m / 2), true};
}

namespace {

namespace fs = std::filesystem;

constexpr double kPlaneThickness = 0.001;  // solid of a plane object, behind its face
constexpr double kSlab = 0.5;              // thickness of the floor's and the walls' solids
// Bounds that keep a run finite and its buffers small (config/scenarios/README.md).
constexpr double kMaxDurationS = 3600;
constexpr size_t kMaxObjects = 256;

// Reads one scenario; every accessor throws ConfigError naming the file and the dotted field.
class Reader {
 public:
  explicit Reader(const std::string& path) : f_(path) {}

  const YAML::Node& root() const { return f_.root(); }
  const YamlFile& file() const { return f_; }

  void onlyKeys(const YAML::Node& node, const std::string& where, const std::set<std::string>& keys) const {
    f_.onlyKeys(node, where, keys);
  }

  YAML::Node section(const YAML::Node& node, const std::string& key, const std::string& where) const {
    const YAML::Node n = f_.get(node, key);
    if (!n.IsDefined() || n.IsNull()) f_.fail(join(where, key), "missing");
    if (!n.IsMap()) f_.fail(join(where, key), "expected a mapping");
    return n;
  }

  // The accessors below take `where` (the dotted path of `node`) so errors name the full field.
  double number(const YAML::Node& node, const std::string& where, const std::string& key) const {
    return prefixed(where, [&] { return f_.number(node, key); });
  }
  double number(const YAML::Node& node, const std::string& where, const std::string& key, double fallback) const {
    return prefixed(where, [&] { return f_.number(node, key, fallback); });
  }
  double nonNegative(const YAML::Node& node, const std::string& where, const std::string& key, double fallback,
                     double max = 1e9) const {
    const double v = number(node, where, key, fallback);
    if (v < 0) f_.fail(join(where, key), "must be >= 0");
    if (v > max) f_.fail(join(where, key), "must be at most " + shortNumber(max));
    return v;
  }
  static std::string shortNumber(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
  }
  std::string string(const YAML::Node& node, const std::string& where, const std::string& key) const {
    return prefixed(where, [&] { return f_.string(node, key); });
  }
  std::string string(const YAML::Node& node, const std::string& where, const std::string& key,
                     const std::string& fallback) const {
    return prefixed(where, [&] { return f_.string(node, key, fallback); });
  }
  bool boolean(const YAML::Node& node, const std::string& where, const std::string& key, bool fallback) const {
    return prefixed(where, [&] { return f_.boolean(node, key, fallback); });
  }
  Pose pose(const YAML::Node& node, const std::string& where, const std::string& key) const {
    return prefixed(where, [&] { return f_.pose(node, key); });
  }
  double positive(const YAML::Node& node, const std::string& where, const std::string& key) const {
    const double v = number(node, where, key);
    if (v <= 0) f_.fail(join(where, key), "must be positive");
    return v;
  }
  std::vector<double> numbers(const YAML::Node& node, const std::string& where, const std::string& key, int n) const {
    return prefixed(where, [&] { return f_.numbers(node, key, n); });
  }
  Eigen::Vector3d positiveSize(const YAML::Node& node, const std::string& where, const std::string& key,
                               int n) const {
    const auto v = numbers(node, where, key, n);
    for (double x : v)
      if (x <= 0) f_.fail(join(where, key), "sizes must be positive");
    return Eigen::Vector3d(v[0], v[1], n == 3 ? v[2] : 0.0);
  }

  /// A grayscale texture, resolved relative to the scenario; loaded once per path.
  cv::Mat texture(const YAML::Node& node, const std::string& where, const std::string& key) {
    const std::string path = f_.resolve(string(node, where, key));
    const auto it = textures_.find(path);
    if (it != textures_.end()) return it->second;
    std::error_code ec;
    if (!fs::exists(path, ec)) f_.fail(join(where, key), "texture file not found: " + path);
    const ImageRead img = readImage(path, ImageMode::kGray);
    if (!img.ok()) f_.fail(join(where, key), "cannot read image: " + img.error);
    textures_[path] = img.image;
    return img.image;
  }

  static std::string join(const std::string& where, const std::string& key) {
    return where.empty() ? key : where + "." + key;
  }

 private:
  template <class F>
  auto prefixed(const std::string& where, F fn) const -> decltype(fn()) {
    if (where.empty()) return fn();
    try {
      return fn();
    } catch (const ConfigError& e) {
      const std::string head = e.file() + ": " + e.field() + ": ";
      const std::string what = e.what();
      const std::string problem = what.rfind(head, 0) == 0 ? what.substr(head.size()) : what;
      throw ConfigError(e.file(), join(where, e.field()), problem);
    }
  }

  YamlFile f_;
  std::map<std::string, cv::Mat> textures_;
};

// Object box: front face at z = 0 (rows along +y), the box extends to z = depth.
std::vector<TexturedPlane> objectBox(const Eigen::Vector3d& size, const std::array<cv::Mat, 6>& tex) {
  const Eigen::Vector3d Y = Eigen::Vector3d::UnitY(), Z = Eigen::Vector3d::UnitZ();
  return boxFaces(size, Eigen::Vector3d(0, 0, size.z() / 2), tex, {Y, Y, Z, Z, Y, Y});
}

// A labelled cylinder (shape: cylinder) in its object frame (oMc = identity): the label's
// geometry checked by the object definitions' rule (core/cylinder.h), named by this object's fields.
TexturedCylinder readCylinder(Reader& r, const YAML::Node& node, const std::string& where) {
  TexturedCylinder c;
  c.radius_m = r.positive(node, where, "radius_m");
  c.height_m = r.positive(node, where, "height_m");
  const Eigen::Vector3d label_size = r.positiveSize(node, where, "label_size_m", 2);
  c.label_width_m = label_size.x();
  c.label_height_m = label_size.y();
  c.label = r.texture(node, where, "label");
  if (node["side_texture"]) c.side_texture = r.texture(node, where, "side_texture");
  if (node["cap_texture"]) c.cap_texture = r.texture(node, where, "cap_texture");
  const CylinderLabel label = c.geometry();
  try {
    label.check(r.file().path());
  } catch (const ConfigError& e) {
    const std::string field = e.field().rfind("cylinder.", 0) == 0 ? e.field().substr(9) : "label";
    r.file().fail(Reader::join(where, field), e.problem());
  }
  if (c.label_height_m > c.height_m)
    r.file().fail(Reader::join(where, "label_size_m"),
                  "label height " + Reader::shortNumber(c.label_height_m) + " m is more than height_m " +
                      Reader::shortNumber(c.height_m) + " m");
  return c;
}

SimObject readObject(Reader& r, const YAML::Node& node, const std::string& where) {
  r.onlyKeys(node, where, {"name", "definition", "target", "shape", "size_m", "texture", "faces",
                           "side_texture", "pose", "grasp_frame", "mass_kg", "radius_m", "height_m",
                           "label", "label_size_m", "cap_texture"});
  SimObject o;
  o.name = r.string(node, where, "name");
  o.is_target = r.boolean(node, where, "target", false);
  const std::string def = r.string(node, where, "definition", "");
  if (!def.empty()) {
    o.definition = r.file().resolve(def);
    std::error_code ec;
    if (!fs::is_regular_file(o.definition, ec))
      r.file().fail(Reader::join(where, "definition"), "file not found: " + o.definition);
  } else if (o.is_target) {
    r.file().fail(Reader::join(where, "definition"), "missing (a target needs an object definition)");
  }
  o.wMo = r.pose(node, where, "pose");
  o.oMg = node["grasp_frame"] ? r.pose(node, where, "grasp_frame") : Pose();
  o.mass_kg = r.number(node, where, "mass_kg", kDefaultObjectMassKg);
  if (o.mass_kg <= 0) r.file().fail(Reader::join(where, "mass_kg"), "must be positive");
  const std::string shape = r.string(node, where, "shape");
  const bool cylinder = shape == "cylinder";
  if (shape != "plane" && shape != "box" && !cylinder)
    r.file().fail(Reader::join(where, "shape"), "expected 'cylinder', 'plane' or 'box', got '" + shape + "'");
  // Fields of a cylinder only, and of a plane or box only.
  for (const char* key : {"radius_m", "height_m", "label", "label_size_m", "cap_texture"})
    if (node[key] && !cylinder) r.file().fail(Reader::join(where, key), "not a field of shape '" + shape + "'");
  for (const char* key : {"size_m", "texture", "faces"})
    if (node[key] && cylinder) r.file().fail(Reader::join(where, key), "not a field of shape 'cylinder'");
  if (shape == "plane") {
    const Eigen::Vector3d size = r.positiveSize(node, where, "size_m", 2);
    o.faces.push_back({r.texture(node, where, "texture"), size.x(), size.y(), Pose()});
    o.solids.push_back({Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, kPlaneThickness / 2)),
                        Eigen::Vector3d(size.x() / 2, size.y() / 2, kPlaneThickness / 2)});
  } else if (shape == "box") {
    const Eigen::Vector3d size = r.positiveSize(node, where, "size_m", 3);
    const cv::Mat side = r.texture(node, where, "side_texture");
    std::array<cv::Mat, 6> tex{side, side, side, side, side, side};
    static const char* const names[6] = {"left", "right", "top", "bottom", "front", "back"};
    const std::string fw = Reader::join(where, "faces");
    const YAML::Node faces = node["faces"];
    if (faces) {
      r.onlyKeys(faces, fw, {names, names + 6});
      for (size_t i = 0; i < 6; ++i)
        if (faces[names[i]]) tex[i] = r.texture(faces, fw, names[i]);
    }
    o.faces = objectBox(size, tex);
    o.solids.push_back({Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, size.z() / 2)), size / 2});
  } else {
    o.cylinders.push_back(readCylinder(r, node, where));
    o.solids.push_back(cylinderSolid(o.cylinders.back().radius_m, o.cylinders.back().height_m));
  }
  return o;
}

// Table: a solid block, frame at the centre of its top, z up, x along its length.
SimObject readTable(Reader& r, const YAML::Node& node, const std::string& w, const std::string& name) {
  r.onlyKeys(node, w, {"name", "size_m", "pose", "texture", "side_texture"});
  SimObject t;
  t.name = name;
  t.kind = ObjectKind::kTable;
  const Eigen::Vector3d size = r.positiveSize(node, w, "size_m", 3);
  const Pose floorMt = r.pose(node, w, "pose");  // pose of the table's footprint centre on the floor
  t.wMo = floorMt * Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, size.z()));
  const cv::Mat top = r.texture(node, w, "texture");
  const cv::Mat side = node["side_texture"] ? r.texture(node, w, "side_texture") : top;
  const Eigen::Vector3d down = -Eigen::Vector3d::UnitZ(), minusY = -Eigen::Vector3d::UnitY();
  t.faces = boxFaces(size, Eigen::Vector3d(0, 0, -size.z() / 2), {side, side, side, side, side, top},
                     {down, down, down, down, minusY, minusY});
  t.solids.push_back({Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, -size.z() / 2)), size / 2});
  return t;
}

// Floor (z = 0, seen from above) and optional walls around it, facing inwards.
void readRoom(Reader& r, const YAML::Node& node, World* world) {
  const std::string w = "room";
  r.onlyKeys(node, w, {"size_m", "centre", "floor_texture", "wall_texture", "wall_height_m"});
  const Eigen::Vector3d size = r.positiveSize(node, w, "size_m", 2);
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  if (node["centre"]) {
    const auto c = r.numbers(node, w, "centre", 2);
    centre = Eigen::Vector3d(c[0], c[1], 0);
  }
  SimObject floor;
  floor.name = "floor";
  floor.kind = ObjectKind::kFloor;
  floor.wMo = Pose(Eigen::Matrix3d::Identity(), centre);
  // Seen from above: face z down, rows along -y, columns along +x.
  floor.faces = {{r.texture(node, w, "floor_texture"), size.x(), size.y(),
                  Pose(Eigen::Vector3d(1, -1, -1).asDiagonal().toDenseMatrix(), Eigen::Vector3d::Zero())}};
  floor.solids.push_back({Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, -kSlab / 2)),
                          Eigen::Vector3d(size.x() / 2, size.y() / 2, kSlab / 2)});
  world->objects.push_back(floor);
  if (!node["wall_texture"]) return;
  const double h = r.number(node, w, "wall_height_m", 2.5);
  if (h <= 0) r.file().fail("room.wall_height_m", "must be positive");
  const cv::Mat wtex = r.texture(node, w, "wall_texture");
  SimObject walls;
  walls.name = "walls";
  walls.kind = ObjectKind::kWalls;
  walls.wMo = floor.wMo;
  // The inside of a box: its faces seen from within are the outside faces of a box turned inside out,
  // so build the outward faces and flip each about its row axis.
  const Eigen::Vector3d down = -Eigen::Vector3d::UnitZ();
  auto box = boxFaces(Eigen::Vector3d(size.x(), size.y(), h), Eigen::Vector3d(0, 0, h / 2),
                      {wtex, wtex, wtex, wtex, wtex, wtex}, {down, down, down, down, down, down});
  const Eigen::Matrix3d flip = axisAngle(Eigen::Vector3d::UnitY(), M_PI);
  for (int i = 0; i < 4; ++i) {
    box[static_cast<size_t>(i)].cMp.R = box[static_cast<size_t>(i)].cMp.R * flip;
    walls.faces.push_back(box[static_cast<size_t>(i)]);
  }
  // Solid slabs behind the walls (they overlap at the corners).
  for (int axis = 0; axis < 2; ++axis)
    for (const double side : {-1.0, 1.0}) {
      Eigen::Vector3d centre(0, 0, h / 2), half(size.x() / 2 + kSlab, size.y() / 2 + kSlab, h / 2);
      centre[axis] = side * (size[axis] / 2 + kSlab / 2);
      half[axis] = kSlab / 2;
      walls.solids.push_back({Pose(Eigen::Matrix3d::Identity(), centre), half});
    }
  world->objects.push_back(walls);
}

}  // namespace

Scenario loadScenario(const std::string& path) {
  Reader r(path);
  const YAML::Node& root = r.root();
  r.onlyKeys(root, "", {"seed", "max_duration_s", "robot_start", "background", "room", "table",
                        "tables", "objects", "camera", "faults"});
  Scenario s;
  s.path = path;
  const double seed = r.number(root, "", "seed");
  if (seed < 0 || seed != std::floor(seed) || seed > 9e15) r.file().fail("seed", "expected a non-negative integer");
  s.seed = static_cast<uint64_t>(seed);
  s.max_duration_s = r.number(root, "", "max_duration_s", 120);
  if (s.max_duration_s <= 0 || s.max_duration_s > kMaxDurationS)
    r.file().fail("max_duration_s", "must be in (0, " + Reader::shortNumber(kMaxDurationS) + "] s");

  const YAML::Node start = r.section(root, "robot_start", "");
  r.onlyKeys(start, "robot_start", {"x", "y", "theta"});
  s.start_x_m = r.number(start, "robot_start", "x");
  s.start_y_m = r.number(start, "robot_start", "y");
  s.start_theta_rad = r.number(start, "robot_start", "theta");

  if (root["background"]) s.world.background = r.texture(root, "", "background");

  const YAML::Node objects = root["objects"];
  if (!objects || objects.IsNull()) r.file().fail("objects", "missing (expected a list of objects)");
  if (!objects.IsSequence() || objects.size() == 0) r.file().fail("objects", "expected a non-empty list");
  if (objects.size() > kMaxObjects)
    r.file().fail("objects", std::to_string(objects.size()) + " objects, at most " + std::to_string(kMaxObjects));
  std::set<std::string> names;
  for (size_t i = 0; i < objects.size(); ++i) {
    const std::string where = "objects[" + std::to_string(i) + "]";
    s.world.objects.push_back(readObject(r, objects[i], where));
    if (!names.insert(s.world.objects.back().name).second)
      r.file().fail(where + ".name", "duplicate object name '" + s.world.objects.back().name + "'");
  }
  if (root["table"]) s.world.objects.push_back(readTable(r, r.section(root, "table", ""), "table", "table"));
  if (root["tables"]) {
    const YAML::Node tables = root["tables"];
    if (!tables.IsSequence() || tables.size() == 0) r.file().fail("tables", "expected a non-empty list");
    if (tables.size() > kMaxObjects)
      r.file().fail("tables", std::to_string(tables.size()) + " tables, at most " + std::to_string(kMaxObjects));
    for (size_t i = 0; i < tables.size(); ++i) {
      const std::string where = "tables[" + std::to_string(i) + "]";
      if (!tables[i].IsMap()) r.file().fail(where, "expected a map");
      const std::string name = tables[i]["name"] ? r.string(tables[i], where, "name") : "table_" + std::to_string(i);
      s.world.objects.push_back(readTable(r, tables[i], where, name));
      if (!names.insert(name).second) r.file().fail(where + ".name", "duplicate name '" + name + "'");
    }
  }
  if (root["room"]) readRoom(r, r.section(root, "room", ""), &s.world);

  if (root["camera"]) {
    const YAML::Node cam = r.section(root, "camera", "");
    const std::string w = "camera";
    r.onlyKeys(cam, w, {"noise_sigma", "motion_blur_px", "motion_blur_angle_rad", "brightness_gain",
                        "brightness_offset", "exposure_s"});
    s.camera.noise_sigma = r.nonNegative(cam, w, "noise_sigma", 0, 255);
    s.camera.motion_blur_px = r.nonNegative(cam, w, "motion_blur_px", 0, kMaxMotionBlurPx);
    s.camera.motion_blur_angle_rad = r.number(cam, w, "motion_blur_angle_rad", 0);
    s.camera.brightness_gain = r.number(cam, w, "brightness_gain", 1);
    if (s.camera.brightness_gain <= 0) r.file().fail("camera.brightness_gain", "must be positive");
    s.camera.brightness_offset = r.number(cam, w, "brightness_offset", 0);
    s.exposure_s = r.nonNegative(cam, w, "exposure_s", 0.01, 1.0);
  }
  if (root["faults"]) {
    const YAML::Node f = r.section(root, "faults", "");
    const std::string w = "faults";
    r.onlyKeys(f, w, {"command_latency_s", "frame_drop_probability", "frame_delay_s", "odom_noise_m_per_m",
                      "odom_noise_rad_per_rad", "stuck_joint", "stuck_after_s"});
    s.faults.command_latency_s = r.nonNegative(f, w, "command_latency_s", 0, 10);
    s.faults.frame_drop_probability = r.nonNegative(f, w, "frame_drop_probability", 0);
    if (s.faults.frame_drop_probability > 1) r.file().fail("faults.frame_drop_probability", "must be in [0, 1]");
    s.faults.frame_delay_s = r.nonNegative(f, w, "frame_delay_s", 0, 10);
    s.faults.odom_noise_m_per_m = r.nonNegative(f, w, "odom_noise_m_per_m", 0);
    s.faults.odom_noise_rad_per_rad = r.nonNegative(f, w, "odom_noise_rad_per_rad", 0);
    s.faults.stuck_joint = r.string(f, w, "stuck_joint", "");
    s.faults.stuck_after_s = r.nonNegative(f, w, "stuck_after_s", 0);
  }
  return s;
}

}  // namespace refgrasp::sim
