// make_reference --views: the faces' frames are the simulator's box faces; a box whose faces are
// photographed and defined with --corners, then joined, maps every texture point of every face
// to where the simulator puts it in the box frame (1 mm); bad faces, sizes and outputs are
// one-line refusals.
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgcodecs.hpp>

#include "common/app_run.h"
#include "common/temp_dir.h"
#include "detector/object.h"
#include "reference/box_views.h"
#include "reference/make_reference.h"
#include "refusal.h"
#include "robot/sim/render.h"
#include "robot/sim/scenario.h"
#include "robot/sim/synthetic_scene.h"

namespace fs = std::filesystem;
using namespace refgrasp;
using refgrasp::testing::AppRun;
using refgrasp::testing::refusal;
using refgrasp::testing::runApp;

namespace {

const Eigen::Vector3d kBoxSize(0.20, 0.30, 0.08);  // W, H, D (metres)

// The six faces as the simulator makes a scenario box (robot/sim/scenario.cpp: front face at
// z = 0, rows along +y on the front, back and sides, along +z on the top and bottom), in
// boxFaces' order -x, +x, -y, +y, -z, +z, with names.
const char* const kSimOrder[6] = {"left", "right", "top", "bottom", "front", "back"};

std::vector<sim::TexturedPlane> simBox(const Eigen::Vector3d& size) {
  const Eigen::Vector3d Y = Eigen::Vector3d::UnitY(), Z = Eigen::Vector3d::UnitZ();
  std::array<cv::Mat, 6> tex;
  const std::vector<std::string>& targets = refgrasp::testing::targetTextures();
  for (size_t i = 0; i < 6; ++i) tex[i] = refgrasp::testing::loadMedia(targets[i % targets.size()]);
  return sim::boxFaces(size, Eigen::Vector3d(0, 0, size.z() / 2), tex, {Y, Y, Z, Z, Y, Y});
}

fs::path scratch() { return refgrasp::testing::tempDir("refgrasp_test_box_views"); }

Intrinsics photoCamera() {
  Intrinsics cam = Intrinsics::pinhole(800, 600, 700, 401.0, 298.5);
  cam.dist = {-0.08, 0.02, 0, 0, 0};
  return cam;
}

// A face photographed on its own (turned and tilted a little, 0.45 m away) and defined with
// --corners on its four texture corners and its size: the user's way.
struct FacePhoto {
  sim::TexturedPlane plane;  ///< cMp: the face in the photo's camera
  std::string yaml;
};

FacePhoto defineFace(const sim::TexturedPlane& face, const std::string& name, size_t i) {
  const Intrinsics cam = photoCamera();
  FacePhoto f{face, (scratch() / (name + ".yaml")).string()};
  f.plane.cMp = Pose::fromRotationVector({0.15 - 0.05 * i, 0.2 * (i % 2 ? 1 : -1), 0.03 * i},
                                         {0.01 * i, -0.02, 0.45});
  const cv::Mat photo = sim::renderView(cam, {f.plane}, refgrasp::testing::clutterBackground(40 + i, 800, 600));
  const std::string img = (scratch() / (name + ".png")).string(), camf = (scratch() / (name + "_camera.yaml")).string();
  EXPECT_TRUE(cv::imwrite(img, photo));
  saveCameraFile(camf, cam, name);
  const reference::Reference ref =
      reference::fromCorners(sim::projectPlaneCorners(cam, f.plane), face.width_m, face.height_m, cam);
  reference::writeObjectDefinition(f.yaml, name, img, camf, ref);
  return f;
}

}  // namespace

TEST(MakeReferenceViews, FaceFramesAreTheSimulatorsBoxFaces) {
  const std::vector<sim::TexturedPlane> sim = simBox(kBoxSize);
  for (size_t i = 0; i < 6; ++i) {
    SCOPED_TRACE(kSimOrder[i]);
    const Pose oMv = reference::boxFacePose(kSimOrder[i], kBoxSize);
    EXPECT_LT((oMv.R - sim[i].cMp.R).norm(), 1e-12);
    EXPECT_LT((oMv.t - sim[i].cMp.t).norm(), 1e-12);
    EXPECT_NEAR(reference::boxFaceSize(kSimOrder[i], kBoxSize).x(), sim[i].width_m, 1e-12);
    EXPECT_NEAR(reference::boxFaceSize(kSimOrder[i], kBoxSize).y(), sim[i].height_m, 1e-12);
  }
  // Written out: the front face is the object frame, the back one faces the other way at z = D.
  EXPECT_LT((reference::boxFacePose("front", kBoxSize).t).norm(), 1e-12);
  EXPECT_LT((reference::boxFacePose("back", kBoxSize).t - Eigen::Vector3d(0, 0, 0.08)).norm(), 1e-12);
  EXPECT_LT((reference::boxFacePose("top", kBoxSize).t - Eigen::Vector3d(0, -0.15, 0.04)).norm(), 1e-12);
  EXPECT_LT((reference::boxFacePose("left", kBoxSize).t - Eigen::Vector3d(-0.1, 0, 0.04)).norm(), 1e-12);
  EXPECT_EQ(refusal([] { reference::boxFacePose("side", kBoxSize); }),
            "--face: unknown face 'side' (front, back, left, right, top, bottom)");
}

