#pragma once
// Evaluation of the detector on realistic sets, side by side with the classic OpenCV
// pipeline (eval/classic.h): the same frames, tables by distance, tilt and target size.
//
// A set: objects defined from reference PHOTOGRAPHS (robot/sim/realistic_scene.h: oblique, other
// camera, light, blur, noise, JPEG, traced polygon region) of textures, and scenes of them at
// stratified distances and tilts with realistic camera looks, partial occlusion and real photos
// in the background. Frame i's content depends on (set seed, i) only, so a seed range is a split:
// develop on one, report on another.
//
// Scoring (per method and frame): "found" = reported with the four true texture corners, mapped
// by the reported homography, within max(5 px, 10 % of the target's diagonal) of the truth;
// "wrong" = reported but not found (a false positive); "pose ok" = found with rotation error
// < 2 deg and translation error < 2 % of the distance.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"
#include "detector/detector.h"
#include "detector/object.h"
#include "robot/sim/realistic_scene.h"

namespace refgrasp::eval {

struct RealisticSetSpec {
  std::string name;
  std::vector<std::string> textures;    ///< media paths (loadMedia)
  double width_m = 0.2;                 ///< physical width of each pattern
  int references_per_texture = 2;       ///< objects per texture (different reference photos)
  double ref_min_tilt_rad = 0, ref_max_tilt_rad = 60 * M_PI / 180;
  double ref_min_width_px = 150, ref_max_width_px = 400;
  std::vector<double> distance_edges_m = {0.3, 0.8, 1.3, 1.8, 2.3, 2.8};
  std::vector<double> tilt_edges_rad = {0, 15 * M_PI / 180, 30 * M_PI / 180, 45 * M_PI / 180, 60 * M_PI / 180};
  int frames = 200;
  double occlusion_probability = 0.25, max_occlusion = 0.35;
  double min_look = 0.3, max_look = 1.0;  ///< randomCameraLook strength range of the scenes
  uint64_t seed = 1;
};

/// The project's realistic sets: "photos" (the real photographs of media/photos/ as patterns),
/// "procedural" (media/targets/), "far_oblique" (a 16 cm face seen at 40-60 deg, reference a
/// small oblique crop as in a frame of a video, 0.5-2.5 m). `seed` picks the split.
std::vector<RealisticSetSpec> realisticSets(uint64_t seed, int frames_per_set);

struct SetObject {
  std::string texture;
  testing::ReferencePhoto photo;
  detector::ObjectModel model;  ///< from the photo: its camera, pose and traced polygon
  double width_m = 0, height_m = 0;
};

struct SetFrame {
  cv::Mat image;
  Intrinsics camera;
  int object = 0;
  Pose cMo;                                ///< truth
  std::array<Eigen::Vector2d, 4> corners;  ///< true texture corners, image px
  double distance_m = 0, tilt_rad = 0, size_px = 0;  ///< size: sqrt of the projected area
  int distance_bin = 0, tilt_bin = 0;
};

class RealisticSet {
 public:
  explicit RealisticSet(RealisticSetSpec spec);
  const RealisticSetSpec& spec() const { return spec_; }
  const std::vector<SetObject>& objects() const { return objects_; }
  int frames() const { return spec_.frames; }
  /// Frame i (rendered on each call; deterministic).
  SetFrame frame(int i) const;

