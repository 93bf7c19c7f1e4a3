// Several-view objects: a box defined by five faces (multiview_box.h), detected and posed in
// its own frame from every side, its faces' poses fused (detector/multiview.h).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <random>

#include "common/temp_dir.h"
#include "core/error.h"
#include "detector/detector.h"
#include "detector/multiview.h"
#include "detector/object.h"
#include "multiview_box.h"

using namespace refgrasp;
using namespace refgrasp::detector;
using namespace refgrasp::testing;

namespace {

constexpr double kDeg = M_PI / 180;

// The tolerance of a found pose: 2 cm + 2 % of the distance, 3 degrees.
bool poseWithin(const Pose& est, const Pose& truth) {
  return translationError(est, truth) <= 0.02 + 0.02 * truth.t.norm() && rotationError(est, truth) <= 3 * kDeg;
}

// A face of the box at cMo "shows" when it is defined, wholly in the image, seen within 70 deg
// of its normal and covers at least 48 x 48 px.
bool faceShows(const sim::TexturedPlane& face_in_camera, const Intrinsics& cam) {
  const Pose& cMp = face_in_camera.cMp;
  const Eigen::Vector3d n = cMp.R.col(2);  // into the box; the texture is seen from -z
  const Eigen::Vector3d to_face = cMp.t.normalized();
  if (!(n.dot(to_face) > std::cos(70 * kDeg))) return false;
  const auto c = sim::projectPlaneCorners(cam, face_in_camera);
  double area = 0;
  for (int i = 0; i < 4; ++i) {
    if (c[i].x() < 0 || c[i].y() < 0 || c[i].x() > cam.width - 1 || c[i].y() > cam.height - 1) return false;
    area += c[i].x() * c[(i + 1) % 4].y() - c[(i + 1) % 4].x() * c[i].y();
  }
  return std::abs(area) / 2 >= 48 * 48;
}

class MultiView : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    box_ = new TestBox;
    dir_ = new std::filesystem::path(tempDir("refgrasp_test_multiview"));
    path_ = new std::string(box_->writeDefinitions(*dir_));
  }
  static void TearDownTestSuite() {
    std::filesystem::remove_all(*dir_);
    delete box_;
    delete dir_;
    delete path_;
  }
  // The defined faces that show at cMo.
  static std::vector<std::string> shown(const Pose& cMo, const Intrinsics& cam) {
    std::vector<std::string> out;
    const auto planes = box_->placed(cMo);
    for (const auto& [i, name] : box_->defined)
      if (faceShows(planes[static_cast<size_t>(i)], cam)) out.push_back(name);
    return out;
  }
  static TestBox* box_;
  static std::filesystem::path* dir_;
  static std::string* path_;
};
TestBox* MultiView::box_ = nullptr;
std::filesystem::path* MultiView::dir_ = nullptr;
std::string* MultiView::path_ = nullptr;

TEST_F(MultiView, TheObjectHasOneIdAndItsViewsStayInside) {
  Detector det;
  const int a = det.addObject(loadObjectDefinition(*path_));
  const int b = det.addObject(loadObjectDefinition((*dir_ / "box_front.yaml").string()));
  EXPECT_EQ(a, 0);
  EXPECT_EQ(b, 1);
  EXPECT_EQ(det.objectCount(), 2);
  EXPECT_TRUE(det.object(a).isMultiView());
  EXPECT_EQ(det.object(a).views.size(), 5u);
  const Intrinsics cam = sceneCamera();
  const Pose cMo = lookAtBox(20 * kDeg, 15 * kDeg, 0.8);
  const DetectionResult r = det.detect(renderScene(cam, box_->placed(cMo), 7), cam);
  ASSERT_TRUE(r.ok) << r.error;
  ASSERT_EQ(r.stats.size(), 2u);
  ASSERT_EQ(r.detections.size(), 2u);
  EXPECT_EQ(r.stats[0].object, 0);
  EXPECT_EQ(r.stats[1].object, 1);
  const auto box = r.find(a);
  ASSERT_TRUE(box);
  EXPECT_EQ(box->view, "front");
  EXPECT_EQ(box->views.front(), "front");
  EXPECT_TRUE(poseWithin(*box->cMo, cMo)) << translationError(*box->cMo, cMo) << " m " << rotationError(*box->cMo, cMo) / kDeg << " deg";
  // The front face alone: its pose is the front face's frame, not the box's.
  // One extraction for the frame, shared by the five views and the other object.
  Detector alone;
  alone.addObject(loadObjectDefinition((*dir_ / "box_front.yaml").string()));
  EXPECT_EQ(r.scene_features, alone.detect(renderScene(cam, box_->placed(cMo), 7), cam).scene_features);
  const auto front = r.find(b);
  ASSERT_TRUE(front);
  EXPECT_TRUE(front->views.empty());
  EXPECT_TRUE(poseWithin(*front->cMo, cMo * box_->faces[4].cMp));
}

