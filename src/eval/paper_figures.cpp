#include "eval/paper_figures.h"

#include <Eigen/Geometry>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <random>
#include <stdexcept>
#include <thread>
#include <unistd.h>

#include "detector/detector.h"
#include "detector/detector_internal.h"
#include "eval/classic.h"
#include "eval/cylinder_eval.h"
#include "eval/eval_util.h"
#include "robot/enon_model.h"
#include "robot/hal.h"
#include "robot/kinematics.h"
#include "robot/sim/degrade.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"
#include "robot/sim/synthetic_camera.h"
#include "robot/sim/synthetic_scene.h"
#include "servo/target_tracker.h"

namespace refgrasp::eval {

namespace {

namespace fs = std::filesystem;
using detail::mix;

constexpr double kDeg = M_PI / 180;
constexpr double kTableTopM = 0.72;

void need(bool ok, const char* type, const char* field, const char* problem) {
  if (!ok) throw std::invalid_argument(std::string(type) + "." + field + ": " + problem);
}

std::string configDir(const std::string& given) {
  return given.empty() ? testing::mediaDir() + "/../config" : given;
}

// A crop of a media photo (gray), its rows and columns as fractions of the photo.
cv::Mat photoCrop(const std::string& relpath, double x0, double y0, double x1, double y1) {
  const cv::Mat p = testing::loadMedia(relpath);
  const cv::Rect r(static_cast<int>(x0 * p.cols), static_cast<int>(y0 * p.rows),
                   static_cast<int>((x1 - x0) * p.cols), static_cast<int>((y1 - y0) * p.rows));
  return p(r).clone();
}

// An upright object frame (y down) whose z axis (into the object, the way a viewer of its front
// looks) points along the horizontal direction `yaw` (from x_w towards y_w).
Eigen::Matrix3d upright(double yaw) {
  const Eigen::Vector3d z(std::cos(yaw), std::sin(yaw), 0), y(0, 0, -1);
  Eigen::Matrix3d R;
  R << y.cross(z), y, z;
  return R;
}

std::string poseYaml(const Eigen::Vector3d& t, const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  const Eigen::Vector3d rv = aa.axis() * aa.angle();
  char buf[200];
  std::snprintf(buf, sizeof buf, "{translation: [%.4f, %.4f, %.4f], rotation_vector: [%.6f, %.6f, %.6f]}", t.x(),
                t.y(), t.z(), rv.x(), rv.y(), rv.z());
  return buf;
}

// Scenario YAML pieces: a plane or a box standing at floor position (x, y), bottom at `base_z`,
// its front facing the direction opposite to `yaw` (a viewer looking along yaw sees it).
std::string media(const std::string& rel) { return testing::mediaDir() + "/" + rel; }

std::string planeYaml(const std::string& name, const std::string& tex, double w, double h, double x, double y,
                      double base_z, double yaw) {
  return "  - name: " + name + "\n    shape: plane\n    size_m: [" + std::to_string(w) + ", " + std::to_string(h) +
         "]\n    texture: " + media(tex) + "\n    pose: " +
         poseYaml(Eigen::Vector3d(x, y, base_z + h / 2), upright(yaw)) + "\n";
}

std::string boxYaml(const std::string& name, const std::string& front, const std::string& side, double w, double h,
                    double d, double x, double y, double base_z, double yaw) {
  return "  - name: " + name + "\n    shape: box\n    size_m: [" + std::to_string(w) + ", " + std::to_string(h) +
         ", " + std::to_string(d) + "]\n    faces: {front: " + media(front) +
         ", top: " + media("boxes/box_top.png") + "}\n    side_texture: " + media(side) + "\n    pose: " +
         poseYaml(Eigen::Vector3d(x, y, base_z + h / 2), upright(yaw)) + "\n";
}

// Loads a scenario written here (the public loader checks it as any other).
sim::Scenario generatedScenario(const std::string& yaml) {
  static std::atomic<int> counter{0};
  const fs::path path = fs::temp_directory_path() /
                        ("refgrasp_paper_figures_" + std::to_string(::getpid()) + "_" + std::to_string(counter++) + ".yaml");
  {
    std::ofstream f(path);
    f << yaml;
    if (!f) throw std::runtime_error(path.string() + ": cannot write");
  }
  try {
    sim::Scenario s = sim::loadScenario(path.string());
    fs::remove(path);
    return s;
  } catch (...) {
    fs::remove(path);
    throw;
  }
}

std::string roomYaml(double size_x, double size_y, double centre_x, double centre_y, double noise_sigma) {
  char buf[600];
  std::snprintf(buf, sizeof buf,
                "seed: 1\nmax_duration_s: 600\nrobot_start: {x: 0.0, y: 0.0, theta: 0.0}\nbackground: %s\n"
                "room:\n  size_m: [%g, %g]\n  centre: [%g, %g]\n  floor_texture: %s\n  wall_texture: %s\n"
                "  wall_height_m: 2.5\ncamera:\n  noise_sigma: %g\n  exposure_s: 0.01\n",
                media("backgrounds/wall.png").c_str(), size_x, size_y, centre_x, centre_y,
                media("backgrounds/floor.png").c_str(), media("backgrounds/wall.png").c_str(), noise_sigma);
  return buf;
}

std::string tableYaml(double len, double width, double cx, double cy) {
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "table:\n  size_m: [%g, %g, %g]\n  pose: {translation: [%g, %g, 0], rotation_vector: [0, 0, 0]}\n"
                "  texture: %s\n",
                len, width, kTableTopM, cx, cy, media("backgrounds/table_wood.png").c_str());
  return buf;
}

// Fig. 7's world: the robot at the origin facing +x, a long table in front (x 0.35-3.65 m), two
// distractors on it off the line of sight, a poster on the far wall.
sim::World fig7World() {
  std::string y = roomYaml(9, 6, 3, 0, 0) + tableYaml(3.3, 1.0, 2.0, 0.0) + "objects:\n";
  y += boxYaml("parcel", "boxes/box_side_b.png", "boxes/box_side_a.png", 0.26, 0.22, 0.20, 1.3, 0.36, kTableTopM, -0.35);
  y += planeYaml("magazine", "targets/magazine.png", 0.2, 0.15, 2.4, -0.38, kTableTopM, 0.3);
  y += planeYaml("poster", "targets/poster_concert.png", 0.8, 0.6, 7.49, 0.5, 1.1, 0);
  return generatedScenario(y).world;
}

// Fig. 8's room: 8 x 8 m around the origin; the robot's path (a circle of 1.5 m radius about the
// origin, its body 0.25 m wide) stays clear of a desk in the middle and of everything along the
// walls: shelves, posters, boxes, people-sized stands, a table with things on it.
sim::Scenario fig8Scenario(double noise_sigma) {
  std::string y = roomYaml(8, 8, 0, 0, noise_sigma) + tableYaml(0.8, 1.6, 2.9, 0.2) + "objects:\n";
  auto at = [](double r, double a) { return Eigen::Vector2d(r * std::cos(a), r * std::sin(a)); };
  // Middle: a desk and what stands on it (fronts towards +x, -x).
  y += boxYaml("desk", "backgrounds/table_wood.png", "backgrounds/table_wood.png", 1.0, 0.72, 0.6, -0.3, 0, 0, 0);
  y += boxYaml("cereal", "targets/cereal_box.png", "boxes/box_side_b.png", 0.22, 0.3, 0.08, -0.35, 0.2, 0.72, 0);
  y += planeYaml("sign", "clutter/clutter_06.png", 0.25, 0.25, 0.25, -0.1, 0.72, M_PI);
  y += boxYaml("tea", "targets/tea_box.png", "boxes/box_side_a.png", 0.18, 0.18, 0.12, 0.1, 0.15, 0.72, M_PI);
  // Shelves against three walls, their fronts towards the middle.
  y += boxYaml("shelf_n", "targets/book_cover.png", "clutter/clutter_01.png", 1.4, 1.8, 0.35, 0.3, 3.62, 0, M_PI / 2);
  y += boxYaml("shelf_w", "targets/magazine.png", "clutter/clutter_07.png", 1.4, 1.8, 0.35, -3.62, -0.5, 0, M_PI);
  y += boxYaml("shelf_s", "clutter/clutter_02.png", "clutter/clutter_00.png", 1.2, 1.6, 0.35, 1.0, -3.62, 0, -M_PI / 2);
  // Posters on the walls.
  y += planeYaml("poster_e", "targets/poster_concert.png", 0.8, 0.6, 3.99, -2.0, 1.1, 0);
  y += planeYaml("poster_n", "hard/symmetric.png", 0.6, 0.6, -2.2, 3.99, 1.2, M_PI / 2);
  y += planeYaml("poster_s", "hard/tiled_motif.png", 0.6, 0.6, -2.0, -3.99, 1.2, -M_PI / 2);
  y += planeYaml("notice_w", "hard/low_texture.png", 0.6, 0.45, -3.99, 2.2, 1.0, M_PI);
  // Boxes and people-sized stands on the floor, facing the middle.
  const struct { const char* name; const char* front; const char* side; double w, h, d, r, a; } floor[] = {
      {"parcel_ne", "boxes/box_side_a.png", "boxes/box_side_b.png", 0.5, 0.45, 0.4, 3.2, 0.85},
      {"parcel_sw", "boxes/box_side_b.png", "boxes/box_side_a.png", 0.45, 0.5, 0.45, 3.3, -2.4},
      {"person_nw", "clutter/clutter_05.png", "clutter/clutter_05.png", 0.5, 1.7, 0.3, 2.9, 2.3},
      {"person_se", "clutter/clutter_03.png", "clutter/clutter_04.png", 0.5, 1.7, 0.3, 2.8, -1.0},
      {"crate_w", "clutter/clutter_04.png", "boxes/box_side_a.png", 0.6, 0.6, 0.6, 2.6, 3.6},
  };
  for (const auto& b : floor) {
    const Eigen::Vector2d p = at(b.r, b.a);
    y += boxYaml(b.name, b.front, b.side, b.w, b.h, b.d, p.x(), p.y(), 0, b.a);
  }
  // On the table (x 2.5-3.3 m): a box and a card, facing the middle.
  y += boxYaml("tin", "targets/cereal_box.png", "clutter/clutter_02.png", 0.2, 0.25, 0.15, 2.75, -0.2, 0.72, 0);
  y += planeYaml("card", "clutter/clutter_07.png", 0.22, 0.3, 2.7, 0.55, 0.72, 0.2);
  return generatedScenario(y);
}

sim::TexturedPlane face(const cv::Mat& tex, double w, double h, const Pose& oMp) {
  sim::TexturedPlane p;
  p.texture = tex;
  p.width_m = w;
  p.height_m = h;
  p.cMp = oMp;
  return p;
}

PaperObject planar(const std::string& name, const std::string& what, const cv::Mat& tex, double width_m,
                   const std::vector<double>& turns) {
  PaperObject o;
  o.name = name;
  const double h = width_m * tex.rows / tex.cols;
  char size[64];
  std::snprintf(size, sizeof size, ", %.1f x %.1f cm", 100 * width_m, 100 * h);
  o.description = what + size;
  o.shape = PaperShape::kPlanar;
  o.model = detector::textureObject(name, tex, width_m);
  o.faces = {face(tex, width_m, h, Pose())};
  o.height_m = h;
  o.turns_deg = turns;
  return o;
}

PaperObject cylinder(const std::string& name, const std::string& what, const cv::Mat& label, double radius_m,
                     double label_h_m, double height_m, const std::vector<double>& turns) {
  PaperObject o;
  o.name = name;
  o.description = what;
  o.shape = PaperShape::kCylinder;
  LabelledCylinder c;  // all the way round
  c.name = name;
  c.label = label;
  c.radius_m = radius_m;
  c.label_width_m = 2 * M_PI * radius_m;
  c.label_height_m = label_h_m;
  c.height_m = height_m;
  o.model = c.object();
  o.cylinder = c.body(Pose());
  o.centre_o = Eigen::Vector3d(0, 0, radius_m);
  o.height_m = height_m;
  o.turns_deg = turns;
  return o;
}

}  // namespace

