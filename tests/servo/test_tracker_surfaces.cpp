// The tracker on objects that are not one plane (servo/surface_model.h, servo/tracker.h): a can
// with a photographed label and a box of three photographed faces, rendered at known poses along
// smooth trajectories (camera noise and motion blur), the tracker started at the first frame's
// ground truth; the surface model's geometry against the definitions it is built from.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <random>

#include "detector/detector.h"
#include "detector/object.h"
#include "robot/sim/degrade.h"
#include "robot/sim/render.h"
#include "robot/sim/scenario.h"
#include "robot/sim/synthetic_scene.h"
#include "servo/surface_model.h"
#include "servo/target_estimator.h"
#include "servo/target_tracker.h"
#include "servo/tracker.h"

using namespace refgrasp;
namespace rt = refgrasp::testing;

namespace {

constexpr double kDeg = M_PI / 180;

Eigen::Matrix3d rotX(double a) { return axisAngle(Eigen::Vector3d::UnitX(), a); }
Eigen::Matrix3d rotY(double a) { return axisAngle(Eigen::Vector3d::UnitY(), a); }

/// A rendered sequence with its ground truth (cMo per frame).
struct Sequence {
  Intrinsics camera = rt::sceneCamera();
  std::vector<cv::Mat> frames;
  std::vector<Pose> truth;
};

/// Camera noise (2 gray levels) and a motion blur along the image motion of `centre_o` over a
/// third of the frame period.
void degradeFrame(cv::Mat* img, const Intrinsics& cam, const Pose& before, const Pose& now,
                  const Eigen::Vector3d& centre_o, std::mt19937_64* rng) {
  const Eigen::Vector2d d = cam.project(now * centre_o) - cam.project(before * centre_o);
  sim::Degradation g;
  g.noise_sigma = 2;
  g.motion_blur_px = 0.3 * d.norm();
  g.motion_blur_angle_rad = std::atan2(d.y(), d.x());
  sim::degrade(*img, g, *rng);
}

// ---- the can ---------------------------------------------------------------------------------
constexpr double kRadius = 0.04, kLabelW = 0.18, kLabelH = 0.12, kCanH = 0.15;
const char* kLabel = "photos/aerial_town.jpg";

const detector::ObjectModel& canModel() {
  static const detector::ObjectModel m =
      detector::cylinderObject("can", rt::loadMedia(kLabel), kRadius, kLabelW, kLabelH);
  return m;
}

/// The can at frame k of n: turned about its axis by up to +-50 deg, tilted towards the camera by
/// up to 20 deg, moving sideways by +-6 cm and from 0.45 to 0.6 m away.
Pose canPose(int k, int n) {
  const double t = static_cast<double>(k) / (n - 1);
  const double turn = 50 * kDeg * std::sin(2 * M_PI * t);
  const double tilt = 20 * kDeg * std::sin(M_PI * t);
  const Eigen::Vector3d axis_c(0.06 * std::sin(M_PI * (2 * t - 0.5)), 0.02 * std::cos(3 * t),
                               0.45 + 0.15 * t);
  // The axis frame (the object frame moved onto the axis) turned and tilted, then back out.
  return Pose(rotX(tilt) * rotY(turn), axis_c) * Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, -kRadius));
}

const Sequence& canSequence() {
  static const Sequence s = [] {
    Sequence q;
    constexpr int n = 80;
    const cv::Mat background = rt::clutterBackground(11);
    std::mt19937_64 rng(36);
    for (int k = 0; k < n; ++k) {
      sim::TexturedCylinder can;
      can.label = rt::loadMedia(kLabel);
      can.radius_m = kRadius;
      can.label_width_m = kLabelW;
      can.label_height_m = kLabelH;
      can.height_m = kCanH;
      can.cMo = canPose(k, n);
      cv::Mat img = sim::renderView(q.camera, {}, {can}, background);
      degradeFrame(&img, q.camera, canPose(std::max(0, k - 1), n), can.cMo, canModel().cylinder->axisPoint(0),
                   &rng);
      q.frames.push_back(img);
      q.truth.push_back(can.cMo);
    }
    return q;
  }();
  return s;
}

// ---- the box ---------------------------------------------------------------------------------
/// 16 x 12 x 10 cm; photographs on its -z (front), +x and -x faces, resized to the faces' size at
/// 2 px/mm; its other faces plain.
const Eigen::Vector3d kBox(0.16, 0.12, 0.10);
const char* kFacePhotos[3] = {"photos/cookie_box.png", "photos/fruits_closeup.jpg",
                              "photos/butterfly_on_leaf.jpg"};

