// End-to-end detection on rendered scenes with ground truth by construction: pose accuracy of
// both pose methods, jitter, stereo fusion, several objects, 2D-only objects, input checks.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <string>

#include "common/format.h"
#include "robot/sim/synthetic_scene.h"
#include "detector/detector.h"
#include "detector/homography.h"
#include "eval/detector_accuracy.h"

using namespace refgrasp;
using namespace refgrasp::detector;
using namespace refgrasp::testing;

namespace {

constexpr double kWidth = 0.20;  // target width, metres
constexpr double kDeg = M_PI / 180;

const char* kTexture = "targets/poster_concert.png";
const char* kTexture2 = "targets/cereal_box.png";

double heightOf(const cv::Mat& tex, double width) { return width * tex.rows / tex.cols; }

double cornerError(const std::array<Eigen::Vector2d, 4>& a, const std::array<Eigen::Vector2d, 4>& b) {
  double e = 0;
  for (int i = 0; i < 4; ++i) e = std::max(e, (a[i] - b[i]).norm());
  return e;
}

}  // namespace

// The runs (eval/detector_accuracy.h) and their tables: build/bench/bench_accuracy.
TEST(Detector, PoseAccuracyBothMethods) {
  const eval::PoseAccuracy a = eval::poseAccuracy(48);
  std::string outside;  // the refined poses outside 1 deg / 1 %, for the message of a failure
  for (size_t i = 0; i < a.frames.size(); ++i) {
    const eval::PoseAccuracyFrame& f = a.frames[i];
    if (f.detected_corner_px) {
      EXPECT_LT(*f.detected_corner_px, 3.0) << "pose " << i;
    }
    if (f.refined && (rotationError(*f.refined, f.truth) > kDeg ||
                      translationError(*f.refined, f.truth) > 0.01 * f.truth.t.norm())) {
      outside += formatted("\n  pose %zu at %.2f m, tilt %.1f deg, %d inliers: refined %.2f deg %.2f%%", i,
                           f.truth.t.norm(), f.tilt_deg, f.inliers, rotationError(*f.refined, f.truth) / kDeg,
                           100 * translationError(*f.refined, f.truth) / f.truth.t.norm());
    }
  }
  const PoseMethod def = DetectorOptions{}.pose;
  const eval::PoseErrors& best = def == PoseMethod::kPaper ? a.paper : a.refined;
  const eval::PoseErrors& other = def == PoseMethod::kPaper ? a.refined : a.paper;
  EXPECT_GE(best.rate(), 0.95) << poseMethodName(def) << outside;
  EXPECT_GE(a.detected.rate(), 0.95);
  // The default is the more accurate method: success rate, then median rotation error.
  EXPECT_GE(best.rate(), other.rate());
  EXPECT_LE(eval::quantile(best.rot_deg, 0.5), eval::quantile(other.rot_deg, 0.5));
}

TEST(Detector, JitterAtHalfMetre) {
  std::vector<double> z;
  const std::vector<std::optional<double>> depths = eval::jitterDepths(50);
  for (size_t i = 0; i < depths.size(); ++i) {
    ASSERT_TRUE(depths[i]) << "frame " << i;
    z.push_back(*depths[i]);
  }
  EXPECT_LE(eval::sampleStd(z), 1e-3);
}

TEST(Detector, StereoFusionReducesJitter) {
  const eval::StereoJitter s = eval::stereoJitter(30);
  const Pose& lMo = s.lMo_truth;
  for (const eval::StereoJitterFrame& f : s.frames) {
    ASSERT_TRUE(f.ok) << f.error;
    ASSERT_EQ(f.objects, 1u);
    ASSERT_TRUE(f.fused);
    if (!f.both) continue;
    EXPECT_LT(rotationError(*f.lMo, lMo), 1.0 * kDeg);
    EXPECT_LT(translationError(*f.lMo, lMo), 0.01 * lMo.t.norm());
  }
  const eval::StereoJitter::Summary j = s.summary();
  ASSERT_GE(j.both, 28);
  EXPECT_LE(j.fused_m, std::min(j.left_m, j.right_m));
}

