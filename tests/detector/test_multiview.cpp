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
