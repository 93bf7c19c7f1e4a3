// The detector facade's contract: find() returns a copy, frame stamps come back, the matcher's
// statistics and the reason for a miss reach the result, a query (ROI, pose prior) restricts the
// search, and failures inside OpenCV give ok = false with a one-line error.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <type_traits>
#include <utility>

#include "robot/sim/synthetic_scene.h"
#include "detector/detector.h"
#include "detector/homography.h"

using namespace refgrasp;
using namespace refgrasp::detector;
using namespace refgrasp::testing;

namespace {

constexpr double kWidth = 0.20;
constexpr double kDeg = M_PI / 180;
const char* kTexture = "targets/poster_concert.png";

// find() hands out a value: calling it on a temporary result cannot dangle.
static_assert(std::is_same_v<decltype(std::declval<DetectionResult>().find(0)), std::optional<Detection>>);
static_assert(std::is_same_v<decltype(std::declval<const DetectionResult&>().find(0, 1)),
                             std::optional<Detection>>);

struct Scene {
  cv::Mat texture;
  RenderedScene s;
};

const Scene& poster() {
  static const Scene scene = [] {
    Scene sc;
    sc.texture = loadMedia(kTexture);
    SceneSpec spec;
    spec.cMo = Pose::fromRotationVector({0.25, -0.3, 0.1}, {0.08, -0.03, 0.7});
    spec.seed = 606;
    sc.s = renderTarget(sceneCamera(), sc.texture, kWidth, kWidth * sc.texture.rows / sc.texture.cols, spec);
    return sc;
  }();
  return scene;
}

Detector posterDetector(DetectorOptions opt = {}) {
  Detector det(opt);
  det.addObject(textureObject("poster", poster().texture, kWidth));
  return det;
}

bool contains(const cv::Rect& r, const std::array<Eigen::Vector2d, 4>& corners) {
  for (const auto& c : corners)
    if (c.x() < r.x || c.y() < r.y || c.x() > r.x + r.width || c.y() > r.y + r.height) return false;
  return true;
}

}  // namespace

TEST(DetectorFacade, FindOnATemporaryResultIsACopy) {
  const Detector det = posterDetector();
  const cv::Mat& img = poster().s.image;
  const std::optional<Detection> d = det.detect(img, sceneCamera()).find(0);  // result is gone
  ASSERT_TRUE(d && d->cMo);
  EXPECT_LT(translationError(*d->cMo, poster().s.cMo), 0.01 * poster().s.cMo.t.norm());
  EXPECT_LT(rotationError(*d->cMo, poster().s.cMo), 1.0 * kDeg);
  // The same values as the detection kept in a result (deterministic detector).
  const DetectionResult r = det.detect(img, sceneCamera());
  ASSERT_EQ(r.detections.size(), 1u);
  EXPECT_EQ(d->inliers, r.detections[0].inliers);
  EXPECT_EQ((d->H - r.detections[0].H).norm(), 0.0);
  EXPECT_FALSE(r.find(0, 1).has_value());
  EXPECT_FALSE(r.find(3).has_value());
}

TEST(DetectorFacade, FrameStampGoesInAndComesBack) {
  const Detector det = posterDetector();
  const cv::Mat& img = poster().s.image;
  const FrameStamp frame{12.375, 4242};
  const DetectionResult r = det.detect(img, sceneCamera(), frame);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.frame.stamp, 12.375);
  EXPECT_EQ(r.frame.index, 4242);
  EXPECT_EQ(det.detect(img, sceneCamera()).frame.index, -1);  // default: unknown
  // Also on a frame that cannot be used, and for both eyes of a stereo pair.
  const DetectionResult bad = det.detect(cv::Mat(), sceneCamera(), frame);
  EXPECT_FALSE(bad.ok);
  EXPECT_EQ(bad.frame.index, 4242);
  StereoRig rig;
  rig.left = rig.right = sceneCamera();
  rig.lMr = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.12, 0, 0));
  const StereoDetectionResult s = det.detectStereo(img, img, rig, {3.5, 7});
  ASSERT_TRUE(s.ok) << s.error;
  EXPECT_EQ(s.frame.stamp, 3.5);
  EXPECT_EQ(s.frame.index, 7);
  EXPECT_EQ(s.left.frame.index, 7);
  EXPECT_EQ(s.right.frame.index, 7);
}