cv::Mat facePhoto(int i, double width_m, double height_m) {
  cv::Mat out;
  cv::resize(rt::loadMedia(kFacePhotos[i]), out,
             cv::Size(static_cast<int>(std::lround(width_m * 2000)), static_cast<int>(std::lround(height_m * 2000))),
             0, 0, cv::INTER_AREA);
  return out;
}

/// The box's faces in its frame (centre, x right, y down, z away from a viewer of the front).
std::vector<sim::TexturedPlane> boxPlanes() {
  const cv::Mat plain(8, 8, CV_8UC1, cv::Scalar(150));
  const Eigen::Vector3d Y = Eigen::Vector3d::UnitY(), Z = Eigen::Vector3d::UnitZ();
  std::array<cv::Mat, 6> tex{facePhoto(2, kBox.z(), kBox.y()), facePhoto(1, kBox.z(), kBox.y()), plain, plain,
                             facePhoto(0, kBox.x(), kBox.y()), plain};
  return sim::boxFaces(kBox, Eigen::Vector3d::Zero(), tex, {Y, Y, Z, Z, Y, Y});
}

/// The several-view definition of the box: its three photographed faces (-x, +x, -z), each a
/// planar definition of the photo at the face's size, at the face's pose (oMv).
const detector::ObjectModel& boxModel() {
  static const detector::ObjectModel m = [] {
    const std::vector<sim::TexturedPlane> planes = boxPlanes();
    detector::ObjectModel box;
    box.name = "box";
    const std::pair<int, const char*> faces[3] = {{4, "front"}, {1, "right"}, {0, "left"}};
    for (const auto& [i, name] : faces) {
      const sim::TexturedPlane& p = planes[static_cast<size_t>(i)];
      box.views.push_back({name,
                           std::make_shared<detector::ObjectModel>(detector::textureObject(name, p.texture, p.width_m)),
                           p.cMp});
    }
    return box;
  }();
  return m;
}

/// The box at frame k of n: turned about its vertical axis from -10 to 110 deg (the front leaves
/// the view at 90 deg, the +x face comes in from 0), tilted 15 deg, 0.55-0.65 m away.
Pose boxPose(int k, int n) {
  const double t = static_cast<double>(k) / (n - 1);
  const double turn = (-10 + 120 * t) * kDeg;
  return Pose(rotX(-15 * kDeg) * rotY(turn),
              Eigen::Vector3d(0.03 * std::sin(M_PI * t), 0.01, 0.55 + 0.1 * t));
}

const Sequence& boxSequence() {
  static const Sequence s = [] {
    Sequence q;
    constexpr int n = 90;
    const cv::Mat background = rt::clutterBackground(12);
    const std::vector<sim::TexturedPlane> faces = boxPlanes();
    std::mt19937_64 rng(36);
    for (int k = 0; k < n; ++k) {
      const Pose cMo = boxPose(k, n);
      std::vector<sim::TexturedPlane> planes = faces;
      for (sim::TexturedPlane& p : planes) p.cMp = cMo * p.cMp;
      cv::Mat img = sim::renderView(q.camera, planes, background);
      degradeFrame(&img, q.camera, boxPose(std::max(0, k - 1), n), cMo, Eigen::Vector3d::Zero(), &rng);
      q.frames.push_back(img);
      q.truth.push_back(cMo);
    }
    return q;
  }();
  return s;
}

struct TrackRun {
  int tracked = 0;          ///< frames after the first with ok = true, before the first loss
  std::string lost;         ///< the first loss's reason
  double max_trans_m = 0, max_rot_deg = 0;
  std::vector<double> trans_m, rot_deg;
  std::vector<servo::TrackQuality> quality;
};

