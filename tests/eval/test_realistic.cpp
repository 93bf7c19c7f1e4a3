// The realistic sets in small: the generator's ground truth, refgrasp vs the classic OpenCV
// pipeline (the full tables: build/bench/bench_realistic), false positives on photo clutter with
// every object registered, and each rule of the verification stage on the frames that show the
// case it exists for (the whole data: bench/bench_ablation, docs/detector.md).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>
#include <opencv2/imgproc.hpp>

#include "detector/detector.h"
#include "detector/homography.h"
#include "eval/classic.h"
#include "eval/realistic_eval.h"
#include "robot/sim/realistic_scene.h"
#include "robot/sim/synthetic_scene.h"

using namespace refgrasp;
using namespace refgrasp::eval;

namespace {

constexpr double kDeg = M_PI / 180;
constexpr uint64_t kHeldOutSeed = 1001;  // the split the tables are measured on, never tuned on

// Frames run with two option sets: the counts of each, and both outcomes per frame.
struct Chunk {
  uint64_t seed;
  const char* set;
  int first, last;  // frames [first, last)
};
struct FramePair {
  std::string where;  // "<set> seed <seed> frame <i>"
  MethodOutcome on, off;
  double size_px = 0;  // the target's size in the frame
};
struct OnOff {
  int frames = 0, found_on = 0, found_off = 0, wrong_on = 0, wrong_off = 0, pose_on = 0, pose_off = 0;
  std::vector<FramePair> pairs;
};
OnOff compareOnChunks(const std::vector<Chunk>& chunks, const EvalOptions& on, const EvalOptions& off) {
  OnOff r;
  for (const Chunk& c : chunks)
    for (const RealisticSetSpec& spec : realisticSets(c.seed, 160)) {
      if (spec.name != c.set) continue;
      const RealisticSet set(spec);
      const std::vector<FrameOutcome> a = evaluateSet(set, on, c.first, c.last);
      const std::vector<FrameOutcome> b = evaluateSet(set, off, c.first, c.last);
      EXPECT_EQ(a.size(), b.size());
      for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
        const MethodOutcome &ra = a[i].refgrasp, &rb = b[i].refgrasp;
        ++r.frames;
        r.found_on += ra.found, r.found_off += rb.found;
        r.wrong_on += ra.reported && !ra.found, r.wrong_off += rb.reported && !rb.found;
        r.pose_on += ra.pose_ok, r.pose_off += rb.pose_ok;
        r.pairs.push_back({spec.name + " seed " + std::to_string(c.seed) + " frame " + std::to_string(a[i].frame), ra, rb, a[i].size_px});
      }
    }
  return r;
}

/// Evaluation without timing and without the classic pipeline's own SIFT (as --classic-fast),
/// matching on the reference's own features only: each verification rule below is shown on the
/// frames where those features fit the case it exists for (a few features several px off, a
/// facade a period off); with the view-synthesised features (MatchOptions::plane_views) a frame
/// whose own candidates were all refused is matched again, and often found right, which is not
/// what these tests are about; so is a weak hypothesis' box extracted again (weak_regions).
EvalOptions quickEvalOptions() {
  EvalOptions o;
  o.classic_own_sift = false;
  o.cpu_time = false;
  o.detector.match.plane_views = false;
  o.detector.match.weak_regions = 0;
  return o;
}

}  // namespace

TEST(RealisticScene, ReferencePhotoGroundTruth) {
  const cv::Mat tex = refgrasp::testing::loadMedia("photos/butterfly_on_leaf.jpg");
  refgrasp::testing::ReferencePhotoSpec spec;
  spec.tilt_rad = 50 * kDeg;
  spec.width_px = 200;
  spec.seed = 3;
  const refgrasp::testing::ReferencePhoto a = refgrasp::testing::photographReference(tex, 0.2, 0.2 * tex.rows / tex.cols, spec);
  const refgrasp::testing::ReferencePhoto b = refgrasp::testing::photographReference(tex, 0.2, 0.2 * tex.rows / tex.cols, spec);
  EXPECT_EQ(cv::norm(a.image, b.image, cv::NORM_INF), 0) << "deterministic";
  // The true corners are the projection of the plane's corners by the photo's camera and pose.
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d X((i == 1 || i == 2 ? 0.1 : -0.1), (i >= 2 ? 0.1 : -0.1) * tex.rows / tex.cols, 0);
    EXPECT_LT((a.camera.project(a.cMo * X) - a.corners_px[i]).norm(), 1e-9) << i;
  }
  // Traced polygon: every corner within 2.5 px of a vertex, 4-8 vertices, oblique as asked.
  EXPECT_GE(a.polygon_px.size(), 4u);
  EXPECT_LE(a.polygon_px.size(), 8u);
  for (const auto& c : a.corners_px) {
    double best = 1e9;
    for (const auto& p : a.polygon_px) best = std::min(best, (p - c).norm());
    EXPECT_LT(best, 2.5);
  }
  const double tilt = std::acos(std::abs(a.cMo.R.col(2).dot(a.cMo.t.normalized())));
  EXPECT_NEAR(tilt, spec.tilt_rad, 1e-9);
  EXPECT_NEAR(a.width_px, 200, 80);  // about as asked (foreshortened by the tilt)
}