TEST(DetectorFacade, MatcherStatisticsAndTheReasonForAMiss) {
  const cv::Mat& img = poster().s.image;
  const Intrinsics cam = sceneCamera();
  const Detector det = posterDetector();
  const DetectionResult r = det.detect(img, cam);
  ASSERT_TRUE(r.find(0));
  ASSERT_EQ(r.stats.size(), 1u);
  const ObjectStats& st = r.stats[0];
  EXPECT_EQ(st.object, 0);
  EXPECT_EQ(st.roi, cv::Rect(0, 0, 640, 480));
  EXPECT_EQ(st.scene_features, r.scene_features);
  EXPECT_GT(st.scene_features, 500);
  EXPECT_GE(st.global_matches, 20);
  EXPECT_LE(st.global_matches, st.scene_features);
  EXPECT_GE(st.hypotheses_evaluated, 1);
  EXPECT_LE(st.hypotheses_evaluated, det.options().match.max_hypotheses);
  EXPECT_EQ(st.candidates, 1);
  EXPECT_EQ(st.miss, MissReason::kNone);

  // A featureless frame: nothing to match.
  DetectionResult miss = det.detect(cv::Mat(480, 640, CV_8UC1, cv::Scalar(90)), cam);
  ASSERT_TRUE(miss.ok);
  EXPECT_LT(miss.stats[0].scene_features, 4);
  EXPECT_EQ(miss.stats[0].miss, MissReason::kTooFewFeatures);
  // Clutter without the target: global matches by chance at most, every hypothesis rejected.
  miss = det.detect(clutterBackground(4242), cam);
  ASSERT_TRUE(miss.ok);
  EXPECT_FALSE(miss.find(0));
  EXPECT_GT(miss.stats[0].scene_features, 500);
  EXPECT_EQ(miss.stats[0].candidates, 0);
  EXPECT_NE(miss.stats[0].miss, MissReason::kNone);
  EXPECT_NE(miss.stats[0].miss, MissReason::kTooFewFeatures);
  std::printf("clutter: %d global matches, %d hypotheses, miss: %s\n", miss.stats[0].global_matches,
              miss.stats[0].hypotheses_evaluated, missReasonName(miss.stats[0].miss));

  // The target present, each acceptance rule made impossible in turn: the rule is named.
  DetectorOptions opt;
  opt.match.min_inliers = 100000;
  DetectionResult m = posterDetector(opt).detect(img, cam);
  EXPECT_FALSE(m.find(0));
  EXPECT_GE(m.stats[0].global_matches, 20);
  EXPECT_GT(m.stats[0].rejected.too_few_inliers, 0);
  EXPECT_EQ(m.stats[0].miss, MissReason::kTooFewInliers);
  opt = {};
  opt.match.min_inlier_spread = 0.99;
  m = posterDetector(opt).detect(img, cam);
  EXPECT_FALSE(m.find(0));
  EXPECT_GT(m.stats[0].rejected.narrow_inlier_spread, 0);
  EXPECT_EQ(m.stats[0].miss, MissReason::kNarrowInlierSpread);
  opt = {};
  opt.sanity.max_distance_m = 0.5;  // the target is 0.71 m away
  m = posterDetector(opt).detect(img, cam);
  EXPECT_FALSE(m.find(0));
  // Nothing accepted from the own features: the second pass on the view-synthesised features
  // ran and found the same instance, refused the same way; the counts add both passes.
  EXPECT_TRUE(m.stats[0].views_matched);
  EXPECT_EQ(m.stats[0].candidates, 2);
  EXPECT_EQ(m.stats[0].miss, MissReason::kSanity);
  EXPECT_EQ(m.stats[0].sanity, SanityStatus::kTooFar);
  EXPECT_EQ(m.detections[0].sanity, SanityStatus::kTooFar);
  opt.match.plane_views = false;
  m = posterDetector(opt).detect(img, cam);
  EXPECT_FALSE(m.stats[0].views_matched);
  EXPECT_EQ(m.stats[0].candidates, 1);
  EXPECT_EQ(m.stats[0].miss, MissReason::kSanity);
  // Found by the own features: no second pass, no weak region looked at again.
  EXPECT_FALSE(posterDetector().detect(img, cam).stats[0].views_matched);
  EXPECT_EQ(posterDetector().detect(img, cam).stats[0].weak_regions, 0);
}