std::vector<PaperObject> paperObjects(const std::vector<double>& turns, const std::vector<double>& box_turns) {
  std::vector<PaperObject> out;
  out.push_back(planar("A_cookie_box", "photos/cookie_box.png, a card", testing::loadMedia("photos/cookie_box.png"),
                       0.10, turns));
  out.push_back(planar("B_hotel", "photos/hotel_facade.jpg (middle 60 % x 85 %), a card",
                       photoCrop("photos/hotel_facade.jpg", 0.2, 0.1, 0.8, 0.95), 0.09, turns));
  out.push_back(planar("C_town", "photos/aerial_town.jpg (left half), a card",
                       photoCrop("photos/aerial_town.jpg", 0, 0, 0.5, 1), 0.07, turns));
  {
    // A box (8 x 12 x 6 cm) defined by its front face, the right half of the aerial photo; its
    // other faces are the project's cardboard textures.
    const cv::Mat front = photoCrop("photos/aerial_town.jpg", 0.5, 0, 1, 1);
    PaperObject o = planar("D_town_box", "photos/aerial_town.jpg (right half) on the front of a box 6 cm deep",
                           front, 0.08, box_turns);
    o.shape = PaperShape::kBox;
    const Eigen::Vector3d size(0.08, 0.12, 0.06);
    const cv::Mat side = testing::loadMedia("boxes/box_side_a.png"), top = testing::loadMedia("boxes/box_top.png");
    const Eigen::Vector3d Y = Eigen::Vector3d::UnitY(), Z = Eigen::Vector3d::UnitZ();  // as scenario boxes
    o.faces = sim::boxFaces(size, Eigen::Vector3d(0, 0, size.z() / 2), {side, side, top, top, front, side},
                            {Y, Y, Z, Z, Y, Y});
    o.centre_o = Eigen::Vector3d(0, 0, size.z() / 2);
    o.height_m = size.y();
    out.push_back(std::move(o));
  }
  out.push_back(cylinder("E_can", "photos/fruits_closeup.jpg (rows 20-80 %) round a can, r 3.3 cm, label 11.5 cm",
                         photoCrop("photos/fruits_closeup.jpg", 0, 0.2, 1, 0.8), 0.033, 0.115, 0.122, turns));
  {
    const cv::Mat label = testing::loadMedia("photos/butterfly_on_leaf.jpg");
    const double r = 0.04, h = 2 * M_PI * r * label.rows / label.cols;
    char what[160];
    std::snprintf(what, sizeof what, "photos/butterfly_on_leaf.jpg round a bottle, r 4 cm, label %.1f cm", 100 * h);
    out.push_back(cylinder("F_bottle", what, label, r, h, 0.24, turns));
  }
  return out;
}