TEST(MakeReferenceViews, PhotographedFacesJoinedMapTheirTexturePointsToTheBoxFrame) {
  const std::vector<sim::TexturedPlane> sim = simBox(kBoxSize);
  const Intrinsics cam = photoCamera();
  std::vector<reference::BoxFaceDefinition> faces;
  std::map<std::string, FacePhoto> photos;
  for (size_t i = 0; i < 6; ++i) {
    if (std::string(kSimOrder[i]) == "bottom") continue;  // five faces: one left out
    photos[kSimOrder[i]] = defineFace(sim[i], kSimOrder[i], i);
    faces.push_back({kSimOrder[i], photos[kSimOrder[i]].yaml});
  }
  const std::string yaml = (scratch() / "box.yaml").string();
  reference::writeBoxDefinition(yaml, "box", kBoxSize, faces);
  const detector::ObjectModel box = detector::loadObjectDefinition(yaml);
  ASSERT_TRUE(box.isMultiView());
  ASSERT_EQ(box.views.size(), 5u);
  const std::vector<std::string> written = {"front", "back", "left", "right", "top"};  // boxFaceNames() order
  for (size_t k = 0; k < 5; ++k) EXPECT_EQ(box.views[k].name, written[k]);
  // Texture points of each face: through its photo and its definition's reference pose into the
  // view's frame, then by oMv into the box frame; against the simulator's oMp.
  double worst = 0;
  for (size_t i = 0; i < 6; ++i) {
    const auto it = photos.find(kSimOrder[i]);
    if (it == photos.end()) continue;
    const detector::ObjectView* view = nullptr;
    for (const auto& v : box.views)
      if (v.name == kSimOrder[i]) view = &v;
    ASSERT_NE(view, nullptr) << kSimOrder[i];
    const sim::TexturedPlane& face = sim[i];
    const int W = face.texture.cols, H = face.texture.rows;
    for (const Eigen::Vector2d& uv : {Eigen::Vector2d(10, 12), Eigen::Vector2d(W - 8, H / 2.0), Eigen::Vector2d(W / 3.0, H - 6)}) {
      const Eigen::Vector3d X_p((uv.x() - (W - 1) / 2.0) * face.width_m / W, (uv.y() - (H - 1) / 2.0) * face.height_m / H, 0);
      const Eigen::Vector2d px = cam.project(it->second.plane.cMp * X_p);
      const std::optional<Eigen::Vector3d> X_v = view->model->target->backProject(cam.undistortPixel(px));
      ASSERT_TRUE(X_v.has_value());
      const double err = (view->oMv * *X_v - face.cMp * X_p).norm();
      worst = std::max(worst, err);
      EXPECT_LT(err, 0.001) << kSimOrder[i] << " texture px " << uv.transpose();
    }
  }
  std::printf("[ measured ] box texture points through the joined definition: worst %.3f mm\n", 1000 * worst);
}

