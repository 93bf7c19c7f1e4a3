#pragma once
// The photometric peak search (VerifyOptions::peak_search_*): where, beside an instance, its
// warped reference agrees with the scene better than at the instance itself. A few features on
// a small target can fit a homography several pixels off that passes every check while a better
// alignment lies beside it, out of ECC's reach from there; the peaks found here join the repeat
// periods' moves in the ambiguity test (periods.h), which aligns them by ECC and judges them.
//
// H: undistorted reference px -> undistorted scene px.
#include <vector>

#include "detector/registered_object.h"
#include "detector/verify.h"

namespace refgrasp::detector {

/// The reference warped by H into the scene, on a grid of at most 48 px on the pattern's
/// diagonal, compared by masked zero-mean NCC (cv::matchTemplate) with the scene at every
/// translation up to peak_search_reach x the diagonal. Returns H moved by the translations of
/// the (at most peak_search_count) best local maxima that correlate better than H itself (its
/// best within a grid px) by more than peak_search_margin and lie more than 3 scene px from it.
/// polygon: the verification region (und ref px). The scene image is the camera's raw one: the
/// pattern is placed there by the distortion's displacement at its centre (locally a
/// translation), and the translations found are applied to H in undistorted px.
std::vector<Eigen::Matrix3d> photometricPeaks(const RegisteredObject& obj, const Eigen::Matrix3d& H,
                                              const std::vector<Eigen::Vector2d>& polygon, const cv::Mat& scene,
                                              const Intrinsics& camera, const VerifyOptions& opt);

}  // namespace refgrasp::detector
