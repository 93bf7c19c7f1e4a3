// make_reference: both methods reproduce the rendered ground truth (1 mm, 0.5 deg), the written
// object definition is accepted by the detector and finds the object in another view with the
// right pose, and bad input is refused with one line.
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/app_run.h"
#include "common/temp_dir.h"
#include "core/error.h"
#include "detector/detector.h"
#include "reference/make_reference.h"
#include "refusal.h"
#include "robot/sim/render.h"
#include "robot/sim/synthetic_scene.h"

namespace fs = std::filesystem;
using namespace refgrasp;
using refgrasp::testing::AppRun;
using refgrasp::testing::refusal;
using refgrasp::testing::runApp;

namespace {

constexpr double kDeg = 180.0 / M_PI;

// A 1280x960 reference photo (f = 1100 px, no distortion).
Intrinsics photoCamera() { return Intrinsics::pinhole(1280, 960, 1100, 639.5, 479.5); }

// AprilTag 36h11 images: 10 x 10 cells (white quiet zone, black border, 6 x 6 data bits).
// Codes and bit positions of the AprilRobotics tag36h11 family (apriltag 3, tag36h11.c):
// bit i (from the most significant of 36) is cell (bit_x[i], bit_y[i]) of the 8 x 8 black-bordered
// square, 1 = white.
cv::Mat tag36h11(int id, int cell_px) {
  static const uint64_t kCodes[] = {0x0000000d7e00984bull, 0x0000000dda664ca7ull};
  static const int kBitX[36] = {1, 2, 3, 4, 5, 2, 3, 4, 3, 6, 6, 6, 6, 6, 5, 5, 5, 4,
                                6, 5, 4, 3, 2, 5, 4, 3, 4, 1, 1, 1, 1, 1, 2, 2, 2, 3};
  static const int kBitY[36] = {1, 1, 1, 1, 1, 2, 2, 2, 3, 1, 2, 3, 4, 5, 2, 3, 4, 3,
                                6, 6, 6, 6, 6, 5, 5, 5, 4, 6, 5, 4, 3, 2, 5, 4, 3, 4};
  cv::Mat g(10, 10, CV_8UC1, cv::Scalar(255));
  g(cv::Rect(1, 1, 8, 8)).setTo(0);
  for (int i = 0; i < 36; ++i)
    if ((kCodes[id] >> (35 - i)) & 1) g.at<uchar>(kBitY[i] + 1, kBitX[i] + 1) = 255;
  cv::Mat big;
  cv::resize(g, big, {10 * cell_px, 10 * cell_px}, 0, 0, cv::INTER_NEAREST);
  return big;
}

struct Photo {
  cv::Mat image;
  Pose cMo;                       ///< the object plane
  std::vector<Pose> cMtag;        ///< each tag (its black square's centre)
  sim::TexturedPlane object;
};

constexpr double kObjectWidth = 0.30, kTagCells = 0.01;  // tag: 10 cells of 1 cm, black square 8 cm

// The poster at cMo, with tags (ids) lying on it at the given object-frame offsets (x, y), 0.2 mm
// in front of its surface.
Photo renderPhoto(const Intrinsics& cam, const Pose& cMo, const std::vector<std::pair<int, Eigen::Vector2d>>& tags,
                  uint64_t seed) {
  const cv::Mat tex = refgrasp::testing::loadMedia("targets/poster_concert.png");
  Photo p;
  p.cMo = cMo;
  p.object = {tex, kObjectWidth, kObjectWidth * tex.rows / tex.cols, cMo};
  std::vector<sim::TexturedPlane> planes = {p.object};
  for (const auto& [id, xy] : tags) {
    const Pose cMt = cMo * Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(xy.x(), xy.y(), -0.0002));
    planes.push_back({tag36h11(id, 24), 10 * kTagCells, 10 * kTagCells, cMt});
    p.cMtag.push_back(cMt);
  }
  p.image = sim::renderView(cam, planes, refgrasp::testing::clutterBackground(seed, cam.width, cam.height));
  return p;
}

const Pose kPhotoPose = Pose::fromRotationVector({0.25, -0.2, 0.1}, {0.03, -0.02, 0.7});

fs::path scratch() { return refgrasp::testing::tempDir("refgrasp_test_reference"); }

// Writes the photo and its camera file; returns their paths.
std::pair<std::string, std::string> savePhoto(const Photo& p, const std::string& stem) {
  const std::string img = (scratch() / (stem + ".png")).string();
  const std::string cam = (scratch() / (stem + "_camera.yaml")).string();
  cv::imwrite(img, p.image);
  saveCameraFile(cam, photoCamera(), stem);
  return {img, cam};
}