const char* fig7MethodName(Fig7Method m, bool round) {
  switch (m) {
    case Fig7Method::kRefined: return round ? "refgrasp, cylinder model" : "refgrasp";
    case Fig7Method::kPaper: return round ? "refgrasp, paper's planar approximation" : "refgrasp, paper's pose";
    case Fig7Method::kClassic: return "classic OpenCV";
  }
  return "?";
}

std::vector<Fig7Method> fig7Methods(const PaperObject& o) {
  if (o.round()) return {Fig7Method::kRefined, Fig7Method::kPaper, Fig7Method::kClassic};
  return {Fig7Method::kRefined, Fig7Method::kClassic};
}

void Fig7Options::check() const {
  need(!distances_m.empty(), "Fig7Options", "distances_m", "must not be empty");
  for (double d : distances_m) need(std::isfinite(d) && d >= 0.4 && d <= 3.4, "Fig7Options", "distances_m", "must be in [0.4, 3.4] m (the table)");
  need(!turns_deg.empty() && !box_turns_deg.empty(), "Fig7Options", "turns_deg", "must not be empty");
  for (double t : turns_deg) need(std::isfinite(t) && std::abs(t) <= 80, "Fig7Options", "turns_deg", "must be within +-80 deg");
  for (double t : box_turns_deg) need(std::isfinite(t) && std::abs(t) <= 80, "Fig7Options", "box_turns_deg", "must be within +-80 deg");
  need(frames >= 1, "Fig7Options", "frames", "must be >= 1");
  need(std::isfinite(noise_sigma) && noise_sigma >= 0 && noise_sigma <= 50, "Fig7Options", "noise_sigma", "must be in [0, 50]");
  need(threads >= 1 && threads <= 64, "Fig7Options", "threads", "must be in [1, 64]");
}