// refgrasp and the classic pipeline on the same held-out frames, every set: refgrasp finds at
// least as many, has at least as many poses within 2 deg / 2 %, and reports nothing wrong.
TEST(RealisticSets, RefgraspFindsAtLeastAsManyAsTheClassicPipeline) {
  EvalOptions opt;
  opt.classic_own_sift = false;  // same keypoints as cv::SIFT (test_sift_fast.cpp), 3x cheaper
  opt.cpu_time = false;
  const int kFrames = 20;
  for (const RealisticSetSpec& spec : realisticSets(kHeldOutSeed, kFrames)) {
    const RealisticSet set(spec);
    const std::vector<FrameOutcome> rows = evaluateSet(set, opt, 0, set.frames());
    const Tally t = tally(rows);
    EXPECT_GE(t.found_r, t.found_c) << spec.name;
    EXPECT_GE(t.pose_r, t.pose_c) << spec.name;
    EXPECT_EQ(t.wrong_r, 0) << spec.name;
    EXPECT_GT(t.found_r, kFrames / 5) << spec.name;
  }
}

// Clutter made of real photographs, procedural clutter and siblings of the registered patterns
// (a piece of 6-15 % of a pattern, a logo or a word, on another texture), every object of the
// photos and procedural sets registered at once: no detection. A sibling matches its shared
// piece well; the verification's cell rules refuse it (docs/detector.md).
TEST(RealisticSets, FalsePositivesOnPhotoClutterWithEveryObjectRegistered) {
  std::vector<SetObject> objects;
  for (const RealisticSetSpec& spec : realisticSets(kHeldOutSeed, 1))
    if (spec.name != "far_oblique") {
      const RealisticSet set(spec);
      for (const auto& o : set.objects()) objects.push_back(o);
    }
  const ClutterReport r = evaluateClutter(objects, detector::DetectorOptions{}, 40, kHeldOutSeed, false);
  for (const auto& d : r.details) std::printf("  false detection: %s\n", d.c_str());
  std::printf("photo clutter: %d detections over %d frames x %zu objects\n", r.detections, r.frames, objects.size());
  EXPECT_EQ(r.detections, 0);
}

