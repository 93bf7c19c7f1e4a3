// Message conversions: images (every supported encoding, every malformed layout), camera_info,
// time, poses, the gripper's joint encoding.
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "robot/dds/convert.h"
#include "robot/dds/robot_topics.h"

using namespace refgrasp;
using namespace refgrasp::dds;

namespace {

/// A message viewing `bytes` (not owned) with the given layout.
msg::Image imageMsg(std::vector<uint8_t>& bytes, uint32_t w, uint32_t h, uint32_t step,
                    const char* encoding) {
  msg::Image m{};
  m.width = w;
  m.height = h;
  m.step = step;
  m.encoding = const_cast<char*>(encoding);
  m.data = {static_cast<uint32_t>(bytes.size()), static_cast<uint32_t>(bytes.size()), bytes.data(), false};
  return m;
}

/// A smooth colour image (BGR) whose gray differs strongly under a red/blue swap.
cv::Mat colourful(int w, int h) {
  cv::Mat bgr(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      bgr.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<uchar>(20 + x % 40), static_cast<uchar>(60 + y % 30),
                                          static_cast<uchar>(230 - (x + y) % 25));
  cv::GaussianBlur(bgr, bgr, cv::Size(5, 5), 2);
  return bgr;
}

/// The Bayer mosaic of `bgr` whose top-left 2x2 block is `pattern` (e.g. "rggb").
cv::Mat mosaic(const cv::Mat& bgr, const std::string& pattern) {
  cv::Mat raw(bgr.size(), CV_8UC1);
  auto channel = [](char c) { return c == 'b' ? 0 : c == 'g' ? 1 : 2; };
  for (int y = 0; y < bgr.rows; ++y)
    for (int x = 0; x < bgr.cols; ++x)
      raw.at<uchar>(y, x) = bgr.at<cv::Vec3b>(y, x)[channel(pattern[static_cast<size_t>((y % 2) * 2 + x % 2)])];
  return raw;
}

}  // namespace

TEST(ImageConversion, Mono8IsViewedInPlace) {
  std::vector<uint8_t> px(64 * 48);
  for (size_t i = 0; i < px.size(); ++i) px[i] = static_cast<uint8_t>(i * 7);
  const msg::Image m = imageMsg(px, 64, 48, 64, "mono8");
  const GrayImage g = toGray(m);
  ASSERT_TRUE(g.ok()) << g.error;
  EXPECT_FALSE(g.copied);
  EXPECT_EQ(g.gray.data, px.data());  // no copy
  EXPECT_EQ(g.gray.type(), CV_8UC1);
  EXPECT_EQ(g.gray.at<uchar>(10, 5), px[10 * 64 + 5]);
}

TEST(ImageConversion, PaddedRowsAreHonoured) {
  std::vector<uint8_t> px(70 * 48, 0);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) px[static_cast<size_t>(y * 70 + x)] = static_cast<uint8_t>(x + y);
  const GrayImage g = toGray(imageMsg(px, 64, 48, 70, "mono8"));
  ASSERT_TRUE(g.ok()) << g.error;
  EXPECT_EQ(g.gray.cols, 64);
  EXPECT_EQ(g.gray.at<uchar>(47, 63), 63 + 47);
}

TEST(ImageConversion, ColourOrderFollowsTheEncoding) {
  const cv::Mat bgr = colourful(64, 48);
  cv::Mat want;
  cv::cvtColor(bgr, want, cv::COLOR_BGR2GRAY);
  cv::Mat rgb, bgra, rgba;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  cv::cvtColor(bgr, bgra, cv::COLOR_BGR2BGRA);
  cv::cvtColor(bgr, rgba, cv::COLOR_BGR2RGBA);
  const std::pair<cv::Mat, const char*> cases[] = {
      {bgr, "bgr8"}, {rgb, "rgb8"}, {bgra, "bgra8"}, {rgba, "rgba8"}};
  for (const auto& [img, enc] : cases) {
    std::vector<uint8_t> px(img.datastart, img.dataend);
    const GrayImage g = toGray(imageMsg(px, 64, 48, static_cast<uint32_t>(img.step[0]), enc));
    ASSERT_TRUE(g.ok()) << enc << ": " << g.error;
    EXPECT_TRUE(g.copied);
    EXPECT_LE(cv::norm(g.gray, want, cv::NORM_INF), 1) << enc;
  }
  // Read as the wrong order, the red-heavy image comes out clearly darker: the check can fail.
  std::vector<uint8_t> px(bgr.datastart, bgr.dataend);
  const GrayImage swapped = toGray(imageMsg(px, 64, 48, static_cast<uint32_t>(bgr.step[0]), "rgb8"));
  EXPECT_GT(cv::norm(swapped.gray, want, cv::NORM_L1) / want.total(), 30);
}