// From all around (azimuth 0-360 deg, elevation 0-40 deg, 0.5-2 m): found and posed in the
// box's frame in >= 90 % of the views that show a defined face.
TEST_F(MultiView, ABoxIsFoundAndPosedFromEverySideThatShowsAFace) {
  const int samples = std::getenv("REFGRASP_MULTIVIEW_SAMPLES") ? std::atoi(std::getenv("REFGRASP_MULTIVIEW_SAMPLES")) : 48;
  Detector det;
  const int id = det.addObject(loadObjectDefinition(*path_));
  const Intrinsics cam = sceneCamera();
  std::mt19937_64 rng(3601);
  std::uniform_real_distribution<double> azimuth(0, 2 * M_PI), elevation(0, 40 * kDeg), distance(0.5, 2.0);
  std::map<int, std::array<int, 2>> by_distance;  // half-metre bin -> {showing, found}
  int showing = 0, found = 0, joint = 0;
  std::vector<double> t_err, r_err;
  for (int i = 0; i < samples; ++i) {
    const double a = azimuth(rng), e = elevation(rng), d = distance(rng);
    const Pose cMo = lookAtBox(a, e, d);
    if (shown(cMo, cam).empty()) continue;
    ++showing;
    const DetectionResult r = det.detect(renderScene(cam, box_->placed(cMo), 100 + i), cam);
    ASSERT_TRUE(r.ok) << r.error;
    const auto det0 = r.find(id);
    const bool ok = det0 && det0->cMo && poseWithin(*det0->cMo, cMo);
    auto& bin = by_distance[static_cast<int>(d / 0.5)];
    ++bin[0];
    if (ok) {
      ++found;
      ++bin[1];
      joint += det0->views.size() >= 2;
      t_err.push_back(translationError(*det0->cMo, cMo) / d);
      r_err.push_back(rotationError(*det0->cMo, cMo) / kDeg);
    } else {
      std::printf("missed: azimuth %.0f deg, elevation %.0f deg, %.2f m, shows %zu faces", a / kDeg, e / kDeg, d,
                  shown(cMo, cam).size());
      if (det0)
        std::printf(" (view %s of %zu, pose off by %.3f m, %.1f deg)", det0->view.c_str(), det0->views.size(),
                    translationError(*det0->cMo, cMo), rotationError(*det0->cMo, cMo) / kDeg);
      std::printf("\n");
    }
  }
  for (const auto& [bin, n] : by_distance)
    std::printf("%.1f-%.1f m: %d/%d found\n", bin * 0.5, bin * 0.5 + 0.5, n[1], n[0]);
  std::sort(t_err.begin(), t_err.end());
  std::sort(r_err.begin(), r_err.end());
  if (!t_err.empty())
    std::printf("found %d/%d (%d joint); median error %.2f %% of distance, %.2f deg; max %.2f %%, %.2f deg\n", found,
                showing, joint, 100 * t_err[t_err.size() / 2], r_err[r_err.size() / 2], 100 * t_err.back(), r_err.back());
  ASSERT_GE(showing, samples / 2);
  EXPECT_GE(found, 0.9 * showing);
  EXPECT_GT(joint, 0);  // some views showed two faces and were fused
}

}  // namespace