// The written definition finds the object in a new view with the pose of `truth` (object frame
// in the new camera), within the detector's tolerances.
void expectDetectedInANewView(const std::string& yaml, const Pose& oMtruth_frame) {
  detector::Detector det;
  det.addObject(detector::loadObjectDefinition(yaml));
  const Intrinsics cam = refgrasp::testing::sceneCamera();
  const Pose cMo = Pose::fromRotationVector({-0.2, 0.3, -0.15}, {-0.02, 0.03, 0.75});
  const Photo view = renderPhoto(cam, cMo, {{0, {0.06, 0.1}}}, 9);
  const detector::DetectionResult r = det.detect(view.image, cam);
  ASSERT_TRUE(r.ok) << r.error;
  const std::optional<detector::Detection> d = r.find(0);
  ASSERT_TRUE(d && d->cMo) << "the object made by make_reference was not found";
  const Pose truth = cMo * oMtruth_frame;
  EXPECT_LT(translationError(*d->cMo, truth), 0.01 * truth.t.norm());
  EXPECT_LT(rotationError(*d->cMo, truth) * kDeg, 1.0);
}

}  // namespace

TEST(MakeReference, CornersReproduceTheRenderedPose) {
  const Intrinsics cam = photoCamera();
  const Photo photo = renderPhoto(cam, kPhotoPose, {}, 5);
  std::array<Eigen::Vector2d, 4> corners = sim::projectPlaneCorners(cam, photo.object);
  for (auto& c : corners) c = (c * 4).array().round() / 4;  // clicked to a quarter pixel
  const reference::Reference ref =
      reference::fromCorners(corners, photo.object.width_m, photo.object.height_m, cam);
  const double t_mm = translationError(ref.cMo, photo.cMo) * 1e3;
  const double r_deg = rotationError(ref.cMo, photo.cMo) * kDeg;
  std::printf("corners: %.3f mm, %.3f deg, rms %.3f px\n", t_mm, r_deg, ref.rms_px);
  EXPECT_LT(t_mm, 1.0);
  EXPECT_LT(r_deg, 0.5);
  EXPECT_EQ(ref.pattern_region_px.size(), 4u);
  const auto [img, camf] = savePhoto(photo, "corners_photo");
  const std::string yaml = (scratch() / "corners_object.yaml").string();
  reference::writeObjectDefinition(yaml, "poster", img, camf, ref);
  const detector::ObjectModel m = detector::loadObjectDefinition(yaml);
  EXPECT_EQ(m.name, "poster");
  ASSERT_TRUE(m.reference_cMo.has_value());
  EXPECT_LT(translationError(*m.reference_cMo, ref.cMo), 1e-8);  // written with enough digits
  expectDetectedInANewView(yaml, Pose());
  const cv::Mat check = reference::drawReference(photo.image, ref, cam);
  EXPECT_EQ(check.size(), photo.image.size());
}

TEST(MakeReference, AnAprilTagReproducesTheRenderedPose) {
  const Intrinsics cam = photoCamera();
  const Photo photo = renderPhoto(cam, kPhotoPose, {{0, {0.06, 0.1}}}, 5);
  reference::TagOptions o;
  o.tag_size_m = 8 * kTagCells;
  const reference::Reference ref = reference::fromTag(photo.image, cam, o);
  EXPECT_EQ(ref.method, "apriltag 36h11 id 0");
  const double t_mm = translationError(ref.cMo, photo.cMtag[0]) * 1e3;
  const double r_deg = rotationError(ref.cMo, photo.cMtag[0]) * kDeg;
  std::printf("apriltag: %.3f mm, %.3f deg, rms %.3f px\n", t_mm, r_deg, ref.rms_px);
  EXPECT_LT(t_mm, 1.0);
  EXPECT_LT(r_deg, 0.5);
  // The default pattern region is the photo minus the tag: a simple polygon the detector accepts.
  EXPECT_GT(ref.pattern_region_px.size(), 4u);
  const auto [img, camf] = savePhoto(photo, "tag_photo");
  const std::string yaml = (scratch() / "tag_object.yaml").string();
  reference::writeObjectDefinition(yaml, "poster", img, camf, ref);
  // The object frame is the tag's: in a new view the detector reports cMtag.
  expectDetectedInANewView(yaml, Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.06, 0.1, -0.0002)));
}