TEST(Detector, TwoObjectsShareOneExtraction) {
  const cv::Mat a = loadMedia(kTexture), b = loadMedia(kTexture2);
  const Intrinsics cam = sceneCamera();
  Detector det;
  const int ia = det.addObject(textureObject("a", a, kWidth));
  const int ib = det.addObject(textureObject("b", b, kWidth));
  for (int seed = 0; seed < 3; ++seed) {
    const Pose pa = Pose::fromRotationVector({0.2, 0.3 - 0.1 * seed, 0.1 * seed}, {-0.13, 0.0, 0.75});
    const Pose pb = Pose::fromRotationVector({-0.2, -0.25, 0.2}, {0.13, 0.02 * seed, 0.8});
    const RenderedScene s = renderTargets(
        cam, {{a, kWidth, heightOf(a, kWidth), pa}, {b, kWidth, heightOf(b, kWidth), pb}},
        SceneSpec{Pose(), 2.0, 0.0, 0.0, static_cast<uint64_t>(300 + seed)});
    const DetectionResult r = det.detect(s.image, cam);
    ASSERT_TRUE(r.ok);
    const std::optional<Detection> da = r.find(ia);
    const std::optional<Detection> db = r.find(ib);
    ASSERT_TRUE(da && db) << "seed " << seed;
    EXPECT_LT(rotationError(*da->cMo, pa), 1.0 * kDeg);
    EXPECT_LT(translationError(*da->cMo, pa), 0.01 * pa.t.norm());
    EXPECT_LT(rotationError(*db->cMo, pb), 1.0 * kDeg);
    EXPECT_LT(translationError(*db->cMo, pb), 0.01 * pb.t.norm());
    EXPECT_GT(r.time_ms.extract, 0);
    EXPECT_EQ(r.detections.size(), 2u);
  }
}

TEST(Detector, TwoInstancesOfOneObject) {
  const cv::Mat a = loadMedia(kTexture);
  const Intrinsics cam = sceneCamera();
  DetectorOptions opt;
  opt.match.max_instances = 3;
  Detector det(opt);
  det.addObject(textureObject("a", a, kWidth));
  const Pose p0 = Pose::fromRotationVector({0.2, 0.3, 0.1}, {-0.12, 0.0, 0.75});
  const Pose p1 = Pose::fromRotationVector({-0.1, -0.25, -0.3}, {0.13, 0.01, 0.8});
  const RenderedScene s = renderTargets(
      cam, {{a, kWidth, heightOf(a, kWidth), p0}, {a, kWidth, heightOf(a, kWidth), p1}},
      SceneSpec{Pose(), 2.0, 0.0, 0.0, 808});
  const DetectionResult r = det.detect(s.image, cam);
  ASSERT_TRUE(r.find(0, 0) && r.find(0, 1));
  EXPECT_FALSE(r.find(0, 2).has_value());  // only two copies in the frame
  // Each true copy is matched by exactly one instance, with an accurate pose.
  for (const Pose& truth : {p0, p1}) {
    int matched = 0;
    for (int k = 0; k < 2; ++k) {
      const Pose est = *r.find(0, k)->cMo;
      if (translationError(est, truth) < 0.01 * truth.t.norm()) {
        ++matched;
        EXPECT_LT(rotationError(est, truth), 1.0 * kDeg);
      }
    }
    EXPECT_EQ(matched, 1);
  }
}

TEST(Detector, TwoDimensionalObjectGivesHomographyOnly) {
  const cv::Mat tex = loadMedia(kTexture);
  const Intrinsics cam = sceneCamera();
  Detector det;
  const int id = det.addObject(makeObjectModel("flat", tex, std::nullopt, std::nullopt));
  SceneSpec spec;
  spec.cMo = Pose::fromRotationVector({0.3, -0.2, 0.4}, {0.0, 0.02, 0.6});
  spec.seed = 9;
  const RenderedScene s = renderTarget(cam, tex, kWidth, heightOf(tex, kWidth), spec);
  const DetectionResult r = det.detect(s.image, cam);
  const std::optional<Detection> d = r.find(id);
  ASSERT_TRUE(d);
  EXPECT_FALSE(d->cMo.has_value());
  EXPECT_LT(cornerError(d->corners, s.corners), 2.0);
  // H maps the reference (texture) pixel-edge corners onto the rendered corners.
  const std::array<Eigen::Vector2d, 4> ref = {Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(tex.cols - 0.5, -0.5),
                                              Eigen::Vector2d(tex.cols - 0.5, tex.rows - 0.5),
                                              Eigen::Vector2d(-0.5, tex.rows - 0.5)};
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d p = d->H * ref[i].homogeneous();
    EXPECT_LT((p.head<2>() / p.z() - s.corners[i]).norm(), 2.0);
  }
}

