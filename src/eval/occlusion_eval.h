#pragma once
// Occlusion by textured occluders: sequences where a card cut from a REAL PHOTOGRAPH (another
// picture of media/photos/, with its own texture) slides over a planar target while the camera
// moves slowly, and the counts of single-frame detection (refgrasp and the classic pipeline) and
// of the robot's tracking pipeline (servo::PoseReplay: 3D objects with the pose tracker, 2D-only
// ones with the homography tracker) on them.
//
// A sequence: the target (a media/photos or media/targets texture, 0.2 m wide) is defined from a
// reference PHOTOGRAPH of it (realistic_scene.h, as the realistic sets), fixed in front of a
// wall of photo clutter; the camera sways at 0.42-0.68 m, tilted up to 25 deg. The card hangs
// 15-40 % of the way from the target to the camera, rotated in its plane, entering from one
// side (a direction drawn per sequence) and leaving the same way: per frame it is placed so that
// it covers the fraction of the target's image area that the sequence prescribes at that time,
// min_cover at the ends and max_cover in the middle (0.5 - 0.5 cos). The camera look (gain,
// gamma, gradient, defocus, vignetting, JPEG) is one per sequence, noise new in every frame.
// Deterministic given the seed.
//
// Scoring as the realistic sets (realistic_eval.h): "found" = the four pattern corners within
// max(5 px, 10 % of the target's diagonal) of the truth; "wrong" = reported but not found.
// Tracking counts a frame as tracked when the pipeline gives a confirmed pose (3D) or confirmed
// corners (2D-only), scored on the corners the same way.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "eval/realistic_eval.h"

namespace refgrasp::eval {

struct OcclusionSequenceSpec {
  std::string texture;   ///< the target, media path
  std::string occluder;  ///< the card's picture, media path (never the target's)
  int frames = 80;
  double min_cover = 0.1, max_cover = 0.6;  ///< fraction of the target's image area covered
  uint64_t seed = 1;
};

/// `count` sequences of `frames` frames, the targets alternating between media/photos and
/// media/targets, each card cut from another photograph; seed picks the draw.
std::vector<OcclusionSequenceSpec> occlusionSequences(uint64_t seed, int count, int frames);

struct OcclusionFrame {
  SetFrame frame;        ///< image, camera, truth (object 0: the sequence's target)
  double covered = 0;    ///< fraction of the target's image area the card hides
};

class OcclusionSequence {
 public:
  explicit OcclusionSequence(OcclusionSequenceSpec spec);
  const OcclusionSequenceSpec& spec() const { return spec_; }
  const SetObject& object() const { return object_; }
  int frames() const { return spec_.frames; }
  /// Frame i (rendered on each call; deterministic).
  OcclusionFrame frame(int i) const;

 private:
  OcclusionSequenceSpec spec_;
  SetObject object_;
  cv::Mat card_, wall_;  ///< the card's picture, the wall's photo clutter
  double card_depth_ = 0;  ///< the card's distance in front of the target / the camera's mean distance
  double card_angle_ = 0, entry_dir_ = 0;  ///< in-plane rotation of the card, direction it enters along (rad)
  uint64_t sway_seed_ = 0;  ///< the camera path and look
};

/// Cover bins of the tables: 10-20, 20-40, 40-60 % (a frame below 10 % goes to the first).
inline const std::vector<double>& occlusionBinEdges() {
  static const std::vector<double> e = {0.0, 0.2, 0.4, 1.0};
  return e;
}
int occlusionBin(double covered);
std::string occlusionBinName(int bin);  ///< "10-20 %", "20-40 %", "40-60 %"

/// One frame's outcomes: detection by both methods (3D registration) and the pipeline's report.
struct OcclusionRow {
  int sequence = 0, frame = 0;
  double covered = 0;
  MethodOutcome refgrasp, classic;    ///< single-frame detection (with the reference pose)
  MethodOutcome refgrasp_2d;          ///< single-frame detection of the 2D-only object
  std::string miss;                   ///< refgrasp's miss reason (3D) when not reported
  MethodOutcome tracked_3d, tracked_2d;  ///< reported = confirmed pose / corners of the pipeline
};

struct OcclusionOptions {
  detector::DetectorOptions detector;
  bool detection = true;  ///< single-frame detection (refgrasp, classic, refgrasp 2D-only)
  bool tracking = true;   ///< the tracking pipeline, 3D and 2D-only
};

/// Runs everything asked on every frame of the sequence (the classic pipeline on the project's
/// fast SIFT features, as bench_realistic --classic-fast).
std::vector<OcclusionRow> evaluateOcclusion(const OcclusionSequence& seq, int sequence_index,
                                            const OcclusionOptions& opt);

struct OcclusionCount {
  int frames = 0;
  int reported = 0;  ///< detection: reported; tracking: a confirmed pose or corners
  int found = 0;     ///< reported within the tolerance
  int wrong = 0;     ///< reported beyond it
};
/// Counts of one outcome (a member of OcclusionRow) over the rows of one cover bin (-1: all).
OcclusionCount countOcclusion(const std::vector<OcclusionRow>& rows, MethodOutcome OcclusionRow::*what, int bin);

/// Markdown: per bin, detection reported / found / wrong (refgrasp 3D, 2D-only, classic) and
/// tracking tracked / lost / wrong (3D and 2D-only; lost: frames without a confirmed report);
/// only the parts `opt` ran.
std::string formatOcclusionTable(const std::vector<OcclusionRow>& rows, const OcclusionOptions& opt = {});

}  // namespace refgrasp::eval