namespace {

// A pose's error in the object frame, (metres, degrees).
std::pair<double, double> poseError(const Pose& est, const Pose& truth) {
  return {translationError(est, truth), rotationError(est, truth) / kDeg};
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? NAN : v[v.size() / 2];
}

// A box turned 180 degrees from its defined front: found by its back and sides.
TEST_F(MultiView, ABoxTurnedAwayIsFoundByItsBackOrSides) {
  Detector det;
  const int id = det.addObject(loadObjectDefinition(*path_));
  const Intrinsics cam = sceneCamera();
  int frames = 0, found = 0;
  for (double a = 140; a <= 220; a += 20) {
    for (double e : {10.0, 30.0}) {
      const Pose cMo = lookAtBox(a * kDeg, e * kDeg, 1.0);
      ++frames;
      const DetectionResult r = det.detect(renderScene(cam, box_->placed(cMo), 500 + frames), cam);
      ASSERT_TRUE(r.ok) << r.error;
      const auto d = r.find(id);
      if (!d) continue;
      EXPECT_EQ(std::count(d->views.begin(), d->views.end(), "front"), 0) << a << " deg";
      EXPECT_TRUE(poseWithin(*d->cMo, cMo)) << a << " deg: " << poseError(*d->cMo, cMo).first << " m, "
                                            << poseError(*d->cMo, cMo).second << " deg";
      found += poseWithin(*d->cMo, cMo);
    }
  }
  std::printf("turned away: %d of %d found and posed\n", found, frames);
  EXPECT_GE(found, frames - 1);
}

// Where two faces show, the joint pose is about as accurate as the better of the two faces'
// own poses (which one is better is known only from the truth).
TEST_F(MultiView, TheJointPoseIsAsAccurateAsTheBestSingleFace) {
  Detector fused, single;
  const int box = fused.addObject(loadObjectDefinition(*path_));
  const ObjectModel model = fused.object(box);
  for (const ObjectView& v : model.views) single.addObject(*v.model);
  const Intrinsics cam = sceneCamera();
  std::vector<double> joint_t, joint_r, best_t, best_r;
  int frame = 0;
  for (double a : {35.0, 55.0, 125.0, 145.0, 215.0, 235.0, 305.0, 325.0}) {
    for (double d : {0.7, 1.2}) {
      const Pose cMo = lookAtBox(a * kDeg, 15 * kDeg, d);
      const cv::Mat img = renderScene(cam, box_->placed(cMo), 700 + ++frame);
      const auto j = fused.detect(img, cam).find(box);
      if (!j || j->views.size() < 2) continue;
      const DetectionResult s = single.detect(img, cam);
      double bt = 1e9, br = 1e9;
      for (const std::string& name : j->views) {
        const int k = static_cast<int>(std::find_if(model.views.begin(), model.views.end(),
                                                    [&](const ObjectView& v) { return v.name == name; }) -
                                       model.views.begin());
        const auto f = s.find(k);
        ASSERT_TRUE(f) << name;  // the same view, found on the same features
        const auto [t, r] = poseError(*f->cMo * model.views[static_cast<size_t>(k)].oMv.inverse(), cMo);
        bt = std::min(bt, t / d);
        br = std::min(br, r);
      }
      const auto [t, r] = poseError(*j->cMo, cMo);
      joint_t.push_back(t / d);
      joint_r.push_back(r);
      best_t.push_back(bt);
      best_r.push_back(br);
    }
  }
  std::printf("%zu frames with two faces: median error joint %.3f %% of distance, %.3f deg; best single face %.3f %%, "
              "%.3f deg\n",
              joint_t.size(), 100 * median(joint_t), median(joint_r), 100 * median(best_t), median(best_r));
  ASSERT_GE(joint_t.size(), 6u);  // of 16 frames: the second face is sometimes too oblique to be found
  EXPECT_LE(median(joint_r), 1.5 * median(best_r) + 0.05);
  EXPECT_LE(median(joint_t), 1.5 * median(best_t) + 0.0005);
}

// A view whose oMv is wrong (the top placed 10 cm off) and the right views disagree: they are
// separate instances, never one pose between them.
TEST_F(MultiView, AWrongViewIsASeparateInstanceNotABlend) {
  const Pose shift(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.1, 0, 0));
  Detector det(DetectorOptions{});
  DetectorOptions two;
  two.match.max_instances = 2;
  Detector det2(two);
  const ObjectModel wrong = loadObjectDefinition(box_->writeDefinitions(*dir_, "wrong", shift));
  const int id = det.addObject(wrong);
  det2.addObject(wrong);
  const Intrinsics cam = sceneCamera();
  int seen_top = 0;
  for (double a : {20.0, 40.0, 60.0}) {
    const Pose cMo = lookAtBox(a * kDeg, 35 * kDeg, 0.8);
    const Pose cMo_wrong = cMo * shift.inverse();  // where the top alone puts the box: oMv' = shift oMv
    const cv::Mat img = renderScene(cam, box_->placed(cMo), 800 + static_cast<int>(a));
    for (const Detector* d : {&det, &det2}) {
      const DetectionResult r = d->detect(img, cam);
      ASSERT_TRUE(r.ok);
      for (const Detection& x : r.detections) {
        if (!x.found) continue;
        const bool has_top = std::count(x.views.begin(), x.views.end(), "top") > 0;
        seen_top += has_top;
        if (has_top) {
          EXPECT_EQ(x.views.size(), 1u) << a;
          EXPECT_TRUE(poseWithin(*x.cMo, cMo_wrong)) << a;
        } else {
          EXPECT_TRUE(poseWithin(*x.cMo, cMo)) << a;
        }
      }
    }
    EXPECT_LE(det.detect(img, cam).detections.size(), 1u);  // max_instances bounds the instances
    EXPECT_EQ(id, 0);
  }
  EXPECT_GT(seen_top, 0);  // the top was seen, so the test had something to refuse
}