 private:
  RealisticSetSpec spec_;
  std::vector<SetObject> objects_;
};

struct MethodOutcome {
  bool reported = false, found = false, pose_ok = false;
  double corner_px = 0, rot_deg = 0, rel_t = 0;  ///< when reported (pose errors when it has a pose)
  bool has_pose = false;
  int inliers = 0;
  double log10_nfa = 0, correlation = 0;  ///< refgrasp: significance and verification of the instance
  double ms = 0;  ///< time of the whole method on the frame (thread CPU or wall, see EvalOptions)
};

struct FrameOutcome {
  int frame = 0, object = 0, distance_bin = 0, tilt_bin = 0;
  double distance_m = 0, tilt_rad = 0, size_px = 0;
  MethodOutcome refgrasp, classic;
  double sift_ms = 0;  ///< refgrasp's SIFT extraction alone on the frame (when timed)
  std::string miss;    ///< refgrasp's miss reason when not reported
};

struct EvalOptions {
  detector::DetectorOptions detector;
  /// true: the classic pipeline extracts with cv::SIFT itself (its real cost, timed); false: it
  /// reuses the project's fast SIFT features of the frame (the same keypoints, proven
  /// equivalent; for quick runs, classic time not meaningful).
  bool classic_own_sift = true;
  bool time_sift = false;   ///< also time refgrasp's extraction alone
  bool cpu_time = true;     ///< thread CPU time (call cv::setNumThreads(1) first) instead of wall
  int min_distance_bin = 0; ///< frames of nearer distance bins are skipped (not rendered)
  /// Both methods get each object without its reference pose (2D-only: H and corners, no cMo),
  /// the use of a reference photo nobody measured; scored on the corners alone.
  bool two_d = false;
};

/// The object without its reference pose: 2D-only (homography and corners, no cMo), the use of a
/// reference photo nobody measured.
detector::ObjectModel twoDOnly(const detector::ObjectModel& model);

/// Runs both methods on frames [first, last) of the set, each with only the frame's object
/// registered. progress(i) is called per frame when given.
std::vector<FrameOutcome> evaluateSet(const RealisticSet& set, const EvalOptions& opt, int first, int last,
                                      const std::function<void(int)>& progress = {});

/// The sets' "pose ok" tolerance, without the "found" part: cMo (object in camera, metres,
/// radians) within 2 deg of the truth's rotation and 2 % of its distance.
bool poseWithinTolerance(const Pose& cMo, const Pose& truth);

/// Scores one reported result (H: reference px -> image px; cMo when the method gave a pose).
MethodOutcome scoreOutcome(const SetObject& obj, const SetFrame& f, const Eigen::Matrix3d& H,
                           const std::optional<Pose>& cMo);
/// Scores reported pattern corners (TL, TR, BR, BL, image px) against the frame's: reported,
/// corner_px and found (no pose figures).
MethodOutcome scoreCorners(const SetFrame& f, const std::array<Eigen::Vector2d, 4>& corners);

struct Tally {
  int n = 0, found_r = 0, found_c = 0, pose_r = 0, pose_c = 0, wrong_r = 0, wrong_c = 0;
  double rot_med_r = NAN, rot_med_c = NAN, t_med_r = NAN, t_med_c = NAN;  ///< over each one's found
  double rot_both_r = NAN, rot_both_c = NAN;  ///< medians over the frames both found
};
Tally tally(const std::vector<FrameOutcome>& rows);

/// Markdown tables (by distance, by tilt, by target size) of one set's outcomes, with totals and
/// the median times.
std::string formatTables(const RealisticSetSpec& spec, const std::vector<FrameOutcome>& rows);

/// Bins where refgrasp finds fewer or gets fewer poses ok than the classic pipeline (empty: none),
/// e.g. "distance 1.8-2.3 m: found 5 < 7".
std::vector<std::string> binsWhereRefgraspLoses(const RealisticSetSpec& spec,
                                                const std::vector<FrameOutcome>& rows);

/// Clutter with real photographs and no registered object in view: every object of `objects`
/// registered in one detector; the frames show other photographs, the procedural clutter and
/// "siblings" of the registered patterns (a piece of 6-15 % of a pattern, a logo or a word,
/// pasted on another texture). Returns the number of detections (all false) over `frames`.
struct ClutterReport {
  int frames = 0, detections = 0, classic_detections = 0;
  std::vector<std::string> details;  ///< one line per false detection
};
/// Frame i of the photo clutter evaluateClutter shows (seed) when `objects` are registered.
struct ClutterFrame {
  cv::Mat image;
  Intrinsics camera;
};
ClutterFrame clutterFrame(const std::vector<SetObject>& objects, uint64_t seed, int i);

ClutterReport evaluateClutter(const std::vector<SetObject>& objects, const detector::DetectorOptions& opt,
                              int frames, uint64_t seed, bool run_classic);

}  // namespace refgrasp::eval