// Small far patterns (the two farthest distance bins of every set of seed 2001, neither tuned on
// nor reported): the plane-affine map of small instances (MatchOptions::affine_below_px) against
// the full homography on the same frames. Few matches on a 30-60 px pattern leave the
// homography's perspective poorly determined; the affine map of the rectified reference plane
// reports no more wrong corners and finds and poses at least as many. Its corners are the closer
// where both find the pattern when the features' fits are compared alone, that is without the
// wide alignments (VerifyOptions::realign_*), which replace a fit the dense refinement refuses
// by ECC's alignment and so correct many of the homographies the affine map avoids.
TEST(RealisticSets, SmallPatternsGetThePlaneAffineMap) {
  constexpr uint64_t kSeed = 2001;
  struct Counts {
    int found = 0, wrong = 0, pose = 0;
  };
  // Affine vs homography with the given trusted wide alignment; the corners where both find it.
  auto compare = [&](double trusted, Counts* a_out, Counts* h_out, std::vector<double>* corner_a,
                     std::vector<double>* corner_h) {
    EvalOptions affine, homography;
    for (EvalOptions* o : {&affine, &homography}) {
      o->classic_own_sift = false;
      o->cpu_time = false;
      o->min_distance_bin = 3;
      o->detector.verify.realign_trusted_correlation = trusted;
      if (trusted >= 1) o->detector.verify.realign_verified_correlation = 1.01;  // the features' fits alone
    }
    EXPECT_GT(affine.detector.match.affine_below_px, 0);  // the default
    homography.detector.match.affine_below_px = 0;
    int changed = 0;
    for (const RealisticSetSpec& spec : realisticSets(kSeed, 100)) {
      const RealisticSet set(spec);
      const std::vector<FrameOutcome> a = evaluateSet(set, affine, 0, set.frames());
      const std::vector<FrameOutcome> h = evaluateSet(set, homography, 0, set.frames());
      EXPECT_EQ(a.size(), h.size());
      for (size_t i = 0; i < std::min(a.size(), h.size()); ++i) {
        const MethodOutcome &ra = a[i].refgrasp, &rh = h[i].refgrasp;
        a_out->found += ra.found, h_out->found += rh.found;
        a_out->wrong += ra.reported && !ra.found, h_out->wrong += rh.reported && !rh.found;
        a_out->pose += ra.pose_ok, h_out->pose += rh.pose_ok;
        changed += ra.reported != rh.reported || ra.corner_px != rh.corner_px;
        if (ra.found && rh.found) {
          corner_a->push_back(ra.corner_px);
          corner_h->push_back(rh.corner_px);
        }
      }
    }
    return changed;
  };
  auto median = [](std::vector<double> v) {
    if (v.empty()) return std::nan("");
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  // The default detector: the affine map finds and poses at least as many, no more wrong.
  Counts a, h;
  std::vector<double> corner_a, corner_h;
  const int changed = compare(EvalOptions().detector.verify.realign_trusted_correlation, &a, &h, &corner_a, &corner_h);
  // The features' fits alone: the affine map's corners are the closer.
  Counts fa, fh;
  std::vector<double> fit_a, fit_h;
  compare(1.0, &fa, &fh, &fit_a, &fit_h);
  ASSERT_FALSE(fit_a.empty());
  std::printf("far bins, seed %llu: plane-affine found %d, pose ok %d, wrong %d, corner median %.2f px; "
              "homography found %d, pose ok %d, wrong %d, corner median %.2f px (%zu found by both); %d frames "
              "changed; features' fits alone: corner median %.2f vs %.2f px (%zu found by both)\n",
              static_cast<unsigned long long>(kSeed), a.found, a.pose, a.wrong, median(corner_a), h.found, h.pose,
              h.wrong, median(corner_h), corner_a.size(), changed, median(fit_a), median(fit_h), fit_a.size());
  EXPECT_GT(changed, 0);
  EXPECT_LE(a.wrong, h.wrong);
  EXPECT_GE(a.found, h.found);
  EXPECT_GE(a.pose, h.pose);
  EXPECT_LE(fa.wrong, fh.wrong);
  EXPECT_GE(fa.found, fh.found);
  EXPECT_GE(fa.pose, fh.pose);
  EXPECT_LE(median(fit_a), median(fit_h));
}

// The photometric re-alignment (VerifyOptions::realign) on frames where a facade's windows,
// matched one period off, give a stretched homography (corners 9-28 px off) that passes every
// other check: with it each is found instead, and nothing found without it is lost. Most are
// the photometric alignment matched again (a better-supported, better-correlating consensus);
// seed 11 photos/15 is the period re-match (VerifyOptions::period_rematch: the alignment one
// window period away has the more significant consensus).
TEST(RealisticSets, RealignmentTakesTheFacadeMatchedAPeriodOffBack) {
  const std::vector<Chunk> chunks = {{3, "far_oblique", 5, 7},   {3, "far_oblique", 51, 52}, {5, "photos", 117, 118},
                                     {5, "photos", 151, 152},    {5, "far_oblique", 144, 145}, {9, "far_oblique", 74, 83},
                                     {11, "photos", 15, 16}};
  EvalOptions on = quickEvalOptions(), off = quickEvalOptions();
  ASSERT_TRUE(on.detector.verify.realign);  // the default
  // The periodic cell rule (periodic_min_strong_cells) refuses two of these facades on its own,
  // so it is off in both arms; the defaults are checked below.
  on.detector.verify.periodic_min_strong_cells = on.detector.verify.min_strong_cells;
  off = on;
  off.detector.verify.realign = false;
  const OnOff r = compareOnChunks(chunks, on, off);
  const OnOff d = compareOnChunks(chunks, quickEvalOptions(), on);
  EXPECT_EQ(d.wrong_on, 0);  // the defaults
  EXPECT_GE(d.found_on, r.found_on);
  for (const FramePair& p : r.pairs)
    EXPECT_TRUE(p.on.found || !p.off.found) << p.where << ": found without the re-alignment, lost with it";
  std::printf("%d frames: re-alignment found %d, pose ok %d, wrong %d; without it found %d, pose ok %d, "
              "wrong %d\n", r.frames, r.found_on, r.pose_on, r.wrong_on, r.found_off, r.pose_off, r.wrong_off);
  EXPECT_EQ(r.frames, 16);
  EXPECT_GE(r.wrong_off, 8);  // the data still shows the failure
  EXPECT_EQ(r.wrong_on, 0);
  EXPECT_GE(r.found_on, r.found_off + 8);
  EXPECT_GE(r.pose_on, r.pose_off + 5);
}

// The dense refinement's retry on locally normalised intensities (DenseRefineOptions::
// normalize_sigma_px) on frames whose references were photographed under other light, where the
// raw ECC alignment converges off (or fails) and the refined pose misses 2 deg. One chunk of
// consecutive frames and three single ones; seed 3 far_oblique/44 is one the retry loses (the
// other planar pose of a small oblique facade), kept in on purpose.
TEST(RealisticSets, TheNormalisedRetryGivesMorePosesWithinTwoDegrees) {
  const std::vector<Chunk> chunks = {{9, "photos", 19, 30}, {1, "procedural", 80, 81}, {3, "procedural", 63, 64},
                                     {3, "far_oblique", 44, 45}};
  EvalOptions on = quickEvalOptions(), off = quickEvalOptions();
  ASSERT_GT(on.detector.dense.normalize_sigma_px, 0);  // the default
  off.detector.dense.normalize_sigma_px = 0;
  const OnOff r = compareOnChunks(chunks, on, off);
  for (const FramePair& p : r.pairs) EXPECT_EQ(p.on.found, p.off.found) << p.where;
  std::printf("%d frames: with the retry found %d, pose ok %d, wrong %d; raw only found %d, pose ok %d, "
              "wrong %d\n", r.frames, r.found_on, r.pose_on, r.wrong_on, r.found_off, r.pose_off, r.wrong_off);
  EXPECT_EQ(r.frames, 14);
  EXPECT_EQ(r.wrong_on, r.wrong_off);
  EXPECT_GE(r.pose_on, r.pose_off + 4);
}

// The trusted wide alignment (VerifyOptions::realign_trusted_correlation) on frames showing
// small oblique targets whose few features fit a homography several pixels off, which the dense
// refinement refuses to move that far. Re-run with room to move, ECC converges within a pixel at
// correlation >= 0.9 and becomes the instance's alignment. Seed 21 far_oblique/21 is a magazine
// the features put 11 px off (a wrong report) that the wide alignment puts 2 px off.
TEST(RealisticSets, ATrustedWideAlignmentCorrectsFewFeatureFits) {
  const std::vector<Chunk> chunks = {{21, "far_oblique", 21, 22}, {9, "far_oblique", 66, 67}, {1, "far_oblique", 116, 117},
                                     {13, "far_oblique", 140, 141}, {19, "far_oblique", 126, 127}, {11, "far_oblique", 4, 5}};
  EvalOptions on = quickEvalOptions(), off = quickEvalOptions();
  ASSERT_LT(on.detector.verify.realign_trusted_correlation, 1);  // the default
  off.detector.verify.realign_trusted_correlation = 1;
  off.detector.verify.realign_verified_correlation = 1.01;
  const OnOff r = compareOnChunks(chunks, on, off);
  double corner_on = 0, corner_off = 0;
  for (const FramePair& p : r.pairs) {
    EXPECT_TRUE(p.on.reported && p.off.reported) << p.where;
    EXPECT_LT(p.on.corner_px, p.off.corner_px) << p.where;
    EXPECT_LT(p.on.corner_px, 2.0) << p.where;
    corner_on += p.on.corner_px / r.pairs.size();
    corner_off += p.off.corner_px / r.pairs.size();
  }
  std::printf("%d frames: trusted wide alignment found %d, pose ok %d, wrong %d, mean corner %.2f px; "
              "features' alignment found %d, pose ok %d, wrong %d, mean corner %.2f px\n", r.frames, r.found_on, r.pose_on,
              r.wrong_on, corner_on, r.found_off, r.pose_off, r.wrong_off, corner_off);
  EXPECT_EQ(r.frames, 6);
  EXPECT_EQ(r.wrong_off, 1);  // the magazine, 11 px off
  EXPECT_EQ(r.wrong_on, 0);
  EXPECT_GE(r.pose_on, r.pose_off + 2);
}

// The verified wide alignment (VerifyOptions::realign_verified_*) on frames showing far targets
// whose few features fit a homography 7-26 px off (wrong reports), which the dense
// refinement refuses to move that far and whose wide alignment converges at an ECC correlation
// below the trusted 0.9 (0.77-0.89), but whose warped reference then verifies at 0.86-0.98,
// 0.09-0.54 better than at the features' homography: the wide alignment is taken and puts the
// corners within 3.5 px. Two 3D objects (seed 37 procedural/76, seed 45 far_oblique/45) and five
// 2D-only ones.
TEST(RealisticSets, AWideAlignmentThatVerifiesClearlyBetterCorrectsFewFeatureFits) {
  const std::vector<Chunk> chunks3d = {{37, "procedural", 76, 77}, {45, "far_oblique", 45, 46}};
  const std::vector<Chunk> chunks2d = {{19, "photos", 114, 115}, {21, "procedural", 57, 58}, {21, "procedural", 93, 94},
                                       {21, "procedural", 114, 115}, {3, "procedural", 143, 144}};
  EvalOptions on = quickEvalOptions(), off = quickEvalOptions();
  ASSERT_LE(on.detector.verify.realign_verified_correlation, 1);  // the default: on
  off.detector.verify.realign_verified_correlation = 1.01;
  OnOff r = compareOnChunks(chunks3d, on, off);
  on.two_d = off.two_d = true;
  const OnOff r2 = compareOnChunks(chunks2d, on, off);
  r.frames += r2.frames, r.found_on += r2.found_on, r.found_off += r2.found_off;
  r.wrong_on += r2.wrong_on, r.wrong_off += r2.wrong_off;
  r.pairs.insert(r.pairs.end(), r2.pairs.begin(), r2.pairs.end());
  for (const FramePair& p : r.pairs) {
    EXPECT_TRUE(p.on.reported && p.off.reported) << p.where;
    EXPECT_TRUE(p.on.found) << p.where;
    EXPECT_FALSE(p.off.found) << p.where << ": no longer a wrong report without the rule";
    EXPECT_LT(p.on.corner_px, 3.5) << p.where;
    std::printf("  %s: corner %.2f px (features' fit %.2f px)\n", p.where.c_str(), p.on.corner_px, p.off.corner_px);
  }
  std::printf("%d frames: verified wide alignment found %d, wrong %d; features' fit found %d, wrong %d\n",
              r.frames, r.found_on, r.wrong_on, r.found_off, r.wrong_off);
  EXPECT_EQ(r.frames, 7);
  EXPECT_EQ(r.wrong_off, 7);
  EXPECT_EQ(r.wrong_on, 0);
}

// ... but not on a reference with repeat periods. Seed 1001 2D photos/22 is a hotel facade whose
// features fit one window period off, which the checks refuse; without the exclusion the rule
// takes the wide alignment there (photometrically as good, a period off) and reports it 21.5 px
// off.
TEST(RealisticSets, AVerifiedWideAlignmentIsNotTakenOnARepeatedMotif) {
  EvalOptions on = quickEvalOptions(), off = quickEvalOptions();
  on.two_d = off.two_d = true;
  off.detector.verify.realign_verified_correlation = 1.01;
  const OnOff r = compareOnChunks({{1001, "photos", 22, 23}}, on, off);
  ASSERT_EQ(r.pairs.size(), 1u);
  EXPECT_FALSE(r.pairs[0].off.reported) << r.pairs[0].where;
  EXPECT_FALSE(r.pairs[0].on.reported) << r.pairs[0].where << ": corner " << r.pairs[0].on.corner_px << " px";
}

// A reference with repeat periods needs 4 strong cells, not 3 (VerifyOptions::
// periodic_min_strong_cells): frames where a facade's lattice is matched wrongly (seed 43
// photos/137, 20 px off; seed 5 far_oblique/75 2D-only, 110 px off) with 3 cells agreeing by
// chance are refused, and right facade reports near the bar (4 or 5 strong cells: seed 45
// photos/12, 2D-only seeds 1 photos/22, 9 photos/66, 11 photos/32) stay found.
TEST(RealisticSets, ARepeatedMotifNeedsMoreCellsToAgree) {
  EvalOptions on = quickEvalOptions(), off = quickEvalOptions();
  ASSERT_EQ(on.detector.verify.periodic_min_strong_cells, 4);  // the default
  off.detector.verify.periodic_min_strong_cells = off.detector.verify.min_strong_cells;
  OnOff wrong = compareOnChunks({{43, "photos", 137, 138}}, on, off);
  OnOff right = compareOnChunks({{45, "photos", 12, 13}}, on, off);
  on.two_d = off.two_d = true;
  const OnOff wrong2 = compareOnChunks({{5, "far_oblique", 75, 76}}, on, off);
  const OnOff right2 = compareOnChunks({{1, "photos", 22, 23}, {9, "photos", 66, 67}, {11, "photos", 32, 33}}, on, off);
  wrong.pairs.insert(wrong.pairs.end(), wrong2.pairs.begin(), wrong2.pairs.end());
  right.pairs.insert(right.pairs.end(), right2.pairs.begin(), right2.pairs.end());
  ASSERT_EQ(wrong.pairs.size(), 2u);
  ASSERT_EQ(right.pairs.size(), 4u);
  for (const FramePair& p : wrong.pairs) {
    EXPECT_TRUE(p.off.reported && !p.off.found) << p.where << ": no longer a wrong report without the rule";
    EXPECT_FALSE(p.on.reported) << p.where << ": corner " << p.on.corner_px << " px";
  }
  for (const FramePair& p : right.pairs) {
    EXPECT_TRUE(p.off.found) << p.where;
    EXPECT_TRUE(p.on.found) << p.where << ": lost with the rule";
  }
}

// The spare candidate (VerifyOptions::spare_candidate) on frames where the matcher's first
// candidate fails the checks (a facade consensus the pose check refuses, a magazine whose first
// consensus fails the sanity check) and the next one is the object: found with it, missed
// without.
TEST(RealisticSets, ASpareCandidateIsCheckedWhenTheFirstFails) {
  const std::vector<Chunk> chunks = {{5, "far_oblique", 121, 122}, {19, "photos", 76, 77}};
  EvalOptions on = quickEvalOptions(), off = quickEvalOptions();
  ASSERT_TRUE(on.detector.verify.spare_candidate);  // the default
  off.detector.verify.spare_candidate = false;
  const OnOff r = compareOnChunks(chunks, on, off);
  for (const FramePair& p : r.pairs) {
    EXPECT_TRUE(p.on.found) << p.where;
    EXPECT_FALSE(p.off.reported) << p.where;
  }
  std::printf("%d frames: with the spare candidate found %d, wrong %d; without it found %d, wrong %d\n",
              r.frames, r.found_on, r.wrong_on, r.found_off, r.wrong_off);
  EXPECT_EQ(r.frames, 2);
  EXPECT_EQ(r.wrong_on, 0);
}

// The repeat-period ambiguity test (VerifyOptions::period_ambiguity_*) on frames showing a
// facade whose features agree one window period off (reported 10-13 px off, wrong) while the
// alignment one period away agrees strongly everywhere: that alignment replaces it. Seed 11
// photos/15 is a right report that the same test moves to the better alignment (it stays
// right); seed 9 far_oblique/51 is a right report it refuses (the alignment a period away
// correlates better, 8 strong cells of 9, but is 15 px off), kept in on purpose.
TEST(RealisticSets, ARepeatPeriodAwayThatAgreesBetterReplacesOrRefusesAFacade) {
  const std::vector<Chunk> chunks = {{13, "far_oblique", 82, 83}, {19, "far_oblique", 82, 83},
                                     {11, "photos", 15, 16}, {9, "far_oblique", 51, 52}};
  EvalOptions on = quickEvalOptions(), off = quickEvalOptions();
  ASSERT_LE(on.detector.verify.period_ambiguity_cells, 9);  // the default: on
  off.detector.verify.period_ambiguity_cells = 10;
  const OnOff r = compareOnChunks(chunks, on, off);
  ASSERT_EQ(r.pairs.size(), 4u);
  for (int i = 0; i < 2; ++i) {
    EXPECT_TRUE(r.pairs[i].off.reported && !r.pairs[i].off.found) << r.pairs[i].where << ": no longer wrong without the test";
    EXPECT_TRUE(r.pairs[i].on.found) << r.pairs[i].where;
    EXPECT_LT(r.pairs[i].on.corner_px, 2.0) << r.pairs[i].where;
  }
  EXPECT_TRUE(r.pairs[2].on.found && r.pairs[2].off.found) << r.pairs[2].where;
  EXPECT_FALSE(r.pairs[3].on.reported) << r.pairs[3].where;
  EXPECT_TRUE(r.pairs[3].off.found) << r.pairs[3].where;
  std::printf("%d frames: with the period test found %d, pose ok %d, wrong %d; without it found %d, "
              "pose ok %d, wrong %d\n", r.frames, r.found_on, r.pose_on, r.wrong_on, r.found_off, r.pose_off, r.wrong_off);
  EXPECT_EQ(r.wrong_off, 2);
  EXPECT_EQ(r.wrong_on, 0);
  EXPECT_EQ(r.found_on, 3);
}

// Runs the chunks with a check on and off and expects it to refuse exactly one wrong report:
// pair `wrong` (of `frames`) is reported but wrong without it and not reported with it; every
// other frame has the same found and pose-ok both ways.
static OnOff refusesOnlyTheWrongOne(const std::vector<Chunk>& chunks, const EvalOptions& on, const EvalOptions& off,
                                    size_t frames, size_t wrong, const char* check) {
  const OnOff r = compareOnChunks(chunks, on, off);
  EXPECT_EQ(r.pairs.size(), frames);
  if (wrong >= r.pairs.size()) {
    ADD_FAILURE() << "no frame " << wrong;
    return r;
  }
  const FramePair& w = r.pairs[wrong];
  EXPECT_TRUE(w.off.reported && !w.off.found) << w.where << ": no longer wrong without " << check;
  EXPECT_FALSE(w.on.reported) << w.where;
  for (size_t i = 0; i < r.pairs.size(); ++i) {
    if (i == wrong) continue;
    EXPECT_EQ(r.pairs[i].on.found, r.pairs[i].off.found) << r.pairs[i].where;
    EXPECT_EQ(r.pairs[i].on.pose_ok, r.pairs[i].off.pose_ok) << r.pairs[i].where;
  }
  EXPECT_EQ(r.wrong_off, 1);
  EXPECT_EQ(r.wrong_on, 0);
  return r;
}

// A few features beside the truth (VerifyOptions::realign_verified_*): seed 19 photos/47 is fruits
// whose 9 features fit a homography 11 px off that passes every other check (verify correlation
// 0.71, 7 strong cells); the wide alignment from there converges on the truth (0.89, 9 strong
// cells) and verifies clearly better, so it is taken. Without the rule the instance is reported
// off; the frames around it and a run of small far_oblique targets are right reports the rule
// leaves as they are.
TEST(RealisticSets, AFitBesideTheTruthIsCorrectedByTheVerifiedWideAlignment) {
  const std::vector<Chunk> chunks = {{19, "photos", 40, 48}, {21, "far_oblique", 16, 24}};
  EvalOptions on = quickEvalOptions(), off = quickEvalOptions();
  ASSERT_LE(on.detector.verify.realign_verified_correlation, 1);  // the default: on
  off.detector.verify.realign_verified_correlation = 1.01;
  const OnOff r = compareOnChunks(chunks, on, off);
  ASSERT_EQ(r.pairs.size(), 16u);
  const FramePair& fruits = r.pairs[7];
  EXPECT_TRUE(fruits.on.found) << fruits.where;
  EXPECT_LT(fruits.on.corner_px, 1.0) << fruits.where;
  EXPECT_TRUE(fruits.off.reported && !fruits.off.found) << fruits.where << ": no longer wrong without the rule";
  EXPECT_GT(fruits.off.corner_px, 8.0) << fruits.where;
  for (size_t i = 0; i < r.pairs.size(); ++i) {
    if (i == 7) continue;
    EXPECT_EQ(r.pairs[i].on.found, r.pairs[i].off.found) << r.pairs[i].where;
    EXPECT_EQ(r.pairs[i].on.pose_ok, r.pairs[i].off.pose_ok) << r.pairs[i].where;
  }
  EXPECT_EQ(r.wrong_on, 0);
  EXPECT_GE(r.found_on, 8);
}

// The feature pose's reprojection bound (VerifyOptions::max_feature_pose_rms_px): seed 19
// photos/56 is a hotel facade whose 16 matches span two windows; the dense alignment is refused
// (31 px away), the pose fitted to the features reprojects them at 2.1 px RMS and the instance,
// 47 px off, passes every other check. Refused with the bound. The other frames are right
// reports whose feature poses reproject them at 1.36-1.49 px, kept.
TEST(RealisticSets, AFeaturePoseThatReprojectsPoorlyIsRefused) {
  const std::vector<Chunk> chunks = {{19, "photos", 56, 57}, {11, "photos", 97, 98}, {13, "photos", 125, 126},
                                     {11, "far_oblique", 15, 16}};
  EvalOptions on = quickEvalOptions(), off = quickEvalOptions();
  ASSERT_LT(on.detector.verify.max_feature_pose_rms_px, 1000);  // the default: on
  off.detector.verify.max_feature_pose_rms_px = 1000;
  const OnOff r = refusesOnlyTheWrongOne(chunks, on, off, 4, 0, "the bound");
  for (size_t i = 1; i < r.pairs.size(); ++i) EXPECT_TRUE(r.pairs[i].on.found) << r.pairs[i].where;
  std::printf("%d frames: with the bound found %d, wrong %d; without it found %d, wrong %d\n", r.frames,
              r.found_on, r.wrong_on, r.found_off, r.wrong_off);
  EXPECT_EQ(r.found_on, 3);
}

// Objects registered 2D-only (no reference pose: H and corners, EvalOptions::two_d) get what the
// 3D ones get: the dense alignment of the whole pattern gives the corners when it converges, and
// the re-alignment, repeat-period and photometric-peak checks run on them. Compared with the
// features' corners alone and none of those checks, on frames around three wrong reports that
// the checks remove; the fourth, far_oblique/20 (a facade 46 px off, its dense alignment
// refused), stays wrong both ways. The exact counts pin this data: a change elsewhere that moves
// them calls for a look at these frames, not a looser bound.
TEST(RealisticSets, TwoDOnlyObjectsGetTheDenseAlignmentAndTheChecks) {
  const std::vector<Chunk> chunks = {{1, "photos", 118, 130}, {1, "procedural", 84, 92}, {1, "far_oblique", 0, 24}};
  EvalOptions on = quickEvalOptions(), off = quickEvalOptions();
  on.two_d = off.two_d = true;
  off.detector.dense.enabled = false;  // the 2D path before: feature H, no realignment
  off.detector.verify.realign = false;
  const OnOff r = compareOnChunks(chunks, on, off);
  std::vector<double> e_on, e_off;
  int within3_on = 0, within3_off = 0;
  for (const FramePair& p : r.pairs) {
    EXPECT_FALSE(p.on.has_pose) << p.where;
    if (p.on.found && p.off.found) e_on.push_back(p.on.corner_px), e_off.push_back(p.off.corner_px);
    within3_on += p.on.found && p.on.corner_px <= 3, within3_off += p.off.found && p.off.corner_px <= 3;
  }
  ASSERT_GT(e_on.size(), 10u);
  std::nth_element(e_on.begin(), e_on.begin() + e_on.size() / 2, e_on.end());
  std::nth_element(e_off.begin(), e_off.begin() + e_off.size() / 2, e_off.end());
  const double med_on = e_on[e_on.size() / 2], med_off = e_off[e_off.size() / 2];
  std::printf("%d frames, 2D-only: with the dense alignment found %d, wrong %d, within 3 px %d, median "
              "corner error %.2f px; without found %d, wrong %d, within 3 px %d, median %.2f px\n", r.frames, r.found_on,
              r.wrong_on, within3_on, med_on, r.found_off, r.wrong_off, within3_off, med_off);
  EXPECT_EQ(r.frames, 44);
  EXPECT_EQ(r.wrong_on, 1);
  EXPECT_EQ(r.wrong_off, 4);
  EXPECT_GE(r.found_on, r.found_off);
  EXPECT_GT(within3_on, within3_off);
  EXPECT_LT(med_on, 0.8 * med_off);
}

// DenseRefineOptions::max_2d_coarsening: a 2D-only target much larger than the dense template
// (max_template_px caps it, so the alignment runs on a coarser pyramid level than the scene
// shows) keeps the homography of its many features; smaller ones take the dense alignment's.
// Frames of seed 1 with targets of 160 px and more: the median corner error with the rule is
// below that of the dense alignment everywhere (and no frame is found or lost).
TEST(RealisticSets, ALarge2DTargetKeepsItsFeatureHomography) {
  const std::vector<Chunk> chunks = {{1, "photos", 20, 60}, {1, "procedural", 140, 160}};
  EvalOptions on = quickEvalOptions(), off = quickEvalOptions();
  on.two_d = off.two_d = true;
  off.detector.dense.max_2d_coarsening = 1e9;
  const OnOff r = compareOnChunks(chunks, on, off);
  std::vector<double> e_on, e_off;
  for (const FramePair& p : r.pairs) {
    EXPECT_EQ(p.on.found, p.off.found) << p.where;
    if (p.size_px >= 160 && p.on.found && p.off.found) e_on.push_back(p.on.corner_px), e_off.push_back(p.off.corner_px);
  }
  ASSERT_GE(e_on.size(), 6u);
  std::nth_element(e_on.begin(), e_on.begin() + e_on.size() / 2, e_on.end());
  std::nth_element(e_off.begin(), e_off.begin() + e_off.size() / 2, e_off.end());
  std::printf("%zu large 2D targets: median worst-corner error %.2f px with the rule, %.2f px with the dense "
              "alignment always\n", e_on.size(), e_on[e_on.size() / 2], e_off[e_off.size() / 2]);
  EXPECT_LT(e_on[e_on.size() / 2], 0.8 * e_off[e_off.size() / 2]);
}

namespace {

// A range stage on far faces that the detector without it does not report: with it each face
// is found with its pose within 2 deg and 2 % of the distance and its corners within 2.5 px, every
// face smaller than max_size_px. Then photo clutter (6 frames) with every object of the photos and
// procedural sets registered yields no detection with the stage on.
void expectFoundOnlyWith(const char* stage, const std::vector<Chunk>& chunks, const EvalOptions& on,
                         const EvalOptions& off, double max_size_px) {
  const OnOff r = compareOnChunks(chunks, on, off);
  for (const FramePair& p : r.pairs) {
    std::printf("%s (%.0f px): %s corner %.2f px, rotation %.2f deg; without: reported %d\n", p.where.c_str(),
                p.size_px, stage, p.on.corner_px, p.on.rot_deg, p.off.reported);
    EXPECT_TRUE(p.on.found && p.on.pose_ok) << p.where;
    EXPECT_LT(p.on.corner_px, 2.5) << p.where;
    EXPECT_FALSE(p.off.reported) << p.where;
    EXPECT_LT(p.size_px, max_size_px) << p.where;
  }
  EXPECT_EQ(r.frames, static_cast<int>(chunks.size()));
  EXPECT_EQ(r.pose_on, r.frames);
  EXPECT_EQ(r.wrong_on, 0);

  std::vector<SetObject> objects;
  for (const RealisticSetSpec& spec : realisticSets(1, 1))
    if (spec.name != "far_oblique") {
      const RealisticSet set(spec);
      for (const auto& o : set.objects()) objects.push_back(o);
    }
  const ClutterReport c = evaluateClutter(objects, on.detector, 6, 1, false);
  for (const auto& d : c.details) std::printf("  false detection: %s\n", d.c_str());
  EXPECT_EQ(c.frames, 6);
  EXPECT_EQ(c.detections, 0);
}

}  // namespace

// View-synthesised reference features (MatchOptions::plane_views) on far faces (1.8-2.8 m, 31-38
// px, 18-56 deg oblique; seed 1) that the reference's own features miss; clutter with the views'
// extra features in every index.
TEST(RealisticSets, ViewSynthesisedFeaturesFindFarObliqueFaces) {
  const std::vector<Chunk> chunks = {{1, "far_oblique", 28, 29}, {1, "far_oblique", 59, 60}, {1, "procedural", 19, 20},
                                     {1, "procedural", 49, 50},  {1, "procedural", 79, 80},  {1, "photos", 9, 10}};
  EvalOptions on = quickEvalOptions(), off = quickEvalOptions();
  ASSERT_TRUE(EvalOptions{}.detector.match.plane_views);  // the default
  on.detector.match.plane_views = true;
  expectFoundOnlyWith("views", chunks, on, off, 40);
}

// Weak evidence looked at again (MatchOptions::weak_regions) on far faces (2.0-2.7 m, 33-51 px,
// 21-51 deg oblique; seed 1) that neither the own nor the view-synthesised features find at the
// frame's contrast threshold: a hypothesis with a few local matches points at each, and its box
// extracted again at the lower threshold gives the features; clutter with the weak boxes looked at
// again.
TEST(RealisticSets, WeakRegionsLookedAtAgainFindSmallFaces) {
  const std::vector<Chunk> chunks = {{1, "photos", 88, 89}, {1, "procedural", 9, 10}, {1, "photos", 113, 114},
                                     {1, "far_oblique", 24, 25}, {1, "far_oblique", 39, 40}};
  EvalOptions on = quickEvalOptions(), off = quickEvalOptions();
  ASSERT_EQ(EvalOptions{}.detector.match.weak_regions, 2);  // the default
  on.detector.match.plane_views = off.detector.match.plane_views = true;
  on.detector.match.weak_regions = 2;
  expectFoundOnlyWith("weak regions", chunks, on, off, 55);

  // The detector's account of it (ObjectStats, control.jsonl's detector.weak_regions): the first
  // frame found by a box looked at again, the boxes counted, at most as many as asked for.
  for (const RealisticSetSpec& spec : realisticSets(1, 160)) {
    if (spec.name != "photos") continue;
    const RealisticSet set(spec);
    const SetFrame f = set.frame(88);
    for (const int n : {0, 1, 2}) {
      detector::DetectorOptions opt;
      opt.match.weak_regions = n;
      detector::Detector det(opt);
      det.addObject(set.objects()[static_cast<size_t>(f.object)].model);
      const detector::DetectionResult d = det.detect(f.image, f.camera);
      ASSERT_TRUE(d.ok) << d.error;
      ASSERT_EQ(d.stats.size(), 1u);
      EXPECT_EQ(d.find(0).has_value(), n > 0) << n;
      EXPECT_TRUE(d.stats[0].views_matched) << n;
      EXPECT_EQ(d.stats[0].weak_regions, n == 0 ? 0 : 1) << n << ": found in the strongest box";
    }
  }
}

// A candidate from the second pass (view-synthesised features, a weak region looked at again) is
// reported only where the dense alignment places it, for 2D-only objects and for references with
// repeat periods (VerifyOptions::second_pass_needs_dense). 2D-only: 9-16 synthesised features on
// a 29-42 px face fit corners 6-11 px off while the warped reference still correlates 0.56-0.88
// at the verification's coarse resolution; frames (seeds 19, 5, 9, 21) where such a fit was
// reported with the rule off; with it each is refused, or (seed 21 photos/24) found right by the
// weak region looked at next. Registered with their reference pose (3D), the same frames are found
// right (corners 0.7-2.1 px off) with the rule on or off: a 3D object's feature pose has its own
// checks. The hotel facade (3D, seeds 9 and 11): second-pass poses 7-20 px off that pass those
// checks, refused with the rule.
TEST(RealisticSets, ASecondPassCandidateIsReportedOnlyWhereTheDenseAlignmentPlacesIt) {
  const std::vector<Chunk> flat_wrong = {{19, "photos", 9, 10}, {5, "photos", 99, 100}, {9, "procedural", 24, 25},
                                         {21, "photos", 24, 25}};
  const std::vector<Chunk> facades = {{9, "far_oblique", 151, 152}, {11, "photos", 93, 94}, {9, "far_oblique", 137, 138}};
  ASSERT_TRUE(EvalOptions{}.detector.verify.second_pass_needs_dense);  // the default
  for (const int pass : {0, 1, 2}) {  // 2D-only, 3D on the same frames, 3D facades
    EvalOptions on = quickEvalOptions(), off = quickEvalOptions();
    on.two_d = off.two_d = pass == 0;
    on.detector.match.plane_views = off.detector.match.plane_views = true;
    on.detector.match.weak_regions = off.detector.match.weak_regions = EvalOptions{}.detector.match.weak_regions;
    off.detector.verify.second_pass_needs_dense = false;
    const std::vector<Chunk>& chunks = pass == 2 ? facades : flat_wrong;
    const OnOff r = compareOnChunks(chunks, on, off);
    ASSERT_EQ(r.frames, static_cast<int>(chunks.size()));
    for (const FramePair& p : r.pairs) {
      std::printf("%s%s (%.0f px): without the rule reported %d, corner %.2f px; with it reported %d, corner %.2f px\n",
                  p.where.c_str(), pass == 0 ? " 2D-only" : " 3D", p.size_px, p.off.reported, p.off.corner_px,
                  p.on.reported, p.on.corner_px);
      if (pass == 1) {
        EXPECT_TRUE(p.on.found) << p.where;
        EXPECT_EQ(p.on.corner_px, p.off.corner_px) << p.where;
      } else {
        EXPECT_TRUE(p.off.reported && !p.off.found) << p.where << ": no longer wrong without the rule";
        EXPECT_TRUE(!p.on.reported || p.on.found) << p.where;
      }
    }
    EXPECT_EQ(r.wrong_on, 0);
    if (pass == 0) EXPECT_EQ(r.found_on, 1);
  }
}