TEST(MakeReferenceViews, BadFacesSizesAndOutputsAreRefusedWithOneLine) {
  const std::vector<sim::TexturedPlane> sim = simBox(kBoxSize);
  const FacePhoto front = defineFace(sim[4], "front_face", 4), left = defineFace(sim[0], "left_face", 0);
  const std::string yaml = (scratch() / "bad_box.yaml").string();
  const auto write = [&](const Eigen::Vector3d& size, const std::vector<reference::BoxFaceDefinition>& faces) {
    return refusal([&] { reference::writeBoxDefinition(yaml, "box", size, faces); });
  };
  EXPECT_EQ(write({0.2, 0, 0.08}, {{"front", front.yaml}}), "--box-size: W,H,D must be positive (metres)");
  EXPECT_EQ(write({0.2, 0.3, -1}, {{"front", front.yaml}}), "--box-size: W,H,D must be positive (metres)");
  EXPECT_EQ(write(kBoxSize, {}), "--face: give at least one face (--face front=FRONT.yaml)");
  EXPECT_EQ(write(kBoxSize, {{"front", front.yaml}, {"frnt", left.yaml}}),
            "--face: unknown face 'frnt' (front, back, left, right, top, bottom)");
  EXPECT_EQ(write(kBoxSize, {{"left", left.yaml}, {"front", front.yaml}, {"left", left.yaml}}), "--face: left is given twice");
  // The left face's definition given as the front: 0.08 m wide, the front is 0.2 x 0.3 (fits), so
  // give it as the top (0.2 x 0.08): its 0.3 m height runs off.
  const std::string off = write(kBoxSize, {{"top", left.yaml}});
  EXPECT_EQ(off.rfind("--face top=" + left.yaml + ": its pattern reaches (", 0), 0u) << off;
  EXPECT_NE(off.find(") m in its frame, off the box's top face (0.2 x 0.08 m, centred): check --box-size and the face's frame"),
            std::string::npos) << off;
  // W and D swapped: the front is 0.08 wide.
  EXPECT_EQ(write({0.08, 0.3, 0.2}, {{"front", front.yaml}}).rfind("--face front=" + front.yaml + ": its pattern reaches (", 0),
            0u);
  // A cylinder definition is no box face.
  const std::string can = (scratch() / "can.yaml").string(), label = (scratch() / "can_label.png").string();
  cv::imwrite(label, cv::Mat(50, 100, CV_8UC1, cv::Scalar(128)));
  std::ofstream(can) << "reference_image: can_label.png\ncylinder: {radius_m: 0.03, label_size_m: [0.1, 0.05]}\n";
  EXPECT_EQ(write(kBoxSize, {{"front", can}}),
            "--face front=" + can + ": not a planar definition with reference_pose (make one with --corners)");
  EXPECT_FALSE(fs::exists(yaml));
}

TEST(MakeReferenceViewsApp, JoinsFacesInAnyOptionOrderOrRefusesWithOneLine) {
  const std::vector<sim::TexturedPlane> sim = simBox(kBoxSize);
  const FacePhoto front = defineFace(sim[4], "app_front", 4), right = defineFace(sim[1], "app_right", 1);
  const std::string yaml = (scratch() / "app_box.yaml").string();
  AppRun r = runApp("make_reference", "--face right=" + right.yaml + " --box-size 0.2,0.3,0.08 --output " + yaml +
                                          " --views --face front=" + front.yaml + " --name tea_box");
  ASSERT_EQ(r.status, 0) << r.err;
  const detector::ObjectModel box = detector::loadObjectDefinition(yaml);
  EXPECT_EQ(box.name, "tea_box");
  ASSERT_EQ(box.views.size(), 2u);
  EXPECT_EQ(box.views[0].name, "app_front");
  EXPECT_LT((box.views[1].oMv.t - Eigen::Vector3d(0.1, 0, 0.04)).norm(), 1e-9);
  EXPECT_LT((box.views[1].oMv.R - sim[1].cMp.R).norm(), 1e-9);
  const auto expectRefused = [](const std::string& args, const std::string& line) {
    const AppRun bad = runApp("make_reference", args);
    EXPECT_EQ(bad.status, 2) << args;
    EXPECT_EQ(bad.err, "make_reference: " + line + "\n") << args;
  };
  const std::string out = " --output " + (scratch() / "app_bad.yaml").string();
  expectRefused("--views --box-size 0.2,0.3 --face front=" + front.yaml + out, "--box-size: expected 3 numbers");
  expectRefused("--views --box-size 0.2,0.3,0.08 --face front" + out,
                "--face: 'front' is not NAME=FILE (NAME: front, back, left, right, top, bottom)");
  expectRefused("--views --box-size 0.2,0.3,0.08 --face front=" + front.yaml + " --output " + front.yaml,
                "--output " + front.yaml + ": is the input --face front " + front.yaml + " (it would be overwritten)");
  const std::string missing = (scratch() / "missing.yaml").string();
  const AppRun bad = runApp("make_reference", "--views --box-size 0.2,0.3,0.08 --face back=" + missing + out);
  EXPECT_EQ(bad.status, 2);
  EXPECT_EQ(bad.err.rfind("make_reference: " + missing + ": ", 0), 0u) << bad.err;
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1);
  const AppRun mixed = runApp("make_reference", "--views --box-size 0.2,0.3,0.08 --face front=" + front.yaml +
                                                    " --image " + front.yaml + out);
  EXPECT_EQ(mixed.status, 2);
  EXPECT_EQ(mixed.err, "make_reference: --image excludes --views (see --help)\n");
  EXPECT_FALSE(fs::exists(scratch() / "app_bad.yaml"));
}