void Fig8Options::check() const {
  need(std::isfinite(duration_s) && duration_s > 0 && duration_s <= 600, "Fig8Options", "duration_s", "must be in (0, 600]");
  need(std::isfinite(frame_rate_hz) && frame_rate_hz >= 0.5 && frame_rate_hz <= 48, "Fig8Options", "frame_rate_hz",
       "must be in [0.5, 48] (the camera's rate)");
  need(std::isfinite(noise_sigma) && noise_sigma >= 0 && noise_sigma <= 50, "Fig8Options", "noise_sigma", "must be in [0, 50]");
}

void makeQuick(Fig7Options* fig7, Fig8Options* fig8) {
  fig7->distances_m = {0.5, 2.0};
  fig7->turns_deg = {30};
  fig7->box_turns_deg = {45};
  fig7->frames = 2;
  fig8->duration_s = 3;
}

namespace {

struct Fig7Scene {
  robot::EnonModel model;
  sim::World world;
  Intrinsics camera;
};

Fig7Scene fig7Scene(const std::string& config_dir) {
  Fig7Scene s;
  s.model = robot::loadEnonModel(configDir(config_dir) + "/enon.yaml");
  s.world = fig7World();
  s.camera = s.model.head.rig.left;
  return s;
}

// The object's pose in the world and the head camera's, the head pointed at the object's centre.
void placeFig7(const Fig7Scene& s, const PaperObject& o, double distance_m, double turn_deg, Pose* wMo, Pose* wMc) {
  const Eigen::Vector3d P(distance_m, 0, kTableTopM + o.height_m / 2);
  const Eigen::Matrix3d R = upright(turn_deg * kDeg);
  *wMo = Pose(R, P - R * o.centre_o);
  double pan = 0, tilt = 0;
  for (int it = 0; it < 8; ++it) {
    const Eigen::Vector3d Pc = robot::headCameraPose(s.model.head, pan, tilt).inverse() * P;
    pan -= std::atan2(Pc.x(), Pc.z());
    tilt += std::atan2(Pc.y(), Pc.z());
    pan = std::clamp(pan, s.model.head.pan.min_rad, s.model.head.pan.max_rad);
    tilt = std::clamp(tilt, s.model.head.tilt.min_rad, s.model.head.tilt.max_rad);
  }
  *wMc = robot::headCameraPose(s.model.head, pan, tilt);
}

cv::Mat renderPlaced(const Fig7Scene& s, const PaperObject& o, const Pose& wMo, const Pose& wMc) {
  std::vector<sim::TexturedPlane> planes = sim::worldPlanes(s.world, wMc);
  const Pose cMo = wMc.inverse() * wMo;
  for (sim::TexturedPlane f : o.faces) {
    f.cMp = cMo * f.cMp;
    planes.push_back(f);
  }
  std::vector<sim::TexturedCylinder> cyl;
  if (o.cylinder) {
    cyl.push_back(*o.cylinder);
    cyl.back().cMo = cMo;
  }
  return sim::renderView(s.camera, planes, cyl, s.world.background);
}

// One worker's detectors: every object registered in each, as on the robot.
struct Fig7Workers {
  std::unique_ptr<detector::Detector> refined, paper;
  std::vector<std::unique_ptr<ClassicPipeline>> classic;
};

Fig7Workers makeWorkers(const std::vector<PaperObject>& objects) {
  detector::DetectorOptions opt;
  opt.sift.threads = 1;  // one view per core
  Fig7Workers w;
  w.refined = std::make_unique<detector::Detector>(opt);
  opt.pose = detector::PoseMethod::kPaper;
  w.paper = std::make_unique<detector::Detector>(opt);
  for (const auto& o : objects) {
    w.refined->addObject(o.model);
    w.paper->addObject(o.model);
    w.classic.push_back(std::make_unique<ClassicPipeline>(o.model));
  }
  return w;
}

Fig7Outcome score(const std::optional<Pose>& cMo, const Pose& truth) {
  Fig7Outcome r;
  if (!cMo) return r;
  r.reported = true;
  r.t = cMo->t;
  r.t_err_m = translationError(*cMo, truth);
  r.rot_deg = rotationError(*cMo, truth) / kDeg;
  const double range = truth.t.norm();
  r.success = r.t_err_m <= 0.05 * range;
  r.pose_ok = r.success && r.rot_deg < 2.0 && r.t_err_m < 0.02 * range;
  return r;
}

Fig7Outcome detectorOutcome(const detector::Detector& det, const cv::Mat& img, const Intrinsics& cam, int object,
                            const Pose& truth) {
  const detector::DetectionResult res = det.detect(img, cam);
  std::optional<Pose> cMo;
  int others = 0;
  for (const auto& d : res.detections) {
    if (!d.found) continue;
    if (d.object == object && d.instance == 0) cMo = d.cMo;
    else if (d.object != object) ++others;
  }
  Fig7Outcome r = score(cMo, truth);
  r.others = others;
  return r;
}

void runCell(const Fig7Scene& s, const std::vector<PaperObject>& objects, const Fig7Options& opt, Fig7Workers& w,
             Fig7Cell* cell) {
  const PaperObject& o = objects[static_cast<size_t>(cell->object)];
  Pose wMo, wMc;
  placeFig7(s, o, cell->distance_m, cell->turn_deg, &wMo, &wMc);
  cell->cMo = wMc.inverse() * wMo;
  cell->range_m = cell->cMo.t.norm();
  const cv::Mat view = renderPlaced(s, o, wMo, wMc);
  Intrinsics undistorted = s.camera;  // the classic pipeline gets undistorted keypoints
  for (double& k : undistorted.dist) k = 0;
  cell->by_method.assign(3, {});
  const std::vector<Fig7Method> methods = fig7Methods(o);
  sim::Degradation deg;
  deg.noise_sigma = opt.noise_sigma;
  for (int k = 0; k < opt.frames; ++k) {
    cv::Mat img = view.clone();
    std::mt19937_64 rng(mix(opt.seed, mix(static_cast<uint64_t>(cell->object * 1000000 + cell->distance * 1000 + cell->turn),
                                          static_cast<uint64_t>(k))));
    sim::degrade(img, deg, rng);
    for (Fig7Method m : methods) {
      Fig7Outcome r;
      if (m == Fig7Method::kRefined) r = detectorOutcome(*w.refined, img, s.camera, cell->object, cell->cMo);
      if (m == Fig7Method::kPaper) r = detectorOutcome(*w.paper, img, s.camera, cell->object, cell->cMo);
      if (m == Fig7Method::kClassic) {
        const detector::Features f = detector::DetectorInternals::extract(*w.refined, img, s.camera);
        const ClassicResult c = w.classic[static_cast<size_t>(cell->object)]->detect(ClassicFeatures{f.keypoints, f.descriptors},
                                                                                     undistorted);
        r = score(c.found ? c.cMo : std::nullopt, cell->cMo);
      }
      cell->by_method[static_cast<size_t>(m)].push_back(r);
    }
  }
}

double sampleStd(const std::vector<double>& v) {
  if (v.size() < 2) return NAN;
  double m = 0;
  for (double x : v) m += x;
  m /= static_cast<double>(v.size());
  double s = 0;
  for (double x : v) s += (x - m) * (x - m);
  return std::sqrt(s / static_cast<double>(v.size() - 1));
}

std::vector<Fig7Row> aggregate(const Fig7Result& r) {
  std::vector<Fig7Row> rows;
  for (size_t oi = 0; oi < r.objects.size(); ++oi)
    for (Fig7Method m : fig7Methods(r.objects[oi]))
      for (size_t di = 0; di < r.options.distances_m.size(); ++di) {
        Fig7Row row;
        row.object = static_cast<int>(oi);
        row.method = m;
        row.distance_m = r.options.distances_m[di];
        Eigen::Vector3d sum_var = Eigen::Vector3d::Zero();
        int with_std = 0;
        for (const Fig7Cell& c : r.cells) {
          if (c.object != static_cast<int>(oi) || c.distance != static_cast<int>(di)) continue;
          std::vector<double> xs[3];
          for (const Fig7Outcome& f : c.by_method[static_cast<size_t>(m)]) {
            ++row.frames;
            row.success += f.success;
            row.pose_ok += f.pose_ok;
            row.wrong += f.reported && !f.success;
            row.others += f.others;
            if (f.success)
              for (int a = 0; a < 3; ++a) xs[a].push_back(f.t[a]);
          }
          if (xs[0].size() >= 2) {
            for (int a = 0; a < 3; ++a) sum_var[a] += std::pow(sampleStd(xs[a]), 2);
            ++with_std;
          }
        }
        if (with_std) row.std_m = (sum_var / with_std).cwiseSqrt();
        rows.push_back(row);
      }
  return rows;
}

}  // namespace

