#pragma once
// The paper's two experiments of Sec. IV reproduced on the simulated enon (docs/evaluation.md).
//
// Fig. 7, detection range: six small objects with photographed labels (media/photos/), four
// planar (one a box seen across an edge) and two round (a can, a bottle), stand on a long table in
// front of the robot, which points its head camera (config/enon.yaml, its rig's left eye,
// distortion included) at them. Per object, distance and turn: one rendered view and `frames`
// copies with independent sensor noise (the static object of the paper, observed many times).
// Methods: refgrasp with PoseMethod::kRefined (on a cylinder definition: the cylinder model where
// the detector has one), refgrasp with PoseMethod::kPaper (the paper's pose; on a cylinder the
// flat label's tangent plane, its planar approximation) for the round objects, and the classic
// OpenCV pipeline (eval/classic.h, on the flat label for the round ones). All six objects are
// registered in each refgrasp detector, as on the robot.
//
// Scoring, per frame and method (truth: the render pose, cMo in the left camera frame):
//   success  the object is reported with its origin within 5 % of the distance of the truth;
//   pose ok  success with rotation error < 2 deg and translation error < 2 % of the distance
//            (bench_realistic's "pose ok");
//   std      per cell (object, distance, turn), the sample standard deviation of the reported
//            position cMo.t (x, y, z, camera frame) over its successful frames (>= 2); per
//            object and distance, the root mean square over the turns that have one.
//
// Fig. 8, false positives: the simulated enon drives and pans/tilts its head through a cluttered
// room (desks, shelves, posters, boxes, people-sized stands: the project's generated textures,
// none of the six labels) for `duration_s`, the six objects registered; every frame the robot's
// pipeline takes (GraspOptions::frame_period_s, 16 per second) goes through the TargetTracker
// (servo/target_tracker.h) in detection mode: a raw detection is one the detector reported, a
// confirmed one survived the tracker's temporal consistency rule (confirm_detections
// consecutive agreeing detections). The left eye only (mono).
#include <Eigen/Core>
#include <functional>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"
#include "detector/object.h"
#include "robot/sim/render.h"

