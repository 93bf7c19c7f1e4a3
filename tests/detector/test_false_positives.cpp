// False positives: the default detector, every shipped target object registered at once, over
// hundreds of seeded clutter frames that do not contain any of them -> zero detections. The run:
// eval::falsePositivesOnClutter (eval/detector_accuracy.h); its figures: build/bench/bench_accuracy.
#include <gtest/gtest.h>

#include <string>

#include "eval/detector_accuracy.h"

using namespace refgrasp;

TEST(FalsePositives, NoDetectionOnClutterWithoutTheTargets) {
  const eval::FalsePositiveRun r = eval::falsePositivesOnClutter(500);
  ASSERT_EQ(r.objects, 5u);
  for (const std::string& f : r.failed) ADD_FAILURE() << f;
  for (const std::string& d : r.false_detections) ADD_FAILURE() << d;
  EXPECT_EQ(r.detections, 0);
}