TEST(MakeReference, BadCornersSizesAndTagsAreRefusedWithOneLine) {
  const Intrinsics cam = photoCamera();
  const std::array<Eigen::Vector2d, 4> ok = {Eigen::Vector2d(100, 100), Eigen::Vector2d(500, 120),
                                             Eigen::Vector2d(480, 400), Eigen::Vector2d(110, 380)};
  EXPECT_EQ(refusal([&] { reference::fromCorners({ok[0], ok[2], ok[1], ok[3]}, 0.3, 0.2, cam); }),
            "--corners: the corners are not a convex quadrilateral (order TL, TR, BR, BL)");
  EXPECT_EQ(refusal([&] { reference::fromCorners({ok[0], ok[3], ok[2], ok[1]}, 0.3, 0.2, cam); }),
            "--corners: corners go anticlockwise; give them as TL, TR, BR, BL");
  const std::array<Eigen::Vector2d, 4> dent = {ok[0], Eigen::Vector2d(250, 250), ok[2], ok[3]};
  EXPECT_EQ(refusal([&] { reference::fromCorners(dent, 0.3, 0.2, cam); }),
            "--corners: the corners are not a convex quadrilateral (order TL, TR, BR, BL)");
  EXPECT_EQ(refusal([&] { reference::fromCorners({ok[0], ok[1], ok[2], Eigen::Vector2d(-20, 380)}, 0.3, 0.2, cam); }),
            "--corners: corner (-20.000000, 380.000000) is outside the 1280x960 image");
  EXPECT_EQ(refusal([&] { reference::fromCorners(ok, 0.0, 0.2, cam); }),
            "--size: width and height must be positive (metres)");
  EXPECT_EQ(refusal([&] { reference::fromCorners(ok, 0.3, -1, cam); }),
            "--size: width and height must be positive (metres)");
  const Photo no_tag = renderPhoto(cam, kPhotoPose, {}, 5);
  reference::TagOptions o;
  o.tag_size_m = 0.08;
  EXPECT_EQ(refusal([&] { reference::fromTag(no_tag.image, cam, o); }),
            "--apriltag: no 36h11 tag found in the photo");
  const Photo two = renderPhoto(cam, kPhotoPose, {{0, {-0.07, 0.1}}, {1, {0.07, 0.1}}}, 5);
  EXPECT_EQ(refusal([&] { reference::fromTag(two.image, cam, o); }),
            "--apriltag: 2 tags (ids 0, 1); choose one with --tag-id");
  o.id = 7;
  EXPECT_EQ(refusal([&] { reference::fromTag(two.image, cam, o); }),
            "--tag-id: tag 7 not found (found ids 0, 1)");
  o.id = 1;
  const reference::Reference one = reference::fromTag(two.image, cam, o);
  EXPECT_EQ(one.method, "apriltag 36h11 id 1");  // the bit pattern of id 1 is right too
  EXPECT_LT(translationError(one.cMo, two.cMtag[1]), 0.001);
  o.tag_size_m = 0;
  EXPECT_EQ(refusal([&] { reference::fromTag(two.image, cam, o); }), "--tag-size: must be positive (metres)");
  o.tag_size_m = 0.08;
  o.family = "36h10x";
  EXPECT_EQ(refusal([&] { reference::fromTag(two.image, cam, o); }),
            "--apriltag: unknown family '36h10x' (36h11, 25h9, 16h5, circle21h7)");
}

TEST(MakeReferenceApp, WritesTheDefinitionAndACheckPictureOrRefusesWithOneLine) {
  const Intrinsics cam = photoCamera();
  const Photo photo = renderPhoto(cam, kPhotoPose, {{0, {0.06, 0.1}}}, 5);
  const auto [img, camf] = savePhoto(photo, "app_photo");
  const std::array<Eigen::Vector2d, 4> c = sim::projectPlaneCorners(cam, photo.object);
  std::string corners;
  for (const auto& p : c) corners += (corners.empty() ? "" : ",") + std::to_string(p.x()) + "," + std::to_string(p.y());
  const std::string yaml = (scratch() / "app_object.yaml").string();
  const std::string common = " --image " + img + " --camera " + camf + " --output " + yaml;
  AppRun r = runApp("make_reference", common + " --corners " + corners + " --size 0.3," +
                                          std::to_string(photo.object.height_m));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_LT(translationError(*detector::loadObjectDefinition(yaml).reference_cMo, photo.cMo), 0.001);
  EXPECT_EQ(cv::imread((scratch() / "app_object.png").string()).size(), photo.image.size());
  r = runApp("make_reference", common + " --apriltag 36h11 --tag-size 0.08");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_LT(translationError(*detector::loadObjectDefinition(yaml).reference_cMo, photo.cMtag[0]), 0.001);
  r = runApp("make_reference", common + " --corners 100,100,480,400,500,120,110,380 --size 0.3,0.2");
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "make_reference: --corners: the corners are not a convex quadrilateral (order TL, TR, BR, BL)\n");
  r = runApp("make_reference", common + " --corners 100,100,500,120,480,400 --size 0.3,0.2");
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "make_reference: --corners: expected 8 numbers\n");
  r = runApp("make_reference", common + " --corners " + corners + " --size 0.3,0");
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "make_reference: --size: width and height must be positive (metres)\n");
  const Photo no_tag = renderPhoto(cam, kPhotoPose, {}, 5);
  const auto [img2, camf2] = savePhoto(no_tag, "app_no_tag");
  r = runApp("make_reference", " --image " + img2 + " --camera " + camf2 + " --output " + yaml +
                                   " --apriltag 36h11 --tag-size 0.08");
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "make_reference: --apriltag: no 36h11 tag found in the photo\n");
  r = runApp("make_reference", "--help");
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(r.out.find("--apriltag"), std::string::npos);
}