TEST(ImageConversion, BayerPatternsNameTheTopLeftBlock) {
  const cv::Mat bgr = colourful(64, 48);
  cv::Mat want;
  cv::cvtColor(bgr, want, cv::COLOR_BGR2GRAY);
  const cv::Rect inner(4, 4, 56, 40);  // demosaicing borders aside
  for (const std::string p : {"rggb", "bggr", "gbrg", "grbg"}) {
    cv::Mat raw = mosaic(bgr, p);
    std::vector<uint8_t> px(raw.datastart, raw.dataend);
    const std::string enc = "bayer_" + p + "8";
    const GrayImage g = toGray(imageMsg(px, 64, 48, 64, enc.c_str()));
    ASSERT_TRUE(g.ok()) << enc << ": " << g.error;
    const double err = cv::norm(g.gray(inner), want(inner), cv::NORM_L1) / inner.area();
    EXPECT_LT(err, 4.0) << enc;
    // The mosaic read as the pattern with red and blue exchanged is far off.
    std::string swapped = p;
    for (char& c : swapped) c = c == 'r' ? 'b' : c == 'b' ? 'r' : c;
    const std::string wrong = "bayer_" + swapped + "8";
    const GrayImage w = toGray(imageMsg(px, 64, 48, 64, wrong.c_str()));
    EXPECT_GT(cv::norm(w.gray(inner), want(inner), cv::NORM_L1) / inner.area(), 3 * err + 10) << wrong;
  }
}

// Each malformed image gives a one-line reason, never an exception or a crash.
TEST(ImageConversion, MalformedImagesAreRejectedWithAReason) {
  std::vector<uint8_t> px(64 * 48 * 3, 0);
  struct Case {
    uint32_t w, h, step;
    size_t bytes;
    const char* enc;
    const char* says;
  } cases[] = {
      {64, 48, 64, 64 * 48, "yuv422", "encoding 'yuv422' not supported"},
      {64, 48, 128, 64 * 48 * 2, "mono16", "encoding 'mono16' not supported"},
      {64, 48, 64, 64 * 48, "", "encoding '' not supported"},
      {64, 48, 64, 64 * 48 - 1, "mono8", "data has 3071 bytes, height 48 x step 64 = 3072"},
      {64, 48, 64, 64 * 48 + 64, "mono8", "data has 3136 bytes"},
      {64, 48, 63, 63 * 48, "mono8", "step 63 < width 64 x 1 bytes per pixel"},
      {64, 48, 64 * 2, 64 * 2 * 48, "rgb8", "step 128 < width 64 x 3 bytes per pixel"},
      {0, 48, 0, 0, "mono8", "empty image (0x48)"},
      {70000, 1, 70000, 70000, "mono8", "larger than 32768"},
      {1, 1, 1, 1, "bayer_rggb8", "smaller than 2x2"},
  };
  for (const Case& c : cases) {
    std::vector<uint8_t> bytes(c.bytes, 0);
    const GrayImage g = toGray(imageMsg(bytes, c.w, c.h, c.step, c.enc));
    EXPECT_FALSE(g.ok()) << c.enc;
    EXPECT_TRUE(g.gray.empty());
    EXPECT_NE(g.error.find(c.says), std::string::npos) << "'" << g.error << "' lacks '" << c.says << "'";
    EXPECT_EQ(g.error.find('\n'), std::string::npos);
  }
  // A null encoding string is not a crash either.
  msg::Image m = imageMsg(px, 64, 48, 64, "mono8");
  m.encoding = nullptr;
  EXPECT_FALSE(toGray(m).ok());
}

TEST(ImageConversion, OutgoingImagesBorrowThePixels) {
  cv::Mat img(30, 40, CV_8UC1, cv::Scalar(9));
  ImageOut out(img, 1.5, "cam");
  EXPECT_EQ(out.msg().data._buffer, img.data);
  EXPECT_EQ(std::string(out.msg().encoding), "mono8");
  EXPECT_EQ(out.msg().step, 40u);
  EXPECT_EQ(out.msg().data._length, 1200u);
  EXPECT_FALSE(out.msg().data._release);
  cv::Mat colour(30, 40, CV_8UC3, cv::Scalar(1, 2, 3));
  ImageOut c(colour, 1.5, "cam");
  EXPECT_EQ(std::string(c.msg().encoding), "bgr8");
  EXPECT_EQ(c.msg().step, 120u);
}

TEST(CameraInfoConversion, RoundTrip) {
  Intrinsics cam = Intrinsics::pinhole(640, 480, 551.5, 320.25, 241.75);
  cam.fy = 549.0;
  cam.dist = {-0.2, 0.05, 0.001, -0.0005, 0.01};
  CameraInfoOut out(cam, 2.0, "cam");
  std::string err;
  const auto back = toIntrinsics(out.msg(), &err);
  ASSERT_TRUE(back.has_value()) << err;
  EXPECT_EQ(back->width, 640);
  EXPECT_EQ(back->height, 480);
  EXPECT_DOUBLE_EQ(back->fx, 551.5);
  EXPECT_DOUBLE_EQ(back->fy, 549.0);
  EXPECT_DOUBLE_EQ(back->cx, 320.25);
  EXPECT_DOUBLE_EQ(back->cy, 241.75);
  for (int i = 0; i < 5; ++i) EXPECT_DOUBLE_EQ(back->dist[static_cast<size_t>(i)], cam.dist[static_cast<size_t>(i)]);
}

