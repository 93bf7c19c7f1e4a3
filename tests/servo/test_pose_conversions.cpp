#include <gtest/gtest.h>

#include <visp3/core/vpThetaUVector.h>

#include "servo/pose_conversions.h"

using namespace refgrasp;

TEST(PoseConversions, RoundTripAndSameConventionAsVisp) {
  const Pose cMo = Pose::fromRotationVector({0.3, -0.1, 0.7}, {0.05, -0.02, 0.6});
  const vpHomogeneousMatrix M = servo::toVisp(cMo);
  const vpThetaUVector tu(M.getRotationMatrix());
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(tu[i], cMo.rotationVector()[i], 1e-12);
  // A point in the object frame maps to the camera frame identically.
  const vpColVector p = M * vpColVector({0.1, 0.2, 0.0, 1.0});
  const Eigen::Vector3d q = cMo * Eigen::Vector3d(0.1, 0.2, 0.0);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(p[i], q[i], 1e-12);
  const Pose back = servo::fromVisp(M);
  EXPECT_NEAR(rotationError(back, cMo), 0, 1e-12);
  EXPECT_NEAR(translationError(back, cMo), 0, 1e-12);
}

// ---- Camera files written by ViSP itself are read with the same model --------------------------
#include <visp3/core/vpCameraParameters.h>
#include <visp3/core/vpIoTools.h>
#include <visp3/core/vpMeterPixelConversion.h>
#include <visp3/core/vpXmlParserCamera.h>

#include "common/temp_dir.h"
#include "core/camera.h"

TEST(VispCameraXml, FileSavedByVispLoadsWithTheSameProjection) {
  vpCameraParameters cam;
  cam.initPersProjWithDistortion(492.5, 493.0, 319.2, 241.7, -0.12, 0.125);
  const std::string path = (refgrasp::testing::tempDir("refgrasp_test_servo") / "bb2.xml").string();
  vpIoTools::remove(path);
  vpXmlParserCamera writer;
  ASSERT_EQ(writer.save(cam, path, "bb2_left", 640, 480), vpXmlParserCamera::SEQUENCE_OK);

  const Intrinsics in = loadCameraFile(path);
  EXPECT_EQ(in.width, 640);
  EXPECT_EQ(in.height, 480);
  for (double x = -0.5; x <= 0.5; x += 0.25)
    for (double y = -0.4; y <= 0.4; y += 0.2) {
      double u = 0, v = 0;
      vpMeterPixelConversion::convertPoint(cam, x, y, u, v);  // ViSP's projection with kud
      const Eigen::Vector2d p = in.distortNormalized({x, y});
      EXPECT_NEAR(p.x(), u, 1e-9);
      EXPECT_NEAR(p.y(), v, 1e-9);
    }
}