TEST(Detector, DistortedSceneCamera) {
  const cv::Mat tex = loadMedia(kTexture);
  Intrinsics cam = sceneCamera();
  cam.dist = {-0.25, 0.08, 0.0005, -0.0003, 0.0};
  Detector det;
  det.addObject(textureObject("poster", tex, kWidth));
  for (int i = 0; i < 3; ++i) {
    SceneSpec spec;
    spec.cMo = Pose::fromRotationVector({0.2, 0.1 * i, -0.3}, {0.08 - 0.05 * i, 0.05, 0.55});
    spec.seed = 40 + i;
    const RenderedScene s = renderTarget(cam, tex, kWidth, heightOf(tex, kWidth), spec);
    const DetectionResult r = det.detect(s.image, cam);
    const std::optional<Detection> d = r.find(0);
    ASSERT_TRUE(d && d->cMo) << i;
    EXPECT_LT(rotationError(*d->cMo, spec.cMo), 1.0 * kDeg);
    EXPECT_LT(translationError(*d->cMo, spec.cMo), 0.01 * spec.cMo.t.norm());
    EXPECT_LT(cornerError(d->corners, s.corners), 2.0);
  }
}

TEST(Detector, DistortedSceneKeepsTheDenseRefinementAccuracy) {
  // The Bumblebee2 case: a far, near-frontal target seen through a distorting lens. The dense
  // (ECC) refinement runs on the pattern's neighbourhood resampled to the ideal pinhole grid, so
  // the distorted camera is as accurate as the ideal one; without it (features only) it is not.
  const cv::Mat tex = loadMedia(kTexture);
  Intrinsics ideal = sceneCamera(), distorted = sceneCamera();
  distorted.dist = {-0.25, 0.08, 0.0005, -0.0003, 0.0};
  DetectorOptions no_dense;
  no_dense.dense.enabled = false;
  Detector det, det_features(no_dense);
  det.addObject(textureObject("poster", tex, kWidth));
  det_features.addObject(textureObject("poster", tex, kWidth));
  double worst_ideal = 0, worst_distorted = 0, worst_features = 0;
  for (int i = 0; i < 6; ++i) {
    SceneSpec spec;
    spec.cMo = Pose::fromRotationVector({0.05 * (i % 3), -0.04 * i, 0.3 * i},
                                        {0.15 - 0.06 * i, 0.08 - 0.03 * i, 1.1});
    spec.seed = 70 + i;
    const RenderedScene si = renderTarget(ideal, tex, kWidth, heightOf(tex, kWidth), spec);
    const RenderedScene sd = renderTarget(distorted, tex, kWidth, heightOf(tex, kWidth), spec);
    const DetectionResult ri = det.detect(si.image, ideal), rd = det.detect(sd.image, distorted),
                          rf = det_features.detect(sd.image, distorted);
    const std::optional<Detection> di = ri.find(0), dd = rd.find(0), df = rf.find(0);
    ASSERT_TRUE(di && di->cMo && dd && dd->cMo && df && df->cMo) << i;
    worst_ideal = std::max(worst_ideal, rotationError(*di->cMo, spec.cMo) / kDeg);
    worst_distorted = std::max(worst_distorted, rotationError(*dd->cMo, spec.cMo) / kDeg);
    worst_features = std::max(worst_features, rotationError(*df->cMo, spec.cMo) / kDeg);
    EXPECT_LT(translationError(*dd->cMo, spec.cMo), 0.002 * spec.cMo.t.norm()) << i;
    EXPECT_LT(cornerError(dd->corners, sd.corners), 0.5) << i;
  }
  std::printf("worst rotation error at 1.1 m: ideal camera %.3f deg, distorted %.3f deg, "
              "distorted without dense refinement %.3f deg\n",
              worst_ideal, worst_distorted, worst_features);
  EXPECT_LT(worst_distorted, 0.35);
  EXPECT_LT(worst_distorted, 2.0 * worst_ideal + 0.05);
  EXPECT_LT(worst_distorted, worst_features);
}

