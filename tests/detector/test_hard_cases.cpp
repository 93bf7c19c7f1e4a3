// Paper matcher vs ratio baseline on the hard cases of Section III-B: small targets, strong motion
// blur, repeated motifs, symmetric patterns, several instances. Each category renders >= 10
// seeded scenes; "found" = the four projected texture corners within 3 px of the truth. The run:
// eval::hardCases (eval/detector_accuracy.h); its table: build/bench/bench_accuracy.
#include <gtest/gtest.h>

#include <vector>

#include "eval/detector_accuracy.h"

namespace refgrasp::eval {
namespace {

TEST(HardCases, PaperMatcherFindsAtLeastAsManyAsRatioBaseline) {
  const std::vector<HardCaseRow> rows = hardCases();
  ASSERT_EQ(rows.size(), 5u);
  HardCaseRow all{"overall"};
  for (const auto& r : rows) {
    all.paper += r.paper;
    all.ratio += r.ratio;
    all.total += r.total;
  }
  for (const auto& r : rows) EXPECT_GE(r.paper, r.ratio) << r.category;
  EXPECT_GT(all.paper, all.ratio);
  EXPECT_EQ(rows.back().category, "3 instances");
  EXPECT_GE(rows.back().paper, rows.back().total * 8 / 10) << "most instances found";
}

}  // namespace
}  // namespace refgrasp::eval
