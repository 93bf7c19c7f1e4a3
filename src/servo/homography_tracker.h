#pragma once
// Frame-to-frame tracking of a 2D-only object (a reference image and pattern region, no metric
// geometry): its homography and pattern corners in every frame.
//
// Per frame: KLT features (OpenCV's pyramidal Lucas-Kanade, as ViSP's vpKltOpencv) on the
// pattern, each anchored to its reference pixel, start at the predicted homography; a robust
// (RANSAC, then least squares on the inliers) homography from the surviving features; then the
// homography is aligned photometrically with the REFERENCE image (the detector's dense ECC,
// Detector::alignHomography, in its robust form that leaves occluded blocks out), so every
// tracked frame is measured against the reference, not only against the previous frame, and the
// error does not grow with time. The features are re-anchored on the aligned homography and
// re-seeded in the pattern when too few are left.
//
// Lost when: fewer than min_features features survive (or fewer than min_feature_fraction of
// those seeded), less than min_visible_fraction of the pattern projects in the image, the
// alignment is refused (correlation below align_min_correlation, a corner moved more than
// align_max_corner_shift_px, the features disagree with it by more than
// align_max_feature_rms_px RMS) max_unaligned_frames frames in a row, or it used less than
// min_aligned_fraction of the reference. The options are TrackerOptions' (servo/tracker.h), with
// the same meaning and defaults as for the pose tracker.
//
// Pixels: H maps undistorted reference px -> undistorted image px (x_s ~ H x_r), as
// detector::Detection::H; corners TL, TR, BR, BL in image px (distorted by the camera). Images
// 8-bit gray of the camera's size. Deterministic: the same frames give the same homographies.
#include <Eigen/Core>
#include <array>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "detector/detector.h"
#include "detector/object.h"
#include "servo/tracker.h"

namespace refgrasp::servo {

/// The outcome of HomographyTracker::start() or track().
struct HomographyStep {
  bool ok = false;  ///< false: lost (or could not be started)
  Eigen::Matrix3d H = Eigen::Matrix3d::Identity();  ///< ok: undistorted reference px -> image px
  std::array<Eigen::Vector2d, 4> corners{};         ///< ok: pattern corners, image px
  TrackQuality quality;
  std::string lost_reason;  ///< !ok: one line, e.g. "too few features (5 < 12)"
};

/// Aligns a homography of one object with its reference (Detector::alignHomography bound to it).
using HomographyAligner = std::function<detector::HomographyAlignment(
    const cv::Mat& gray, const Intrinsics& camera, const Eigen::Matrix3d& H)>;

class HomographyTracker {
 public:
  /// object: a single planar reference (2D-only, or planar with a pose); align: nullptr tracks
  /// by the features alone (they drift). Throws std::invalid_argument for bad options or a
  /// several-view or cylinder object (start-up).
  HomographyTracker(const detector::ObjectModel& object, const TrackerOptions& options,
                    HomographyAligner align);
  ~HomographyTracker();
  /// Starts on the frame a detection was made in, at its H. Never throws.
  HomographyStep start(const cv::Mat& gray, const Intrinsics& camera, const Eigen::Matrix3d& H);
  /// H in the next frame, starting from predicted_H (empty: the last H). ok = false: lost; the
  /// tracker stays stopped until the next start(). Never throws.
  HomographyStep track(const cv::Mat& gray, const Intrinsics& camera,
                       const std::optional<Eigen::Matrix3d>& predicted_H = std::nullopt);

 private:
  struct Impl;
  std::unique_ptr<Impl> p_;
};

/// A tracker for object `id` of `detector` (which must outlive it), aligned through
/// Detector::alignHomography with the detector's dense options, robust, and the alignment
/// thresholds of `options`.
std::unique_ptr<HomographyTracker> makeHomographyTracker(const detector::Detector& detector, int id,
                                                         const TrackerOptions& options = {});

/// Pattern corners TL, TR, BR, BL in image px under H (undistorted reference px -> undistorted
/// image px); corners_ref: the object's corners in undistorted reference px.
std::array<Eigen::Vector2d, 4> cornersUnderH(const Eigen::Matrix3d& H,
                                             const std::array<Eigen::Vector2d, 4>& corners_ref,
                                             const Intrinsics& camera);

}  // namespace refgrasp::servo
