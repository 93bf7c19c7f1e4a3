#pragma once
// A several-view box on real footage: OpenCV's hand-held box clip
// (media/video/box.mp4) with the two-view definition made from one of its frames
// (config/objects/box_video.yaml), checked against box corners labelled by hand in some frames
// (media/video/box_corners.txt).
//
// Two runs over the clip:
//   - the robot's pipeline (servo::PoseReplay with the planar trackers, as pose_replay runs it):
//     per frame detect / track / lost; at the labelled frames the box corners projected with its
//     cMo against the labels;
//   - each view alone (its planar definition registered as an object of its own, detected on
//     every view_stride-th frame): where both views are found, the object pose each implies
//     (cMo = cMv * oMv^-1) and how far the two are apart.
//
// Frames: o = the box (origin at the front face's centre, x along the front's columns, y down,
// z into the box), c = the camera. Labelled corners, in this order: A front-top-left, B
// front-top-right, C front-bottom-right, D front-bottom-left, F back-top-right; the box spans
// x in [-W/2, W/2], y in [-H/2, H/2], z in [0, D].
#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/camera.h"
#include "core/pose.h"
#include "detector/detector.h"
#include "servo/target_tracker.h"

namespace refgrasp::eval {

struct BoxVideoOptions {
  std::string video;   ///< the clip (any file cv::VideoCapture reads)
  std::string camera;  ///< its intrinsics (ROS yaml / ViSP xml)
  std::string object;  ///< the several-view definition of the box
  std::string labels;  ///< hand-labelled corners ("" = none)
  Eigen::Vector3d box_size_m{0.25, 0.0775, 0.1725};  ///< W, H, D of the box the labels are corners of
  int max_frames = 0;   ///< frames read from the start (0 = all)
  int view_stride = 1;  ///< the views alone are detected on frames 0, stride, 2 stride, ... (0 = never)
  /// A pose whose labelled corners lie farther than this from their labels on average is a
  /// wrong report (the box drawn somewhere else). 20 px: about 8 % of the box's width in the
  /// clip (200-290 px); an accurate pose misses the labels by their own scatter (a box fitted
  /// to them leaves 3 px RMS) plus the camera's and the box's estimated geometry.
  double wrong_px = 20;
  bool track = true;  ///< false: the pipeline detects every frame
  detector::DetectorOptions detector;
  /// Throws std::invalid_argument "BoxVideoOptions.<field>: <problem>".
  void check() const;
};

/// The corners of the box in one frame, image px (order: see the header comment).
struct BoxLabel {
  int frame = 0;
  std::array<Eigen::Vector2d, 5> corners_px;
};

/// Reads a labels file: one line per frame, `frame uA vA uB vB uC vC uD vD uF vF`, '#' comments.
/// Throws ConfigError("<file>: line N: <problem>").
std::vector<BoxLabel> loadBoxLabels(const std::string& path);

/// The labelled corners A, B, C, D, F of a W x H x D box in its frame o.
std::array<Eigen::Vector3d, 5> boxLabelPoints(const Eigen::Vector3d& size_m);

struct BoxLabelCheck {
  int frame = 0;
  servo::TrackMode mode = servo::TrackMode::kLost;
  bool has_pose = false;
  double max_px = 0, mean_px = 0;  ///< corner errors (0 without a pose)
  std::array<double, 5> corner_px{};  ///< per corner, A B C D F
};

/// Two views' poses of the box in one frame.
struct BoxViewAgreement {
  int frame = 0;
  double distance_m = 0;      ///< the box's distance (mean of the two)
  double translation_m = 0;   ///< |t_a - t_b|
  double rotation_deg = 0;    ///< angle of R_a^T R_b
  /// A view was found only with its view-synthesised features (ObjectStats::views_matched):
  /// its own features found nothing in this frame.
  bool by_views = false;
};

struct BoxVideoResult {
  int frames = 0;
  int detect = 0, track = 0, lost = 0;  ///< the pipeline's modes
  std::vector<BoxLabelCheck> labelled;  ///< one per label whose frame was read
  int wrong = 0;                        ///< labelled frames whose mean corner error exceeds wrong_px
  std::vector<std::string> view_names;
  int view_frames = 0;                  ///< frames the views alone were detected on
  std::vector<int> view_found;          ///< per view: frames it was found in
  std::vector<BoxViewAgreement> agreement;  ///< frames where every view was found (two views)
};

BoxVideoResult runBoxVideo(const BoxVideoOptions& options);

/// A box fitted to the labels with a given focal length (square pixels, principal point at the
/// image centre, no distortion): one pose per labelled frame (PnP on its five corners) and the
/// aspect ratios H/W, D/W (H/W in [0.2, 0.5], D/W in [0.4, 1]; a 0.02 grid, then 0.005 around
/// its best) that minimise the reprojection RMS over every frame. The labels carry no scale: W is 1.
struct BoxFit {
  double f_px = 0;
  double h_over_w = 0, d_over_w = 0;
  double rms_px = 0;
};
BoxFit fitBoxToLabels(const std::vector<BoxLabel>& labels, double f_px, int image_width, int image_height);

/// The six top-and-front corners (A, B, C, D, F as labelled, then E back-top-left) of a box of
/// size_m fitted to one frame's labels with the pinhole camera (PnP on the five corners).
std::array<Eigen::Vector2d, 6> fittedBoxCorners(const BoxLabel& label, const Eigen::Vector3d& size_m,
                                                const Intrinsics& camera);

}  // namespace refgrasp::eval
