#pragma once
// Rendered views of labelled cylinders (cans, bottles) with ground truth by construction, and
// their scoring, shared by tests/detector/test_cylinder_detection.cpp and bench/bench_cylinder.cpp.
// The label is a crop of a real photograph (media/photos/), wrapped on the cylinder as
// core/cylinder.h defines; the views are rendered by the simulator's ray caster over a
// backdrop, then degraded (motion blur, noise: robot/sim/degrade.h; then JPEG).
//
// Frames: cMo = the cylinder's object frame (core/cylinder.h) in the camera frame, metres,
// radians. Images CV_8UC1.
#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"
#include "detector/detector.h"
#include "detector/object.h"
#include "robot/sim/render.h"

namespace refgrasp::eval {

/// A labelled cylinder: its label image and geometry.
struct LabelledCylinder {
  std::string name;
  std::string photo;  ///< media path the label was cut from
  cv::Mat label;      ///< CV_8UC1, columns along the circumference
  double radius_m = 0.033;
  double label_width_m = 0;  ///< arc length (2 pi r: all the way round)
  double label_height_m = 0;
  double height_m = 0;  ///< the whole side (>= label_height_m)

  detector::ObjectModel object() const;
  sim::TexturedCylinder body(const Pose& cMo) const;
};

/// A label cut from a media photo (the largest centred crop of the label's aspect, resized to
/// `rows` rows, gray): radius_m, label height, and the fraction of the circumference it covers
/// (1: all the way round).
LabelledCylinder labelledCylinder(const std::string& photo, double radius_m, double label_height_m,
                                  double wrap_fraction, int rows = 200);

/// Where the cylinder stands in a view.
struct CylinderViewSpec {
  double distance_m = 0.5;  ///< camera centre to the axis' middle
  double turn_rad = 0;      ///< about its axis: the label column at theta = turn faces the camera
  double tilt_rad = 0;      ///< axis tilted towards (+) or away from the camera, about camera x
  double roll_rad = 0;      ///< axis turned in the image plane
  Eigen::Vector2d offset =
      Eigen::Vector2d::Zero();  ///< axis' middle off the optical axis, fraction of the half-view (-1..1)
  std::string backdrop;         ///< "" : photo clutter (seeded); else a media path resized to the frame
  /// Photos (media paths) kept out of the photo clutter, besides the cylinder's own label photo.
  std::vector<std::string> exclude_from_backdrop;
  double noise_sigma = 2;  ///< gray levels
  double motion_blur_px = 0;
  int jpeg_quality = 0;  ///< 1-100, 0: none
  uint64_t seed = 0;
};

/// The pose a spec gives (object frame in the frame of camera `cam`).
Pose cylinderPose(const Intrinsics& cam, const LabelledCylinder& c, const CylinderViewSpec& spec);

struct CylinderView {
  cv::Mat image;
  Pose cMo;
  /// Width (px) of the label's visible part in the image (its columns facing the camera).
  double visible_width_px = 0;
  /// Angle between the label's centre column's outward normal and the ray to the camera
  /// (0: facing it), radians; 0 for a label that goes all the way round (its visible part is
  /// always centred).
  double centre_angle_rad = 0;
  /// The bar applies: visible part >= 40 px wide and centre column within 60 deg.
  bool counted() const;
};

/// Renders `c` (or nothing when c is null: a clutter frame) over the backdrop and degrades it.
/// `others`: more cylinders in the scene (distractors).
CylinderView renderCylinderView(const Intrinsics& cam, const LabelledCylinder* c, const CylinderViewSpec& spec,
                                const std::vector<sim::TexturedCylinder>& others = {});

/// Random views: distance uniform in [min_distance_m, max_distance_m], turn uniform in +-max_turn_rad, tilt
/// in +-max_tilt_rad, roll in +-0.3 rad, offset in +-0.5, noise 1-3, blur 0-2 px, JPEG 60-95 on half.
std::vector<CylinderViewSpec> randomCylinderViews(std::mt19937_64& rng, int n, double min_distance_m,
                                                  double max_distance_m, double max_turn_rad, double max_tilt_rad);

/// Pose error of a detection against the truth.
struct CylinderPoseError {
  bool found = false;
  double rotation_deg = 0;
  double translation_fraction = 0;  ///< |t_est - t_true| / |t_true|
  /// The bar: found, within 2 deg and 2 % of the distance.
  bool within() const { return found && rotation_deg <= 2 && translation_fraction <= 0.02; }
};
CylinderPoseError cylinderPoseError(const std::optional<detector::Detection>& d, const Pose& truth);
CylinderPoseError cylinderPoseError(const std::optional<Pose>& cMo, const Pose& truth);

}  // namespace refgrasp::eval