// Two boxes side by side: two instances, each posed on one box.
TEST_F(MultiView, TwoBoxesAreTwoInstances) {
  DetectorOptions two;
  two.match.max_instances = 2;
  Detector det(two);
  const int id = det.addObject(loadObjectDefinition(*path_));
  const Intrinsics cam = sceneCamera();
  const Pose a = lookAtBox(30 * kDeg, 20 * kDeg, 1.0) * Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.15, 0, 0));
  const Pose b = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(-0.2, 0.02, 0.1)) * lookAtBox(-40 * kDeg, 15 * kDeg, 1.0);
  std::vector<sim::TexturedPlane> planes = box_->placed(a);
  for (const auto& p : box_->placed(b)) planes.push_back(p);
  const DetectionResult r = det.detect(renderScene(cam, planes, 901), cam);
  ASSERT_TRUE(r.ok);
  const auto d0 = r.find(id, 0), d1 = r.find(id, 1);
  ASSERT_TRUE(d0 && d1);
  const bool straight = poseWithin(*d0->cMo, a) && poseWithin(*d1->cMo, b);
  const bool crossed = poseWithin(*d0->cMo, b) && poseWithin(*d1->cMo, a);
  EXPECT_TRUE(straight || crossed);
}

// A prior on the object's pose (a tracker's prediction) is moved to each view.
TEST_F(MultiView, APriorOnTheObjectGuidesEveryView) {
  Detector det;
  const int id = det.addObject(loadObjectDefinition(*path_));
  const Intrinsics cam = sceneCamera();
  const Pose cMo = lookAtBox(45 * kDeg, 20 * kDeg, 1.0);
  const cv::Mat img = renderScene(cam, box_->placed(cMo), 950);
  DetectionQuery near;
  near.only_priors = true;
  near.priors.push_back({id, cMo * Pose::fromRotationVector({0.02, -0.03, 0}, {0.01, 0, 0.02}), {}, 0.25, 2.0, std::nullopt, 0});
  const DetectionResult r = det.detect(img, cam, {}, near);
  ASSERT_TRUE(r.ok);
  const auto d = r.find(id);
  ASSERT_TRUE(d);
  EXPECT_TRUE(poseWithin(*d->cMo, cMo));
  EXPECT_LT(r.stats[0].roi.area(), cam.width * cam.height / 2);  // a region around the box, not the image
  // A prior elsewhere: the box is not searched where it is.
  DetectionQuery away = near;
  away.priors[0].cMo = Pose(cMo.R, cMo.t + Eigen::Vector3d(0.5, 0, 0));
  EXPECT_FALSE(det.detect(img, cam, {}, away).find(id));
}

// Five views are five chances of a false detection: none on cluttered scenes without the box.
TEST_F(MultiView, NoFalsePositivesOnClutter) {
  Detector det;
  const int id = det.addObject(loadObjectDefinition(*path_));
  const Intrinsics cam = sceneCamera();
  int false_positives = 0;
  for (uint64_t seed = 4000; seed < 4024; ++seed) {
    const DetectionResult r = det.detect(renderScene(cam, {}, seed), cam);
    ASSERT_TRUE(r.ok);
    false_positives += r.find(id).has_value();
  }
  EXPECT_EQ(false_positives, 0);
}

