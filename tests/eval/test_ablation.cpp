// The verification stage's ablation (eval/ablation.h) in small: its first row is the detector
// with the defaults, scored as the realistic-set evaluation scores it; the rows do not depend on
// the number of worker threads; a variant's changed outcomes are counted against the first row.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "eval/ablation.h"
#include "eval/realistic_eval.h"

using namespace refgrasp;
using namespace refgrasp::eval;

namespace {

AblationData smallData() {
  AblationData d;
  d.seeds = {1001};
  d.frames_per_set = 4;
  d.pair_seeds = 0;
  d.clutter_frames = 1;
  return d;
}

}  // namespace

TEST(Ablation, TheFirstRowIsTheDefaultDetectorScoredAsTheSetsAre) {
  cv::setNumThreads(1);
  const std::vector<AblationVariant> all = verificationAblation();
  ASSERT_GE(all.size(), 10u);
  EXPECT_EQ(all[0].name, "all checks");
  // The defaults, and a variant that refuses most instances (a floor of 80 inliers).
  const AblationVariant strict{"strict", "match.min_inliers: 80",
                               [](detector::DetectorOptions* o) { o->match.min_inliers = 80; }};
  const std::vector<AblationVariant> variants = {all[0], strict};
  const AblationData data = smallData();
  const std::vector<AblationCounts> one = runAblation(variants, data, 1);
  const std::vector<AblationCounts> two = runAblation(variants, data, 2);
  ASSERT_EQ(one.size(), 2u);
  ASSERT_EQ(two.size(), 2u);

  // The first row against evaluateSet on the same frames (3D and 2D-only).
  int frames = 0, found = 0, pose_ok = 0, wrong = 0, found_2d = 0, wrong_2d = 0;
  for (const RealisticSetSpec& spec : realisticSets(1001, data.frames_per_set)) {
    const RealisticSet set(spec);
    EvalOptions opt;
    opt.classic_own_sift = false;
    opt.cpu_time = false;
    const Tally t3 = tally(evaluateSet(set, opt, 0, set.frames()));
    opt.two_d = true;
    const Tally t2 = tally(evaluateSet(set, opt, 0, set.frames()));
    frames += t3.n, found += t3.found_r, pose_ok += t3.pose_r, wrong += t3.wrong_r;
    found_2d += t2.found_r, wrong_2d += t2.wrong_r;
  }
  const AblationCounts& base = one[0];
  EXPECT_EQ(base.frames_3d, frames);
  EXPECT_EQ(base.frames_2d, frames);
  EXPECT_EQ(base.found_3d, found);
  EXPECT_EQ(base.pose_ok_3d, pose_ok);
  EXPECT_EQ(base.wrong_3d, wrong);
  EXPECT_EQ(base.found_2d, found_2d);
  EXPECT_EQ(base.wrong_2d, wrong_2d);
  EXPECT_GT(base.found_3d, 0);
  EXPECT_EQ(base.clutter_frames, 1);
  EXPECT_EQ(base.changed, 0);
  EXPECT_EQ(base.moved, 0);

  // Threads change nothing but the times.
  for (size_t v = 0; v < 2; ++v) {
    EXPECT_EQ(one[v].found_3d, two[v].found_3d) << v;
    EXPECT_EQ(one[v].pose_ok_3d, two[v].pose_ok_3d) << v;
    EXPECT_EQ(one[v].wrong_3d, two[v].wrong_3d) << v;
    EXPECT_EQ(one[v].within_3px_2d, two[v].within_3px_2d) << v;
    EXPECT_EQ(one[v].clutter_false, two[v].clutter_false) << v;
    EXPECT_EQ(one[v].changed, two[v].changed) << v;
    EXPECT_EQ(one[v].moved, two[v].moved) << v;
  }
  // The strict variant loses found frames, and each is an outcome changed against the first row.
  EXPECT_LT(one[1].found_3d, base.found_3d);
  EXPECT_GE(one[1].changed, (base.found_3d - one[1].found_3d) + (base.found_2d - one[1].found_2d));
  const std::string table = formatAblation(variants, one);
  EXPECT_NE(table.find("| all checks |"), std::string::npos) << table;
  EXPECT_NE(table.find("`match.min_inliers: 80`"), std::string::npos) << table;
}

TEST(Ablation, NonsenseDataIsRefused) {
  const std::vector<AblationVariant> variants = {verificationAblation()[0]};
  AblationData none;
  none.seeds.clear();
  none.pair_seeds = 0;
  none.clutter_frames = 0;
  EXPECT_THROW(runAblation(variants, none, 1), std::invalid_argument);
  AblationData frames = smallData();
  frames.frames_per_set = 0;
  EXPECT_THROW(runAblation(variants, frames, 1), std::invalid_argument);
  EXPECT_THROW(runAblation(variants, smallData(), 0), std::invalid_argument);
  EXPECT_THROW(runAblation({}, smallData(), 1), std::invalid_argument);
}