TEST(DetectorFacade, PosePriorRestrictsTheSearch) {
  const cv::Mat& img = poster().s.image;
  const Pose& truth = poster().s.cMo;
  const Intrinsics cam = sceneCamera();
  const Detector det = posterDetector();
  const DetectionResult whole = det.detect(img, cam);
  ASSERT_TRUE(whole.find(0));

  // A prediction 2 cm and 3 degrees off (a tracker's last pose after a short loss).
  DetectionQuery q;
  ObjectPrior p;
  p.object = 0;
  p.cMo = Pose::fromRotationVector(truth.rotationVector() + Eigen::Vector3d(0.03, -0.04, 0.02),
                                   truth.t + Eigen::Vector3d(0.015, -0.01, 0.01));
  q.priors = {p};
  const DetectionResult r = det.detect(img, cam, {}, q);
  ASSERT_TRUE(r.ok) << r.error;
  const std::optional<Detection> d = r.find(0);
  ASSERT_TRUE(d && d->cMo);
  EXPECT_LT(translationError(*d->cMo, truth), 0.01 * truth.t.norm());
  EXPECT_LT(rotationError(*d->cMo, truth), 1.0 * kDeg);
  const ObjectStats& st = r.stats[0];
  EXPECT_TRUE(contains(st.roi, poster().s.corners)) << st.roi;
  EXPECT_LT(st.roi.area(), 0.5 * 640 * 480) << st.roi;
  EXPECT_GT(st.min_keypoint_px, 0);
  EXPECT_LT(st.max_keypoint_px, 200);
  std::printf("prior: %d scene features in %dx%d px (whole image: %d), keypoints %.1f-%.1f px, "
              "extraction %.1f ms (whole image %.1f ms)\n",
              r.scene_features, st.roi.width, st.roi.height, whole.scene_features,
              st.min_keypoint_px, st.max_keypoint_px, r.time_ms.extract, whole.time_ms.extract);
  EXPECT_LT(r.scene_features, whole.scene_features / 2);
  EXPECT_EQ(r.scene_features, st.scene_features);

  // An explicit region elsewhere (the left third of the frame holds no part of the target).
  q.priors[0].roi = cv::Rect(0, 0, 200, 480);
  ASSERT_LT(poster().s.corners[0].x(), 640);
  for (const auto& c : poster().s.corners) ASSERT_GT(c.x(), 220);
  DetectionResult elsewhere = det.detect(img, cam, {}, q);
  ASSERT_TRUE(elsewhere.ok);
  EXPECT_FALSE(elsewhere.find(0));
  EXPECT_EQ(elsewhere.stats[0].roi, cv::Rect(0, 0, 200, 480));
  EXPECT_NE(elsewhere.stats[0].miss, MissReason::kNone);
  // The same through the query-wide ROI, without a prior.
  DetectionQuery left;
  left.roi = cv::Rect(0, 0, 200, 480);
  EXPECT_FALSE(det.detect(img, cam, {}, left).find(0));
  // A prediction entirely outside the image: nothing is extracted.
  q.priors[0].roi = {};
  q.priors[0].cMo = Pose(truth.R, truth.t + Eigen::Vector3d(2.0, 0, 0));
  elsewhere = det.detect(img, cam, {}, q);
  ASSERT_TRUE(elsewhere.ok);
  EXPECT_EQ(elsewhere.scene_features, 0);
  EXPECT_EQ(elsewhere.stats[0].roi.area(), 0);
  EXPECT_EQ(elsewhere.stats[0].miss, MissReason::kTooFewFeatures);
}