/// Tracks the sequence from frame 0's ground truth, predicting by the last frame-to-frame motion.
TrackRun track(const Sequence& seq, servo::FrameTracker* tracker) {
  TrackRun r;
  const servo::TrackStep s0 = tracker->start(seq.frames[0], seq.camera, seq.truth[0]);
  if (!s0.ok) {
    r.lost = "start: " + s0.lost_reason;
    return r;
  }
  std::optional<Pose> last = seq.truth[0], before;
  for (size_t k = 1; k < seq.frames.size(); ++k) {
    const Pose predicted = before ? *last * before->inverse() * *last : *last;
    const servo::TrackStep s = tracker->track(seq.frames[k], seq.camera, predicted);
    if (!s.ok) {
      r.lost = "frame " + std::to_string(k) + ": " + s.lost_reason;
      return r;
    }
    ++r.tracked;
    before = last;
    last = s.cMo;
    r.trans_m.push_back(translationError(s.cMo, seq.truth[k]));
    r.rot_deg.push_back(rotationError(s.cMo, seq.truth[k]) / kDeg);
    r.max_trans_m = std::max(r.max_trans_m, r.trans_m.back());
    r.max_rot_deg = std::max(r.max_rot_deg, r.rot_deg.back());
    r.quality.push_back(s.quality);
  }
  return r;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

void print(const char* what, const TrackRun& r) {
  int fmin = 1 << 30;
  for (const auto& q : r.quality) fmin = std::min(fmin, q.features);
  std::printf("%s: %d frames tracked%s%s; translation median %.2f max %.2f mm, rotation median %.3f "
              "max %.3f deg, fewest features %d\n",
              what, r.tracked, r.lost.empty() ? "" : ", lost at ", r.lost.c_str(), 1e3 * median(r.trans_m),
              1e3 * r.max_trans_m, median(r.rot_deg), r.max_rot_deg, r.quality.empty() ? 0 : fmin);
}

}  // namespace

// The surface model's geometry: a ray through the projection of a label point meets the can at
// that point; a ray through a box face's point meets that face, never the hidden one behind.
TEST(SurfaceModel, RaysMeetTheLabelAndTheFaceInFront) {
  const Intrinsics cam = rt::sceneCamera();
  const servo::SurfaceModel can(canModel());
  const CylinderLabel& L = *canModel().cylinder;
  const Pose cMo = canPose(20, 80);
  int hit = 0, facing = 0;
  for (int u = 0; u < L.image_width; u += 37)
    for (int v = 0; v < L.image_height; v += 41) {
      const Eigen::Vector2d uv(u, v);
      if (!L.facesCamera(uv.x(), uv.y(), cMo, 0.05)) continue;
      ++facing;
      const Eigen::Vector3d X = L.point(uv);
      const auto h = can.intersect(cMo, cam, cam.project(cMo * X));
      ASSERT_TRUE(h.has_value()) << u << "," << v;
      EXPECT_LT((h->X_o - X).norm(), 1e-9) << u << "," << v;
      ++hit;
    }
  EXPECT_GE(facing, 40);
  EXPECT_EQ(hit, facing);

  const servo::SurfaceModel box(boxModel());
  ASSERT_EQ(box.surfaceCount(), 3);
  const Pose bMo = boxPose(40, 90);  // turned 43 deg: front and +x faces in view
  const Eigen::Vector3d front(0.03, -0.02, -kBox.z() / 2), right(kBox.x() / 2, 0.01, 0.02);
  for (const auto& [X, face] : {std::pair{front, 0}, std::pair{right, 1}}) {
    const auto h = box.intersect(bMo, cam, cam.project(bMo * X));
    ASSERT_TRUE(h.has_value());
    EXPECT_EQ(h->surface, face);
    EXPECT_LT((h->X_o - X).norm(), 1e-9);
  }
  // A ray through the -x face's (hidden) centre meets the front face in front of it.
  const Eigen::Vector3d left(-kBox.x() / 2, 0, 0);
  const auto h = box.intersect(bMo, cam, cam.project(bMo * left));
  ASSERT_TRUE(h.has_value());
  EXPECT_EQ(h->surface, 0);
  // Off the box: no surface.
  EXPECT_FALSE(box.intersect(bMo, cam, Eigen::Vector2d(5, 5)).has_value());

  // Visible fraction: all of the facing label in the image, then the can's axis on the right edge
  // (about half of it out).
  EXPECT_NEAR(can.visibleFraction(cMo, cam), 1.0, 1e-12);
  Pose half(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, 0.5));
  EXPECT_NEAR(can.visibleFraction(half, cam), 1.0, 1e-12);
  half.t.x() = (cam.width - 0.5 - cam.cx) * (half.t.z() + kRadius) / cam.fx;
  EXPECT_NEAR(can.visibleFraction(half, cam), 0.5, 0.05);
  // The box turned away (its photographed faces seen from behind or edge-on): nothing faces.
  EXPECT_EQ(box.visibleFraction(Pose(rotY(M_PI), Eigen::Vector3d(0, 0, 0.6)), cam), 0);
  EXPECT_GT(box.visibleFraction(bMo, cam), 0.99);
}