// Stereo: each eye fuses the views, then the eyes' poses of the object are fused.
TEST_F(MultiView, StereoFusesBothEyesPosesOfTheObject) {
  Detector det;
  const int id = det.addObject(loadObjectDefinition(*path_));
  StereoRig rig;
  rig.left = rig.right = sceneCamera();
  rig.lMr = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.12, 0, 0));
  const Pose lMo = lookAtBox(130 * kDeg, 25 * kDeg, 0.9);
  const StereoDetectionResult r =
      det.detectStereo(renderScene(rig.left, box_->placed(lMo), 961),
                       renderScene(rig.right, box_->placed(rig.lMr.inverse() * lMo), 962), rig);
  ASSERT_TRUE(r.ok) << r.error;
  ASSERT_EQ(r.objects.size(), 1u);
  EXPECT_EQ(r.objects[0].fused.eyes, EyesUsed::kBoth);
  ASSERT_TRUE(r.objects[0].fused.lMo);
  EXPECT_TRUE(poseWithin(*r.objects[0].fused.lMo, lMo));
  EXPECT_FALSE(r.objects[0].left.views.empty());
  EXPECT_EQ(r.objects[0].object, id);
}

// fuseViews on exact correspondences: agreeing views give the joint pose the pairs define,
// disagreeing ones separate instances, best first.
TEST(FuseViews, AgreeingViewsGiveTheExactJointPoseAndDisagreeingOnesStaySeparate) {
  const Eigen::Matrix3d K = sceneCamera().K();
  const Pose cMo = Pose::fromRotationVector({0.3, -0.5, 0.1}, {0.05, -0.02, 1.0});
  const Pose oMv0(Eigen::Matrix3d::Identity(), {0, 0, -0.04});
  const Pose oMv1 = Pose::fromRotationVector({0, M_PI / 2, 0}, {-0.1, 0, 0});
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-0.07, 0.07);
  auto instance = [&](int view, const Pose& oMv, int n, const Pose& error) {
    ViewInstance v;
    v.view = view;
    v.detection.found = true;
    v.detection.inliers = n;
    v.cMo = cMo * error;
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3d X = oMv * Eigen::Vector3d(u(rng), u(rng), 0);
      v.pairs.points_o.push_back(X);
      v.pairs.points_px.push_back(projectPinhole(K, cMo * X));
      v.pairs.sigma_px.push_back(1);
    }
    return v;
  };
  const Pose small = Pose::fromRotationVector({0.01, 0, 0.005}, {0.004, -0.003, 0.006});
  const std::vector<std::string> names = {"front", "left", "top"};
  std::vector<Detection> out = fuseViews({instance(0, oMv0, 20, small), instance(1, oMv1, 30, small.inverse())}, names,
                                         K, PoseOptions{}, MultiViewOptions{});
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].view, "left");  // the most inliers
  EXPECT_EQ(out[0].views, (std::vector<std::string>{"left", "front"}));
  EXPECT_EQ(out[0].inliers, 50);
  EXPECT_LT(translationError(*out[0].cMo, cMo), 1e-6);
  EXPECT_LT(rotationError(*out[0].cMo, cMo), 1e-6);
  // The top 12 cm off: its own instance, after the larger group.
  const Pose off(Eigen::Matrix3d::Identity(), {0.12, 0, 0});
  out = fuseViews({instance(2, oMv0, 40, off), instance(0, oMv0, 20, small), instance(1, oMv1, 30, Pose())}, names, K,
                  PoseOptions{}, MultiViewOptions{});
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].views, (std::vector<std::string>{"top"}));
  EXPECT_EQ(out[1].views, (std::vector<std::string>{"left", "front"}));
  EXPECT_EQ(out[0].instance, 0);
  EXPECT_EQ(out[1].instance, 1);
  EXPECT_LT(translationError(*out[0].cMo, cMo * off), 1e-12);  // alone: its own pose, untouched
}

}  // namespace

namespace {

// Built in code rather than loaded: a view the detector cannot pose is refused at start-up.
TEST(MultiViewObject, AViewWithoutMetricGeometryIsRefusedAtAddObject) {
  ObjectModel box;
  box.name = "box";
  box.views.push_back({"flat", std::make_shared<ObjectModel>(makeObjectModel(
                                   "flat", loadMedia("targets/tea_box.png"), std::nullopt, std::nullopt)),
                       Pose()});
  Detector det;
  try {
    det.addObject(box);
    ADD_FAILURE() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("box: views[0].definition: a view needs metric geometry"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(det.objectCount(), 0);
}

}  // namespace
