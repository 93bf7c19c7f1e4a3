#pragma once
// The reference side of matching, built once per object (paper III-B): the reference features
// inside the pattern polygon (capped), the pattern geometry, each feature's nearest reference
// neighbours (for the local search) and the integer descriptors for the global 2-NN.
//
// Frames: reference px, pixels of the reference image (possibly undistorted by the caller).
#include <Eigen/Core>
#include <vector>

#include "detector/features.h"
#include "detector/knn.h"

namespace refgrasp::detector {

struct MatchOptions;  // detector/matching.h

struct ReferenceIndex {
  Features features;                          ///< kept reference features (indices used below)
  std::vector<Eigen::Vector2d> polygon_px;    ///< pattern polygon, reference px
  std::vector<Eigen::Vector2d> hull_px;       ///< its convex hull (used for plausibility/overlap)
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();  ///< pattern centre c_r (polygon centroid)
  double diagonal_px = 0;                     ///< diagonal of the polygon's bounding box
  double feature_hull_area_px2 = 0;           ///< area of the convex hull of the kept features
  GridIndex neighbours;                       ///< features.keypoints for nearest-first queries (reference px)
  IntegerDescriptors descriptors;             ///< features.descriptors for the kernels (byte split)
  /// Reference px -> the pattern plane seen fronto-parallel (plane metres scaled to about the
  /// reference's px), from the reference pose; identity for 2D-only objects (the reference then
  /// stands for the plane).
  Eigen::Matrix3d rectify_px = Eigen::Matrix3d::Identity();
  /// Features per place of the pattern: kept features over those of the reference image itself
  /// (1 without view-synthesised features), so that a walk over the nearest N places visits
  /// N x this features.
  double features_per_place = 1;
};

/// Keeps features inside the polygon (>= 3 vertices; empty = whole image), then at most
/// opt.max_reference_features: strongest first within each octave, taken round robin over the
/// octaves (so coarse features, the only ones left on far objects, survive the cap); the result
/// is ordered strongest first. Keypoint .pt may already be undistorted by the caller.
/// Throws std::invalid_argument for nonsense options or a degenerate polygon.
ReferenceIndex buildReferenceIndex(Features ref_features,
                                   const std::vector<Eigen::Vector2d>& pattern_polygon_px,
                                   const MatchOptions& opt);

/// Global 2-NN of every scene feature among the reference features (indices into
/// ref.features); multithreaded, exact.
std::vector<NearestTwo> nearestTwo(const ReferenceIndex& ref, const Features& scene,
                                   KnnKernel kernel = KnnKernel::kAuto);

/// The reference's repeat periods: displacements in the rectified pattern plane (ref.rectify_px
/// units) that carry at least max(4, 1 %) of its features onto look-alikes (size within 30 %,
/// SIFT descriptors closer than 200, farther apart than the feature's size), e.g. a facade's
/// window spacing. Modes of 3-unit bins, strongest first, both signs of each, at most
/// max_periods; empty for a pattern without repeats.
std::vector<Eigen::Vector2d> repeatPeriods(const ReferenceIndex& ref, int max_periods = 6);

}  // namespace refgrasp::detector