// A can turning +-50 deg about its axis, tilting and moving, tracked from the first frame's
// ground truth: features on the label anchored to their points on the cylinder. The paper's
// planar approximation (the flat label on the tangent plane) on the same frames is worse.
TEST(SurfaceTracker, FollowsACanTurningAboutItsAxis) {
  const Sequence& seq = canSequence();
  auto tracker = servo::makePlanarTracker(canModel());
  const TrackRun r = track(seq, tracker.get());
  print("can (cylinder)", r);
  EXPECT_TRUE(r.lost.empty()) << r.lost;
  EXPECT_EQ(r.tracked, static_cast<int>(seq.frames.size()) - 1);
  EXPECT_LT(median(r.trans_m), 0.003);
  EXPECT_LT(r.max_trans_m, 0.01);
  EXPECT_LT(median(r.rot_deg), 2.0);
  EXPECT_LT(r.max_rot_deg, 5.0);
  for (const servo::TrackQuality& q : r.quality) {
    EXPECT_GE(q.features, 40);
    EXPECT_LT(q.projection_error_px, 1.0);
    EXPECT_GT(q.visible_fraction, 0.99);
  }

  const detector::ObjectModel& can = canModel();
  const detector::ObjectModel flat =
      detector::makeObjectModel("flat label", can.reference, can.camera, can.reference_cMo);
  auto planar = servo::makePlanarTracker(flat);
  const TrackRun p = track(seq, planar.get());
  print("can (tangent plane)", p);
  EXPECT_TRUE(!p.lost.empty() || median(p.trans_m) > 2 * median(r.trans_m));
}

// A box turning 120 deg about its vertical axis: the front face leaves the view (from frame 75
// on it faces away), the +x face comes in; features are re-seeded on it, and the pose holds on it
// alone at the end.
TEST(SurfaceTracker, FollowsABoxAcrossAChangeOfFace) {
  const Sequence& seq = boxSequence();
  auto tracker = servo::makePlanarTracker(boxModel());
  const TrackRun r = track(seq, tracker.get());
  print("box", r);
  EXPECT_TRUE(r.lost.empty()) << r.lost;
  EXPECT_EQ(r.tracked, static_cast<int>(seq.frames.size()) - 1);
  EXPECT_LT(median(r.trans_m), 0.002);
  EXPECT_LT(r.max_trans_m, 0.015);
  EXPECT_LT(median(r.rot_deg), 0.5);
  EXPECT_LT(r.max_rot_deg, 4.0);
  // The last frames: the front faces away, only the +x face is tracked.
  double late_trans = 0, late_rot = 0;
  for (size_t k = 76; k < seq.frames.size(); ++k) {
    const Eigen::Vector3d front_normal_c = seq.truth[k].R * Eigen::Vector3d(0, 0, -1);
    ASSERT_GT(front_normal_c.dot(seq.truth[k].t), 0) << k << ": the front should face away";
    late_trans = std::max(late_trans, r.trans_m[k - 1]);
    late_rot = std::max(late_rot, r.rot_deg[k - 1]);
  }
  std::printf("box, frames 76-%zu (front away): translation max %.2f mm, rotation max %.3f deg\n",
              seq.frames.size() - 1, 1e3 * late_trans, late_rot);
  EXPECT_LT(late_trans, 0.015);
  EXPECT_LT(late_rot, 4.0);
}

// kMbt follows one planar pattern: a cylinder or several views are refused at start-up; a 2D-only
// object has no pose to track; several views have one, through their views.
TEST(SurfaceTracker, TheMbtTrackerRefusesObjectsThatAreNotOnePlane) {
  servo::TrackerOptions mbt;
  mbt.method = servo::TrackerMethod::kMbt;
  for (const detector::ObjectModel* m : {&canModel(), &boxModel()}) {
    try {
      servo::makePlanarTracker(*m, mbt);
      ADD_FAILURE() << m->name << ": expected std::invalid_argument";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(m->name + ": the mbt tracker follows one planar pattern"),
                std::string::npos)
          << e.what();
    }
  }
  EXPECT_TRUE(boxModel().hasPose());
  EXPECT_FALSE(boxModel().has3d());
  const detector::ObjectModel flat = detector::makeObjectModel("flat", rt::loadMedia(kLabel), std::nullopt, std::nullopt);
  EXPECT_FALSE(flat.hasPose());
  EXPECT_THROW(servo::SurfaceModel{flat}, std::invalid_argument);
  EXPECT_EQ(servo::visibleFraction(flat, Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, 1)), rt::sceneCamera()), 0);
  // The corners reported for several views: the view seen most squarely (the front, then +x).
  const auto front = servo::projectPattern(boxModel(), boxPose(0, 90), rt::sceneCamera());
  const auto side = servo::projectPattern(boxModel(), boxPose(89, 90), rt::sceneCamera());
  ASSERT_TRUE(front && side);
  const auto quads = servo::patternQuads(boxModel());
  ASSERT_EQ(quads.size(), 3u);
  EXPECT_LT(((*front)[0] - rt::sceneCamera().project(boxPose(0, 90) * quads[0][0])).norm(), 1e-9);
  EXPECT_LT(((*side)[0] - rt::sceneCamera().project(boxPose(89, 90) * quads[1][0])).norm(), 1e-9);
}