TEST(Detector, CroppedReferenceWithRegionPastItsBorder) {
  // The reference photo shows only the middle of the poster (cropped unevenly); its outline, the
  // pattern region, runs past the photo on every side. Features come from the photo, corners and
  // pose from the outline: the full poster's corners and pose are recovered.
  const cv::Mat tex = loadMedia(kTexture);
  const int left = 30, top = 20, right = 10, bottom = 25;
  const cv::Mat crop = tex(cv::Rect(left, top, tex.cols - left - right, tex.rows - top - bottom)).clone();
  const Intrinsics full_cam = textureCamera(tex, kWidth, 0.5);
  const Intrinsics crop_cam = Intrinsics::pinhole(crop.cols, crop.rows, full_cam.fx,
                                                  full_cam.cx - left, full_cam.cy - top);
  const std::vector<Eigen::Vector2d> outline = {
      {-0.5 - left, -0.5 - top}, {tex.cols - 0.5 - left, -0.5 - top},
      {tex.cols - 0.5 - left, tex.rows - 0.5 - top}, {-0.5 - left, tex.rows - 0.5 - top}};
  const ObjectModel cropped = makeObjectModel("cropped", crop, crop_cam,
                                              Pose(Eigen::Matrix3d::Identity(), {0, 0, 0.5}), outline);
  const ObjectModel whole = textureObject("whole", tex, kWidth);
  for (int i = 0; i < 4; ++i)
    EXPECT_LT((cropped.target->corners_o[i] - whole.target->corners_o[i]).norm(), 1e-12) << i;

  const Intrinsics cam = sceneCamera();
  DetectorOptions features_only;
  features_only.dense.enabled = false;
  Detector det, det_features(features_only);
  det.addObject(cropped);
  det_features.addObject(cropped);
  for (int i = 0; i < 4; ++i) {
    SceneSpec spec;
    spec.cMo = Pose::fromRotationVector({0.2 - 0.1 * i, 0.15 * i, 0.3 * i}, {0.05 - 0.03 * i, 0.02, 0.55 + 0.1 * i});
    spec.seed = 90 + i;
    const RenderedScene s = renderTarget(cam, tex, kWidth, heightOf(tex, kWidth), spec);
    for (const Detector* d : {&det, &det_features}) {
      const std::optional<Detection> found = d->detect(s.image, cam).find(0);
      ASSERT_TRUE(found && found->cMo) << "pose " << i;
      EXPECT_LT(rotationError(*found->cMo, s.cMo), 0.5 * kDeg) << i;
      EXPECT_LT(translationError(*found->cMo, s.cMo), 0.005 * s.cMo.t.norm()) << i;
      EXPECT_LT(cornerError(found->corners, s.corners), 1.5) << i;
    }
    // Dense refinement on this reference: the template is the part of the outline inside the
    // photo. From the true H moved by ~1.5 px it converges back.
    std::vector<Eigen::Vector2d> ref_corners(outline.begin(), outline.end()),
        scene_corners(s.corners.begin(), s.corners.end());
    const Eigen::Matrix3d H = fitHomographyLeastSquares(ref_corners, scene_corners);
    Eigen::Matrix3d shift = Eigen::Matrix3d::Identity();
    shift(0, 2) = 1.2;
    shift(1, 2) = -0.9;
    std::array<Eigen::Vector2d, 4> rect;
    std::copy(outline.begin(), outline.end(), rect.begin());
    const DenseRefineResult dr =
        refineHomographyDense(buildReferencePyramid(crop), s.image, shift * H, rect, DenseRefineOptions{});
    ASSERT_TRUE(dr.ok) << i;
    double err = 0;
    for (int k = 0; k < 4; ++k) err = std::max(err, (applyHomography(dr.H, rect[k]) - s.corners[k]).norm());
    EXPECT_LT(err, 0.5) << i;
  }
}

TEST(Detector, InputChecks) {
  const cv::Mat tex = loadMedia(kTexture);
  const Intrinsics cam = sceneCamera();
  Detector det;
  det.addObject(textureObject("poster", tex, kWidth));
  SceneSpec spec;
  spec.cMo = Pose::fromRotationVector({0.1, 0.1, 0}, {0, 0, 0.6});
  spec.seed = 3;
  const RenderedScene s = renderTarget(cam, tex, kWidth, heightOf(tex, kWidth), spec);

  DetectionResult r = det.detect(cv::Mat(), cam);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("empty image"), std::string::npos);
  r = det.detect(cv::Mat(240, 320, CV_8UC1, cv::Scalar(0)), cam);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("320x240 differs from the camera's 640x480"), std::string::npos) << r.error;
  r = det.detect(cv::Mat(480, 640, CV_32FC1, cv::Scalar(0)), cam);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("unsupported pixel type"), std::string::npos);
  Intrinsics broken = cam;
  broken.fx = -1;
  EXPECT_FALSE(det.detect(s.image, broken).ok);
  // Colour input is converted to gray.
  cv::Mat bgr;
  cv::cvtColor(s.image, bgr, cv::COLOR_GRAY2BGR);
  r = det.detect(bgr, cam);
  ASSERT_TRUE(r.ok);
  EXPECT_TRUE(r.find(0).has_value());
  // Bad options are refused at construction.
  DetectorOptions bad;
  bad.sanity.max_distance_m = -1;
  EXPECT_THROW(Detector{bad}, std::invalid_argument);
}