TEST(DetectorFacade, QueryWithSeveralObjects) {
  const cv::Mat& img = poster().s.image;
  const Intrinsics cam = sceneCamera();
  Detector det = posterDetector();
  det.addObject(textureObject("cereal", loadMedia("targets/cereal_box.png"), kWidth));
  // Only the object with a prior is searched; the other is reported as not searched.
  DetectionQuery q;
  q.only_priors = true;
  ObjectPrior p;
  p.object = 0;
  p.cMo = poster().s.cMo;
  q.priors = {p};
  DetectionResult r = det.detect(img, cam, {}, q);
  ASSERT_TRUE(r.ok) << r.error;
  ASSERT_EQ(r.stats.size(), 2u);
  EXPECT_TRUE(r.find(0));
  EXPECT_EQ(r.stats[1].miss, MissReason::kNotSearched);
  EXPECT_EQ(r.stats[1].scene_features, 0);
  // Without only_priors the other object is searched in the whole image (its own extraction).
  q.only_priors = false;
  r = det.detect(img, cam, {}, q);
  EXPECT_TRUE(r.find(0));
  EXPECT_EQ(r.stats[1].roi, cv::Rect(0, 0, 640, 480));
  EXPECT_EQ(r.scene_features, r.stats[0].scene_features + r.stats[1].scene_features);
  EXPECT_NE(r.stats[1].miss, MissReason::kNone);
  // Bad queries are frame errors, not exceptions.
  struct Bad {
    DetectionQuery q;
    std::string error;
  };
  std::vector<Bad> bad(7);
  bad[0].q.priors = {p, p};
  bad[0].error = "query.priors[1].object: a second prior for object 0";
  bad[1].q.priors = {p};
  bad[1].q.priors[0].object = 5;
  bad[1].error = "query.priors[0].object: no object 5 (2 registered)";
  bad[2].q.priors = {p};
  bad[2].q.priors[0].scale_margin = 0.5;
  bad[2].error = "query.priors[0].scale_margin: must be >= 1";
  bad[3].q.priors = {p};
  bad[3].q.priors[0].cMo->t.x() = std::nan("");
  bad[3].error = "query.priors[0].cMo: must be finite";
  bad[4].q.roi = cv::Rect(10, 10, 0, 5);
  bad[4].error = "query.roi: empty rectangle";
  bad[5].q.priors = {p};
  bad[5].q.priors[0].H = Eigen::Matrix3d::Zero();
  bad[5].error = "query.priors[0].H: must be finite and invertible";
  bad[6].q.priors = {p};
  bad[6].q.priors[0].max_scale = -1;
  bad[6].error = "query.priors[0].max_scale: must be >= 0";
  for (const Bad& b : bad) {
    const DetectionResult e = det.detect(img, cam, {}, b.q);
    EXPECT_FALSE(e.ok);
    EXPECT_EQ(e.error, b.error);
    EXPECT_TRUE(e.detections.empty());
  }
}

// A prior at 1280x720 (f 1100 px) where the poster, 0.5 m away, is seen larger than its 400 px
// reference: with ObjectPrior::max_scale 0.4 the region is extracted downsampled and the dense
// alignment restores the full-resolution result, for a pose prior (3D) and an H prior (2D-only).
TEST(DetectorFacade, PriorRegionAt1280x720IsDownsampledAndPrecise) {
  const Intrinsics cam = Intrinsics::pinhole(1280, 720, 1100, 639.5, 359.5);
  const cv::Mat& tex = poster().texture;
  SceneSpec spec;
  spec.cMo = Pose::fromRotationVector({0.2, -0.25, 0.1}, {0.03, -0.02, 0.5});
  spec.seed = 607;
  const RenderedScene sc = renderTarget(cam, tex, kWidth, kWidth * tex.rows / tex.cols, spec);
  // A prediction 1 cm and 3 degrees off (a tracker's last pose after a short loss).
  const Pose predicted = Pose::fromRotationVector(spec.cMo.rotationVector() + Eigen::Vector3d(0.03, -0.04, 0.02),
                                                  spec.cMo.t + Eigen::Vector3d(0.01, -0.005, 0.005));
  auto cornerError = [&](const Detection& d) {
    double e = 0;
    for (int i = 0; i < 4; ++i) e = std::max(e, (d.corners[i] - sc.corners[i]).norm());
    return e;
  };
  const Detector det3 = posterDetector();
  DetectionQuery q;
  q.only_priors = true;
  ObjectPrior p;
  p.object = 0;
  p.cMo = predicted;
  p.roi_margin = 0.5;  // servo::TargetTrackerOptions' re-detection margins
  p.scale_margin = 2;
  p.max_scale = 0.4;
  q.priors = {p};
  const DetectionResult r3 = det3.detect(sc.image, cam, {}, q);
  ASSERT_TRUE(r3.ok) << r3.error;
  const std::optional<Detection> d3 = r3.find(0);
  ASSERT_TRUE(d3 && d3->cMo);
  EXPECT_GT(r3.stats[0].downsample, 2.0);  // the poster spans ~440 px: 1.1 reference px per px
  EXPECT_LT(cornerError(*d3), 0.15);
  EXPECT_LT(rotationError(*d3->cMo, spec.cMo), 0.05 * kDeg);
  EXPECT_LT(translationError(*d3->cMo, spec.cMo), 0.0005 * spec.cMo.t.norm());

  // 2D-only: the prior is the homography the predicted pose gives.
  Detector det2;
  const ObjectModel flat = makeObjectModel("poster", tex, std::nullopt, std::nullopt);
  det2.addObject(flat);
  const ObjectModel model3d = textureObject("poster", tex, kWidth);
  std::vector<Eigen::Vector2d> ref, img;
  for (int i = 0; i < 4; ++i) {
    ref.push_back(flat.corners_px[i]);
    img.push_back(cam.project(predicted * model3d.target->corners_o[i]));
  }
  p.cMo.reset();
  p.H = fitHomographyLeastSquares(ref, img);
  q.priors = {p};
  const DetectionResult r2 = det2.detect(sc.image, cam, {}, q);
  ASSERT_TRUE(r2.ok) << r2.error;
  const std::optional<Detection> d2 = r2.find(0);
  ASSERT_TRUE(d2);
  EXPECT_GT(r2.stats[0].downsample, 2.0);
  EXPECT_LT(cornerError(*d2), 0.3);
  EXPECT_TRUE(contains(r2.stats[0].roi, sc.corners)) << r2.stats[0].roi;
  std::printf("1280x720 prior: downsample %.2f (3D) %.2f (2D-only), corner error %.3f / %.3f px, rotation %.4f deg\n",
              r3.stats[0].downsample, r2.stats[0].downsample, cornerError(*d3), cornerError(*d2),
              rotationError(*d3->cMo, spec.cMo) / kDeg);
}