TEST(CameraInfoConversion, UnusableCameraInfoIsRejected) {
  const Intrinsics cam = Intrinsics::pinhole(640, 480, 550, 319.5, 239.5);
  std::string err;
  {
    CameraInfoOut o(cam, 0, "c");
    o.msg().k[0] = 0;
    EXPECT_FALSE(toIntrinsics(o.msg(), &err));
    EXPECT_NE(err.find("uncalibrated"), std::string::npos) << err;
  }
  {
    CameraInfoOut o(cam, 0, "c");
    o.msg().width = 0;
    EXPECT_FALSE(toIntrinsics(o.msg(), &err));
    EXPECT_NE(err.find("size"), std::string::npos) << err;
  }
  {
    CameraInfoOut o(cam, 0, "c");
    o.msg().distortion_model = const_cast<char*>("equidistant");
    EXPECT_FALSE(toIntrinsics(o.msg(), &err));
    EXPECT_NE(err.find("'equidistant' not supported"), std::string::npos) << err;
  }
  {
    CameraInfoOut o(cam, 0, "c");
    o.msg().d._length = 4;
    EXPECT_FALSE(toIntrinsics(o.msg(), &err));
    EXPECT_NE(err.find("plumb_bob needs 5"), std::string::npos) << err;
  }
  {
    CameraInfoOut o(cam, 0, "c");
    o.msg().binning_x = 2;
    EXPECT_FALSE(toIntrinsics(o.msg(), &err));
    EXPECT_NE(err.find("binning"), std::string::npos) << err;
  }
  {
    CameraInfoOut o(cam, 0, "c");
    o.msg().roi.width = 100;
    o.msg().roi.height = 100;
    EXPECT_FALSE(toIntrinsics(o.msg(), &err));
    EXPECT_NE(err.find("region of interest"), std::string::npos) << err;
  }
  {
    CameraInfoOut o(cam, 0, "c");
    o.msg().k[2] = NAN;
    EXPECT_FALSE(toIntrinsics(o.msg(), &err));
  }
}

TEST(TimeConversion, RoundTripAndCarry) {
  for (double t : {0.0, 1.5, 12.345678901, 1.7e9 + 0.25, -2.25}) {
    const msg::Time r = toRosTime(t);
    EXPECT_LT(r.nanosec, 1000000000u);
    EXPECT_NEAR(fromRosTime(r), t, 1e-9 * std::max(1.0, std::abs(t) * 1e-9) + 1e-9);
  }
  const msg::Time c = toRosTime(1.9999999999);
  EXPECT_EQ(c.sec, 2);
  EXPECT_EQ(c.nanosec, 0u);
  const msg::Time n = toRosTime(-2.25);
  EXPECT_EQ(n.sec, -3);
  EXPECT_EQ(n.nanosec, 750000000u);
  EXPECT_NEAR(fromRosDuration(toRosDuration(0.2)), 0.2, 1e-12);
}

TEST(PoseConversion, RoundTripWithCanonicalQuaternion) {
  for (const Eigen::Vector3d& rv : {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.3, -0.2, 0.1),
                                   Eigen::Vector3d(0, 3.1, 0), Eigen::Vector3d(-2.0, 1.0, 1.5)}) {
    const Pose p = Pose::fromRotationVector(rv, {1, -2, 0.5});
    const msg::Pose m = toRosPose(p);
    EXPECT_GE(m.orientation.w, 0);
    EXPECT_NEAR(std::hypot(std::hypot(m.orientation.x, m.orientation.y), std::hypot(m.orientation.z, m.orientation.w)), 1, 1e-12);
    const Pose q = fromRosPose(m);
    EXPECT_LT(rotationError(p, q), 1e-9);
    EXPECT_LT(translationError(p, q), 1e-12);
  }
  msg::Pose zero{};
  EXPECT_TRUE(fromRosPose(zero).R.isIdentity());
}

TEST(RobotTopicsTest, GripperPhasesSurviveTheJointEncoding) {
  using robot::GripperPhase;
  for (GripperPhase p : {GripperPhase::kOpen, GripperPhase::kClosing, GripperPhase::kClosedEmpty,
                         GripperPhase::kHolding, GripperPhase::kOpening})
    EXPECT_EQ(decodeGripper(encodeGripper(p)), p) << robot::toString(p);
  const RobotTopics t("/enon");
  EXPECT_EQ(t.cmd_vel, "/enon/cmd_vel");
  EXPECT_EQ(t.left_image, "/enon/left/image_raw");
  EXPECT_EQ(RobotTopics("/").joint_states, "/joint_states");
}