// The pipeline on the can with a real detector. The detector gives a cylinder its planar
// approximation's pose (the flat label on the tangent plane: its rotation is off by tens of
// degrees on this label, its position by millimetres); the tracker starts from it on the
// cylinder's surface model and keeps it, without a loss, to the end.
TEST(SurfaceTracker, ThePipelineDetectsConfirmsAndTracksACan) {
  const Sequence& seq = canSequence();
  detector::Detector det;
  det.addObject(canModel());
  servo::TargetTracker pipeline(det);
  std::string modes;
  std::vector<double> trans, rot;
  int confirmed = 0;
  for (size_t k = 0; k < seq.frames.size(); ++k) {
    robot::MonoFrame f;
    f.image = seq.frames[k];
    f.stamp = static_cast<double>(k) / 30;
    f.index = static_cast<int64_t>(k);
    const servo::TargetFrame r = pipeline.process(f, seq.camera);
    ASSERT_TRUE(r.ok) << r.error;
    const servo::TargetState& s = r.objects[0];
    modes += s.mode == servo::TrackMode::kDetect ? 'D' : s.mode == servo::TrackMode::kTrack ? 'T' : '.';
    confirmed += s.confirmed;
    if (s.cMo) {
      trans.push_back(translationError(*s.cMo, seq.truth[k]));
      rot.push_back(rotationError(*s.cMo, seq.truth[k]) / kDeg);
    }
  }
  std::printf("pipeline on the can: %s (%d confirmed); translation median %.2f max %.2f mm, rotation "
              "median %.3f max %.3f deg\n",
              modes.c_str(), confirmed, 1e3 * median(trans), 1e3 * *std::max_element(trans.begin(), trans.end()),
              median(rot), *std::max_element(rot.begin(), rot.end()));
  const size_t first = modes.find("DD");
  ASSERT_NE(first, std::string::npos) << "two detections in a row confirm the can";
  EXPECT_EQ(modes.find('.', first), std::string::npos) << "no loss once confirmed: " << modes;
  EXPECT_NE(modes.find('T', first), std::string::npos) << modes;
  EXPECT_GE(confirmed, static_cast<int>(modes.size() - first) - 1);
  EXPECT_LT(*std::max_element(trans.begin(), trans.end()), 0.015);
}

// The new options are checked at start-up; the oracle (ground truth as an estimator) sees a
// several-view object by the view it shows most squarely.
TEST(SurfaceTracker, OptionsAreCheckedAndTheOracleSeesSeveralViews) {
  const auto throwsWith = [](const servo::TrackerOptions& o, const std::string& what) {
    try {
      o.check();
      ADD_FAILURE() << "expected " << what;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  servo::TrackerOptions o;
  o.seed_min_facing_cos = 1;
  throwsWith(o, "TrackerOptions.seed_min_facing_cos");
  o = servo::TrackerOptions();
  o.appearance_search_px = std::nan("");
  throwsWith(o, "TrackerOptions.appearance_search_px");
  o = servo::TrackerOptions();
  o.appearance_min_score = -0.1;
  throwsWith(o, "TrackerOptions.appearance_min_score");

  const servo::OracleEstimator oracle(boxModel());
  const Intrinsics cam = rt::sceneCamera();
  std::array<Eigen::Vector2d, 4> corners;
  // The end of the turn: the front faces away, the +x face is 20 deg from square.
  ASSERT_TRUE(oracle.visible(boxPose(89, 90), cam, &corners));
  const auto quads = servo::patternQuads(boxModel());
  EXPECT_LT((corners[2] - cam.project(boxPose(89, 90) * quads[1][2])).norm(), 1e-9);
  // Turned half-way round: the photographed faces are all away or edge-on.
  EXPECT_FALSE(oracle.visible(Pose(rotY(M_PI), Eigen::Vector3d(0, 0, 0.6)), cam));
}
