// The detect_object line codec: exact field names and order (docs/formats.md contract),
// found:false lines without geometry, tags, stereo lines with the fused pose.
#include <gtest/gtest.h>

#include "detector/detection_json.h"

using namespace refgrasp;
using namespace refgrasp::detector;

namespace {

Detection found(int object, int instance, bool with_pose) {
  Detection d;
  d.object = object;
  d.instance = instance;
  d.found = true;
  d.H << 2, 0, 10, 0, 2, 20, 0, 0, 2;  // written divided by H(2,2)
  d.corners = {Eigen::Vector2d(1, 2), Eigen::Vector2d(3, 4), Eigen::Vector2d(5, 6), Eigen::Vector2d(7, 8)};
  if (with_pose) d.cMo = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.5, 0.25, 2));
  d.inliers = 42;
  return d;
}

}  // namespace

TEST(DetectionJson, MonoLinesInTheDocumentedOrder) {
  DetectionResult r;
  r.detections = {found(0, 0, true), Detection{}};
  r.detections[1].object = 1;
  r.time_ms = {1.5, 0.25, 0.125, 2};
  const std::vector<Json> lines = detectionLines(r, {{"image", "p.png"}}, {"poster", "box"}, true);
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_EQ(lines[0].dump(),
            R"({"image":"p.png","found":true,"homography":[1.0,0.0,5.0,0.0,1.0,10.0,0.0,0.0,1.0],)"
            R"("corners":[[1.0,2.0],[3.0,4.0],[5.0,6.0],[7.0,8.0]],"R":[1.0,0.0,0.0,0.0,1.0,0.0,0.0,0.0,1.0],)"
            R"("t":[0.5,0.25,2.0],"inliers":42,"object":"poster","instance":0,)"
            R"("time_ms":{"extract":1.5,"match":0.25,"pose":0.125,"total":2.0}})");
  EXPECT_EQ(lines[1].dump(),
            R"({"image":"p.png","found":false,"object":"box","instance":0,)"
            R"("time_ms":{"extract":1.5,"match":0.25,"pose":0.125,"total":2.0}})");
  // Untagged, 2D-only: no R, t, object, instance.
  r.detections = {found(0, 0, false)};
  const Json j = detectionLines(r, {{"image", "q.png"}}, {"flat"}, false).at(0);
  EXPECT_FALSE(j.contains("R") || j.contains("t") || j.contains("object") || j.contains("instance"));
  EXPECT_EQ(std::next(j.begin(), 3).key(), "corners");
  EXPECT_EQ(std::next(j.begin(), 4).key(), "inliers");
}

TEST(DetectionJson, StereoLinesCarryTheFusedPoseAndBothEyesTime) {
  StereoDetectionResult r;
  r.left.time_ms = {1, 2, 3, 6};
  r.right.time_ms = {10, 20, 30, 60};
  StereoDetection s;
  s.object = 0;
  s.left = found(0, 0, true);
  s.right.object = 0;
  s.fused.eyes = EyesUsed::kLeft;
  s.fused.lMo = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.5, 0.25, 2.5));
  r.objects = {s};
  const Json j = stereoDetectionLines(r, {{"image", "l.png"}, {"right", "r.png"}}, {"poster"}, false).at(0);
  EXPECT_EQ(j.dump(),
            R"({"image":"l.png","right":"r.png","found":true,"homography":[1.0,0.0,5.0,0.0,1.0,10.0,0.0,0.0,1.0],)"
            R"("corners":[[1.0,2.0],[3.0,4.0],[5.0,6.0],[7.0,8.0]],"R":[1.0,0.0,0.0,0.0,1.0,0.0,0.0,0.0,1.0],)"
            R"("t":[0.5,0.25,2.5],"inliers":42,"eyes":"left",)"
            R"("time_ms":{"extract":11.0,"match":22.0,"pose":33.0,"total":66.0}})");
  // Neither eye: found false, no geometry, "eyes":"none".
  r.objects[0].left = Detection{};
  r.objects[0].fused = FusedPose{};
  const Json none = stereoDetectionLines(r, {{"image", "l.png"}}, {"poster"}, true).at(0);
  EXPECT_EQ(none.dump(), R"({"image":"l.png","found":false,"eyes":"none","object":"poster","instance":0,)"
                         R"("time_ms":{"extract":11.0,"match":22.0,"pose":33.0,"total":66.0}})");
}