namespace refgrasp::eval {

enum class PaperShape { kPlanar, kBox, kCylinder };

/// One of the six objects: its definition and how it is drawn.
struct PaperObject {
  std::string name;         ///< also the detector object's name
  std::string description;  ///< label source and size, for the report
  PaperShape shape = PaperShape::kPlanar;
  detector::ObjectModel model;
  /// Planar and box: the faces, each TexturedPlane::cMp holding oMp (face in the object frame).
  std::vector<sim::TexturedPlane> faces;
  /// Cylinder: the can or bottle (its cMo is set per view).
  std::optional<sim::TexturedCylinder> cylinder;
  /// The point the object is placed and turned about, object frame: the face centre (planar),
  /// the box centre, the axis at the label's centre height (cylinder).
  Eigen::Vector3d centre_o = Eigen::Vector3d::Zero();
  double height_m = 0;             ///< standing height (it rests on the table at centre - height/2)
  std::vector<double> turns_deg;   ///< the turns it is seen at
  bool round() const { return shape == PaperShape::kCylinder; }
};

/// The six objects A-F (labels cropped from media/photos/ in code).
std::vector<PaperObject> paperObjects(const std::vector<double>& planar_turns_deg,
                                      const std::vector<double>& box_turns_deg);

enum class Fig7Method { kRefined, kPaper, kClassic };
const char* fig7MethodName(Fig7Method m, bool round);

struct Fig7Options {
  std::vector<double> distances_m = {0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0, 2.25, 2.5, 2.75, 3.0};
  std::vector<double> turns_deg = {0, 30, 60};      ///< planar objects and the round ones
  std::vector<double> box_turns_deg = {30, 45, 60};  ///< the box: always across an edge
  int frames = 20;                                  ///< noisy copies per view
  double noise_sigma = 2.5;                         ///< sensor noise, gray levels
  int threads = 2;                                  ///< views rendered and detected in parallel
  uint64_t seed = 7;
  std::string config_dir;  ///< holds enon.yaml (its rig, cameras); "" = the source tree's config/
  /// Throws std::invalid_argument "Fig7Options.<field>: <problem>".
  void check() const;
};

/// One frame's outcome for one method.
struct Fig7Outcome {
  bool reported = false, success = false, pose_ok = false;
  Eigen::Vector3d t = Eigen::Vector3d::Zero();  ///< reported cMo.t (camera frame, metres)
  double rot_deg = 0, t_err_m = 0;
  int others = 0;  ///< other registered objects reported in the frame (false positives)
};

struct Fig7Cell {
  int object = 0, distance = 0, turn = 0;  ///< indices into objects, distances, the object's turns
  double distance_m = 0, turn_deg = 0;
  double range_m = 0;  ///< |cMo.t| of the truth
  Pose cMo;            ///< truth
  std::vector<std::vector<Fig7Outcome>> by_method;  ///< [Fig7Method][frame]; empty when not run
};

/// One table row: an object, a method, a distance.
struct Fig7Row {
  int object = 0;
  Fig7Method method = Fig7Method::kRefined;
  double distance_m = 0;
  int frames = 0, success = 0, pose_ok = 0, wrong = 0, others = 0;
  Eigen::Vector3d std_m = Eigen::Vector3d::Constant(NAN);  ///< RMS over turns of the per-cell std
  double success_rate() const { return frames ? static_cast<double>(success) / frames : 0; }
};

struct Fig7Result {
  Fig7Options options;
  std::vector<PaperObject> objects;
  std::vector<Fig7Cell> cells;
  std::vector<Fig7Row> rows;  ///< per object, method (those run), distance
  Intrinsics camera;
  /// Rows of one object and method, by distance.
  std::vector<const Fig7Row*> rowsOf(int object, Fig7Method m) const;
};

/// Methods run on an object: refined and classic; paper too for the round ones.
std::vector<Fig7Method> fig7Methods(const PaperObject& o);

/// Runs Fig. 7; progress(done, total) after each view.
Fig7Result runFig7(const Fig7Options& opt, const std::function<void(int, int)>& progress = {});

/// The rendered view of one cell before noise (for the report's illustration and tests).
cv::Mat renderFig7View(const Fig7Options& opt, const PaperObject& o, double distance_m, double turn_deg,
                       Pose* cMo = nullptr);

struct Fig8Options {
  double duration_s = 73;
  double frame_rate_hz = 16;  ///< GraspOptions::frame_period_s = 1/16 s
  double noise_sigma = 2.5;
  uint64_t seed = 8;
  std::string config_dir;  ///< as Fig7Options
  void check() const;
};

struct Fig8Frame {
  double t_s = 0;
  std::vector<int> raw, confirmed;  ///< per object: 1 when detected / confirmed this frame
  double x_m = 0, y_m = 0, pan_rad = 0, tilt_rad = 0;  ///< true robot base position and head
};

struct Fig8Result {
  Fig8Options options;
  std::vector<std::string> names;
  std::vector<Fig8Frame> frames;
  int collisions = 0;  ///< contacts of the run (the path avoids every object: 0)
  std::vector<int> rawTotals() const;
  std::vector<int> confirmedTotals() const;
};

/// paper_figures --quick: 2 distances (0.5, 2 m), one turn (30 deg; the box 45 deg), 2 frames per
/// view, 3 s of driving: a smoke test of the whole pipeline in seconds, not the figures.
void makeQuick(Fig7Options* fig7, Fig8Options* fig8);

/// Runs Fig. 8; progress(done, total) after each frame.
Fig8Result runFig8(const Fig8Options& opt, const std::function<void(int, int)>& progress = {});

/// The report: docs/evaluation.md's text (markdown tables, the paper's words beside them) and
/// its three PNGs written to <dir>/evaluation.md and <dir>/img/ (fig7_success.png,
/// fig7_pose_std.png, fig7_views.png, fig8_false_positives.png). `command` is the line that made it. Returns
/// the paths written. Throws std::runtime_error naming a file that cannot be written.
std::vector<std::string> writePaperReport(const std::string& dir, const Fig7Result& fig7, const Fig8Result& fig8,
                                          const std::string& command);

/// The markdown tables alone (also printed by the command).
std::string fig7Tables(const Fig7Result& r);
std::string fig8Table(const Fig8Result& r);

/// The plots.
cv::Mat fig7SuccessPlot(const Fig7Result& r);
cv::Mat fig7StdPlot(const Fig7Result& r);
cv::Mat fig8Plot(const Fig8Result& r);
/// The six objects seen from the robot at one distance (each at its middle turn), 960x480.
cv::Mat fig7Views(const Fig7Result& r, double distance_m);

}  // namespace refgrasp::eval
