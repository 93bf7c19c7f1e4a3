// False positives: the default detector, every shipped target object registered at once, over
// hundreds of seeded clutter frames that do not contain any of them -> zero detections.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "robot/sim/degrade.h"
#include "robot/sim/synthetic_scene.h"
#include "detector/detector.h"

using namespace refgrasp;
using namespace refgrasp::detector;
using namespace refgrasp::testing;

TEST(FalsePositives, NoDetectionOnClutterWithoutTheTargets) {
  const std::vector<std::string>& targets = targetTextures();
  Detector det;
  for (const auto& t : targets) det.addObject(textureObject(t, loadMedia(t), 0.2));
  const Intrinsics cam = sceneCamera();
  const int kFrames = 500;
  int detections = 0, candidates_rejected_by_sanity = 0;
  double total_ms = 0;
  std::mt19937_64 rng(100000);
  sim::Degradation noise;
  noise.noise_sigma = 2.0;  // sensor noise, as in the rendered target scenes
  for (int i = 0; i < kFrames; ++i) {
    cv::Mat img = clutterBackground(100000 + i);
    sim::degrade(img, noise, rng);
    const DetectionResult r = det.detect(img, cam);
    ASSERT_TRUE(r.ok) << r.error;
    total_ms += r.time_ms.total;
    for (const Detection& d : r.detections) {
      if (d.found) {
        ++detections;
        ADD_FAILURE() << "frame " << i << ": false detection of " << targets[d.object] << " ("
                      << d.inliers << " inliers)";
      } else if (d.sanity != SanityStatus::kOk) {
        ++candidates_rejected_by_sanity;
      }
    }
  }
  std::printf("False positives: %d detections over %d clutter frames x %zu objects "
              "(%d matcher candidates rejected by the sanity check), mean %.1f ms/frame\n",
              detections, kFrames, targets.size(), candidates_rejected_by_sanity, total_ms / kFrames);
  EXPECT_EQ(detections, 0);
}