std::vector<const Fig7Row*> Fig7Result::rowsOf(int object, Fig7Method m) const {
  std::vector<const Fig7Row*> out;
  for (const Fig7Row& r : rows)
    if (r.object == object && r.method == m) out.push_back(&r);
  return out;
}

cv::Mat renderFig7View(const Fig7Options& opt, const PaperObject& o, double distance_m, double turn_deg, Pose* cMo) {
  const Fig7Scene s = fig7Scene(opt.config_dir);
  Pose wMo, wMc;
  placeFig7(s, o, distance_m, turn_deg, &wMo, &wMc);
  if (cMo) *cMo = wMc.inverse() * wMo;
  return renderPlaced(s, o, wMo, wMc);
}

Fig7Result runFig7(const Fig7Options& opt, const std::function<void(int, int)>& progress) {
  opt.check();
  Fig7Result r;
  r.options = opt;
  r.objects = paperObjects(opt.turns_deg, opt.box_turns_deg);
  const Fig7Scene scene = fig7Scene(opt.config_dir);
  r.camera = scene.camera;
  for (size_t oi = 0; oi < r.objects.size(); ++oi)
    for (size_t di = 0; di < opt.distances_m.size(); ++di)
      for (size_t ti = 0; ti < r.objects[oi].turns_deg.size(); ++ti) {
        Fig7Cell c;
        c.object = static_cast<int>(oi);
        c.distance = static_cast<int>(di);
        c.turn = static_cast<int>(ti);
        c.distance_m = opt.distances_m[di];
        c.turn_deg = r.objects[oi].turns_deg[ti];
        r.cells.push_back(c);
      }
  std::atomic<size_t> next{0};
  std::atomic<int> done{0};
  std::mutex mu;
  std::exception_ptr failure;
  auto work = [&] {
    try {
      Fig7Workers w = makeWorkers(r.objects);
      for (size_t i; (i = next++) < r.cells.size();) {
        runCell(scene, r.objects, opt, w, &r.cells[i]);
        const int d = ++done;
        if (progress) {
          std::lock_guard<std::mutex> lock(mu);
          progress(d, static_cast<int>(r.cells.size()));
        }
      }
    } catch (...) {
      std::lock_guard<std::mutex> lock(mu);
      if (!failure) failure = std::current_exception();
      next = r.cells.size();
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < opt.threads; ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);
  r.rows = aggregate(r);
  return r;
}

std::vector<int> Fig8Result::rawTotals() const {
  std::vector<int> n(names.size(), 0);
  for (const auto& f : frames)
    for (size_t i = 0; i < n.size(); ++i) n[i] += f.raw[i];
  return n;
}

std::vector<int> Fig8Result::confirmedTotals() const {
  std::vector<int> n(names.size(), 0);
  for (const auto& f : frames)
    for (size_t i = 0; i < n.size(); ++i) n[i] += f.confirmed[i];
  return n;
}

namespace {

// The drive: a full turn on the spot (head sweeping), then circles of 1.5 m radius about the
// room's middle; the head pans +-1.2 rad and tilts 0.05-0.55 rad (looking down) throughout.
void fig8Command(robot::Robot& robot, double t) {
  robot.head().setPosition(1.2 * std::sin(2 * M_PI * t / 14), 0.3 + 0.25 * std::sin(2 * M_PI * t / 9.3));
  constexpr double kTurnS = 2 * M_PI / 0.5;
  if (t < kTurnS) robot.base().setVelocity(0, 0.5);
  else robot.base().setVelocity(0.3, 0.2);
}

}  // namespace

Fig8Result runFig8(const Fig8Options& opt, const std::function<void(int, int)>& progress) {
  opt.check();
  Fig8Result out;
  out.options = opt;
  const robot::EnonModel model = robot::loadEnonModel(configDir(opt.config_dir) + "/enon.yaml");
  sim::Scenario scenario = fig8Scenario(opt.noise_sigma);
  scenario.seed = opt.seed;
  scenario.start_x_m = 0;
  scenario.start_y_m = -1.5;
  scenario.start_theta_rad = 0;
  scenario.max_duration_s = opt.duration_s + 1;
  const std::vector<PaperObject> objects = paperObjects({0}, {45});
  detector::DetectorOptions dopt;  // the robot's detector: its defaults
  detector::Detector det(dopt);
  for (const auto& o : objects) {
    det.addObject(o.model);
    out.names.push_back(o.name);
  }
  servo::TargetTrackerOptions topt;
  topt.track = false;  // every frame detected: the filter is the confirmation alone
  servo::TargetTracker tracker(det, topt);
  std::unique_ptr<robot::Robot> robot = sim::makeSimRobot(model, scenario);
  if (robot->configure() != robot::ReturnType::kOk || robot->activate() != robot::ReturnType::kOk)
    throw std::runtime_error("fig8: the simulated enon did not activate: " + robot->hardware().lastError());
  const double dt = model.control_period_s, period = 1.0 / opt.frame_rate_hz;
  const int total = static_cast<int>(std::floor(opt.duration_s / period + 1e-9));
  const Intrinsics& camera = model.head.rig.left;
  double next_frame = 0;
  for (int64_t k = 0; static_cast<int>(out.frames.size()) < total; ++k) {
    const double t = static_cast<double>(k) * dt;
    if (robot->read(t, dt) != robot::ReturnType::kOk) out.collisions = 1;
    if (t + 1e-9 >= next_frame) {
      std::optional<robot::StereoFrame> frame;
      if (robot->camera().grab(t, &frame) == robot::ReturnType::kOk && frame) {
        robot::MonoFrame mono;
        mono.image = frame->left;
        mono.stamp = frame->stamp;
        mono.index = frame->index;
        mono.capture = frame->capture;
        const servo::TargetFrame tf = tracker.process(mono, camera);
        Fig8Frame f;
        f.t_s = frame->stamp;
        f.raw.assign(objects.size(), 0);
        f.confirmed.assign(objects.size(), 0);
        for (const auto& s : tf.objects) {
          f.raw[static_cast<size_t>(s.object)] = s.detection.found ? 1 : 0;
          f.confirmed[static_cast<size_t>(s.object)] = s.confirmed ? 1 : 0;
        }
        const robot::RobotState& st = robot->state();
        f.x_m = st.wMb_odom.t.x();
        f.y_m = st.wMb_odom.t.y();
        f.pan_rad = st.pan_rad;
        f.tilt_rad = st.tilt_rad;
        out.frames.push_back(f);
        next_frame += period;
        if (progress) progress(static_cast<int>(out.frames.size()), total);
      }
    }
    fig8Command(*robot, t);
    if (robot->write(t, dt) != robot::ReturnType::kOk) out.collisions = 1;
  }
  robot->deactivate();
  return out;
}

}  // namespace refgrasp::eval