namespace {

// The standard OpenCV allocator, refusing any single allocation above `limit` bytes by throwing
// cv::Exception (as OpenCV does when malloc fails) or std::bad_alloc.
class RefusingAllocator : public cv::MatAllocator {
 public:
  RefusingAllocator(size_t limit, bool opencv_error) : limit_(limit), opencv_(opencv_error) {}
  cv::UMatData* allocate(int dims, const int* sizes, int type, void* data, size_t* step,
                         cv::AccessFlag flags, cv::UMatUsageFlags usage) const override {
    size_t total = CV_ELEM_SIZE(type);
    for (int i = 0; i < dims; ++i) total *= static_cast<size_t>(sizes[i]);
    if (!data && total > limit_) {
      ++refused;
      if (opencv_) CV_Error(cv::Error::StsNoMem, "refused " + std::to_string(total) + " bytes");
      throw std::bad_alloc();
    }
    return std_->allocate(dims, sizes, type, data, step, flags, usage);
  }
  bool allocate(cv::UMatData* u, cv::AccessFlag flags, cv::UMatUsageFlags usage) const override {
    return std_->allocate(u, flags, usage);
  }
  void deallocate(cv::UMatData* u) const override { std_->deallocate(u); }
  mutable int refused = 0;

 private:
  const cv::MatAllocator* std_ = cv::Mat::getStdAllocator();
  size_t limit_;
  bool opencv_;
};

}  // namespace

TEST(DetectorFacade, FailureInsideOpenCvGivesOkFalseAndOneLine) {
  // cv::SIFT allocates its scale space as cv::Mat, which the allocator below can refuse (the fast
  // SIFT keeps its own workspaces).
  DetectorOptions opt;
  opt.sift.implementation = SiftImplementation::kOpenCV;
  const Detector det = posterDetector(opt);
  const cv::Mat& img = poster().s.image;
  const Intrinsics cam = sceneCamera();
  for (bool opencv_error : {true, false}) {
    // SIFT's 2x up-sampled float image (1280 x 960 x 4 bytes) is refused; the 640 x 480 input is not.
    RefusingAllocator refuse(3 << 20, opencv_error);
    cv::MatAllocator* const previous = cv::Mat::getDefaultAllocator();
    cv::Mat::setDefaultAllocator(&refuse);
    DetectionResult r;
    EXPECT_NO_THROW(r = det.detect(img, cam, {1.0, 9}));
    cv::Mat::setDefaultAllocator(previous);
    EXPECT_GT(refuse.refused, 0);
    std::printf("%s\n", r.error.c_str());
    EXPECT_FALSE(r.ok);
    EXPECT_EQ(r.error.find('\n'), std::string::npos) << r.error;
    EXPECT_EQ(r.error.rfind("detection failed: ", 0), 0u) << r.error;
    EXPECT_NE(r.error.find(opencv_error ? "refused" : "out of memory"), std::string::npos) << r.error;
    EXPECT_TRUE(r.detections.empty());
    EXPECT_EQ(r.frame.index, 9);
    // The detector is intact: the next frame is detected.
    EXPECT_TRUE(det.detect(img, cam).find(0));
  }
}
