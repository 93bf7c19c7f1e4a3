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
