// The vision component in-process on a private domain: poses of rendered frames against ground
// truth, the detect service, malformed input, the newest-frame policy, stereo, several objects,
// a 2D-only object's corners.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <mutex>

#include "component/vision_component.h"
#include "component_test_util.h"
#include "robot/dds/dds_test_util.h"
#include "robot/sim/synthetic_sequence.h"
#include "servo/two_d_sequence.h"

using namespace refgrasp;
using namespace refgrasp::testing;
using component::VisionComponent;
using component::VisionComponentOptions;

namespace {

constexpr double kDeg = M_PI / 180;
const char* kTexture = "targets/cereal_box.png";
const char* kTexture2 = "targets/tea_box.png";

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

class Component : public ::testing::Test {
 protected:
  void SetUp() override {
    useLoopbackDds();
    domain_ = privateDomain();
    ns_ = privateNamespace("vc");
  }
  /// A component on this test's domain; warnings are collected in warnings().
  std::unique_ptr<VisionComponent> start(std::vector<detector::ObjectModel> objects,
                                         std::optional<StereoRig> rig = std::nullopt,
                                         double warning_period_s = 5, bool track = false) {
    detector::Detector det;
    for (const auto& o : objects) det.addObject(o);
    VisionComponentOptions o;
    o.domain = domain_;
    o.ns = ns_;
    o.stereo = rig;
    o.warning_period_s = warning_period_s;
    o.track = track;
    return std::make_unique<VisionComponent>(std::move(det), o, [this](const std::string& w) {
      std::lock_guard<std::mutex> l(mu_);
      warnings_.push_back(w);
    });
  }
  std::vector<std::string> warnings() {
    std::lock_guard<std::mutex> l(mu_);
    return warnings_;
  }

  int domain_ = 0;
  std::string ns_;
  std::mutex mu_;
  std::vector<std::string> warnings_;
};

}  // namespace

TEST_F(Component, PosesOfRenderedFramesMatchGroundTruth) {
  auto c = start({target("cereal_box", kTexture)});
  dds::Participant pp(domain_);
  CameraPublisher cam(pp, ns_);
  InfoListener infos(pp, ns_);
  dds::Reader<dds::msg::PoseStamped> poses(pp, dds::ddsTopicName(ns_ + "/object_pose"), dds::QosProfile::reliable(50));
  dds::Reader<dds::msg::Detection3DArray> dets(pp, dds::ddsTopicName(ns_ + "/detections"), dds::QosProfile::reliable(50));
  ASSERT_TRUE(cam.waitForComponent(10));
  const int kFrames = 6;
  std::vector<double> latency_ms;
  const double t_start = now();
  for (int i = 0; i < kFrames; ++i) {
    const Frame f = renderFrame(kTexture, 1000 + i);
    const Seconds stamp = 100.0 + i * 0.1;
    const double t0 = now();
    const auto r = publishUntilAnswered(cam, infos, f.image, stamp, "cereal_box", "camera_optical_frame");
    latency_ms.push_back((now() - t0) * 1e3);
    ASSERT_TRUE(r.has_value()) << "frame " << i;
    ASSERT_TRUE(r->found) << "frame " << i;
    EXPECT_LT(rotationError(r->cMo, f.cMo), 1 * kDeg) << "frame " << i;
    EXPECT_LT(translationError(r->cMo, f.cMo), 0.01 * f.cMo.t.norm()) << "frame " << i;
    EXPECT_GT(r->inliers, 10);
    EXPECT_EQ(r->frame, "camera_optical_frame");
    // object_pose and detections carry the same pose and the image's header.
    dds::Sample<dds::msg::PoseStamped> ps;
    ASSERT_TRUE(waitUntil([&] { return poses.takeNewest(&ps) > 0; }, 3));
    EXPECT_EQ(InfoListener::key(dds::fromRosTime(ps->header.stamp)), InfoListener::key(stamp));
    EXPECT_EQ(std::string(ps->header.frame_id), "camera_optical_frame");
    EXPECT_LT(rotationError(dds::fromRosPose(ps->pose), f.cMo), 1 * kDeg);
    dds::Sample<dds::msg::Detection3DArray> da;
    ASSERT_TRUE(waitUntil([&] { return dets.takeNewest(&da) > 0; }, 3));
    ASSERT_EQ(da->detections._length, 1u);
    const dds::msg::Detection3D& d = da->detections._buffer[0];
    ASSERT_EQ(d.results._length, 1u);
    EXPECT_EQ(std::string(d.results._buffer[0].hypothesis.class_id), "cereal_box");
    EXPECT_EQ(std::string(d.id), "cereal_box#0");
    EXPECT_NEAR(d.bbox.size.x, kTargetWidth, 1e-3);
    // The box centre is the pattern centre: the object origin for a texture object.
    EXPECT_LT(translationError(dds::fromRosPose(d.bbox.center), f.cMo), 0.01 * f.cMo.t.norm());
  }
  const double elapsed = now() - t_start;
  const auto s = c->stats();
  std::sort(latency_ms.begin(), latency_ms.end());
  std::printf("component: %d frames in %.2f s (publish -> object_info, one at a time: median %.1f ms); "
              "detector median %.1f ms, component overhead median %.2f ms\n",
              kFrames, elapsed, latency_ms[latency_ms.size() / 2], s.detect_ms_median, s.overhead_ms_median);
  EXPECT_GE(s.processed, kFrames);
  EXPECT_EQ(s.rejected, 0);
}

// --track: the robot's pipeline in the component. The first detection is not published (not
// confirmed yet), the next confirms it, then the frames are tracked (no detector run) and every
// frame gets a pose within the detector's tolerances.
TEST_F(Component, TrackingPublishesConfirmedPosesOnEveryFrame) {
  TrackingSequenceSpec spec;
  spec.frames = 24;
  spec.texture = kTexture;
  spec.width_m = kTargetWidth;
  spec.path = [](double t) { return orbitPath(0.25 + 0.25 * t); };  // 1.1 -> 0.4 m, tilting
  const TrackingSequence seq = renderTrackingSequence(spec);
  auto c = start({target("cereal_box", kTexture)}, std::nullopt, 5, /*track=*/true);
  dds::Participant pp(domain_);
  CameraPublisher cam(pp, ns_);
  InfoListener infos(pp, ns_);
  ASSERT_TRUE(cam.waitForComponent(10));
  std::string found;
  for (size_t k = 0; k < seq.mono.size(); ++k) {
    const Seconds stamp = 200.0 + 0.05 * static_cast<double>(k);
    const auto r = publishUntilAnswered(cam, infos, seq.mono[k].image, stamp, "cereal_box");
    ASSERT_TRUE(r.has_value()) << "frame " << k;
    found += r->found ? '1' : '0';
    if (!r->found) continue;
    EXPECT_LT(rotationError(r->cMo, seq.truth[k]), 1 * kDeg) << "frame " << k;
    EXPECT_LT(translationError(r->cMo, seq.truth[k]), 0.01 * seq.truth[k].t.norm()) << "frame " << k;
    EXPECT_GT(r->inliers, 10) << "frame " << k;
  }
  const auto s = c->stats();
  std::printf("--track: found %s; %ld frames processed, %ld tracked only; pipeline median %.2f ms\n",
              found.c_str(), s.processed, s.tracked, s.detect_ms_median);
  EXPECT_EQ(found, "0" + std::string(seq.mono.size() - 1, '1'));
  EXPECT_GE(s.tracked, static_cast<long>(seq.mono.size()) - 4);
  EXPECT_EQ(s.rejected, 0);
}

TEST_F(Component, DetectServiceAnswersWithinItsTimeout) {
  auto c = start({target("cereal_box", kTexture)});
  dds::Participant pp(domain_);
  DetectClient client(pp, ns_ + "/detect");
  ASSERT_TRUE(client.waitForService(10));
  CameraPublisher cam(pp, ns_);
  ASSERT_TRUE(cam.waitForComponent(10));

  // Before any frame: the latest result is "none yet".
  auto r = callDetect(client, "cereal_box", 0, 5);
  ASSERT_TRUE(r.has_value());
  EXPECT_FALSE((*r)->found);
  EXPECT_STREQ((*r)->error, "no frame received yet");

  // An unknown object: an error reply at once.
  double t0 = now();
  r = callDetect(client, "x", 0, 5);
  ASSERT_TRUE(r.has_value());
  EXPECT_LT(now() - t0, 1.0);
  EXPECT_FALSE((*r)->found);
  EXPECT_STREQ((*r)->error, "unknown object 'x'");
  r = callDetect(client, "cereal_box", -1, 5);
  ASSERT_TRUE(r.has_value());
  EXPECT_NE(std::string((*r)->error).find("timeout_s"), std::string::npos);

  // No frame within the timeout: found = false after about the timeout.
  t0 = now();
  r = callDetect(client, "cereal_box", 0.5, 5);
  const double waited = now() - t0;
  ASSERT_TRUE(r.has_value());
  EXPECT_FALSE((*r)->found);
  EXPECT_NE(std::string((*r)->error).find("timeout"), std::string::npos) << (*r)->error;
  EXPECT_GT(waited, 0.45);
  EXPECT_LT(waited, 1.5);

  // A frame arriving while the call waits: its result, within the timeout.
  const Frame f = renderFrame(kTexture, 77);
  std::thread pub([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    for (int i = 0; i < 5; ++i) {
      cam.publish(f.image, 50.0 + i, "camera_optical_frame");
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
  });
  t0 = now();
  r = callDetect(client, "cereal_box", 8, 10);
  const double took = now() - t0;
  pub.join();
  ASSERT_TRUE(r.has_value());
  EXPECT_LT(took, 8);
  EXPECT_TRUE((*r)->found) << (*r)->error;
  EXPECT_STREQ((*r)->error, "");
  Pose P;
  for (int k = 0; k < 9; ++k) P.R(k / 3, k % 3) = (*r)->rotation[k];
  for (int k = 0; k < 3; ++k) P.t[k] = (*r)->translation[k];
  EXPECT_LT(rotationError(P, f.cMo), 1 * kDeg);
  EXPECT_LT(translationError(P, f.cMo), 0.01 * f.cMo.t.norm());

  // And now the latest result is that pose.
  r = callDetect(client, "cereal_box", 0, 5);
  ASSERT_TRUE(r.has_value());
  EXPECT_TRUE((*r)->found);
  EXPECT_GE(c->stats().requests, 6);
}

// Every kind of bad frame: found = false on object_info, one warning naming the problem, and the
// component keeps serving (a good frame afterwards is found).
TEST_F(Component, MalformedFramesGiveFoundFalseAWarningAndServingGoesOn) {
  auto c = start({target("cereal_box", kTexture)});
  dds::Participant pp(domain_);
  CameraPublisher cam(pp, ns_);
  InfoListener infos(pp, ns_);
  ASSERT_TRUE(cam.waitForComponent(10));
  const Frame good = renderFrame(kTexture, 5);
  const std::string frame = "camera_optical_frame";
  Seconds stamp = 10;

  // Sends `m` (image layout already set up) until the component answers for its stamp.
  auto send = [&](const std::function<void(dds::msg::Image&)>& mangle, bool with_info = true,
                  const Intrinsics& info_cam = sceneCamera(), const std::string& info_frame = "camera_optical_frame") {
    stamp += 1;
    std::optional<InfoListener::Info> r;
    for (int attempt = 0; attempt < 20 && !r; ++attempt) {
      if (with_info) cam.publishInfo(info_cam, stamp, info_frame);
      dds::ImageOut img(good.image, stamp, frame);
      dds::msg::Image m = img.msg();
      mangle(m);
      dds::Writer<dds::msg::Image> const& w = cam.imageWriter();
      w.write(m);
      r = infos.waitFor(stamp, "cereal_box", 2);
    }
    return r;
  };
  auto lastWarning = [&] {
    const auto w = warnings();
    return w.empty() ? std::string() : w.back();
  };
  auto keep = [](dds::msg::Image&) {};

  // No camera_info yet.
  auto r = send(keep, false);
  ASSERT_TRUE(r.has_value());
  EXPECT_FALSE(r->found);
  EXPECT_NE(lastWarning().find("no camera_info received on " + ns_ + "/camera_info"), std::string::npos)
      << lastWarning();

  struct Case {
    const char* what;
    std::function<void(dds::msg::Image&)> mangle;
    const char* says;
  };
  std::vector<uint8_t> short_data(good.image.total() - 7);
  std::vector<uint8_t> pad_data(good.image.total() + 640);
  const std::vector<Case> cases = {
      {"unsupported encoding", [](dds::msg::Image& m) { m.encoding = const_cast<char*>("yuv422"); },
       "encoding 'yuv422' not supported"},
      {"16-bit", [](dds::msg::Image& m) { m.encoding = const_cast<char*>("mono16"); }, "encoding 'mono16'"},
      {"data size", [&](dds::msg::Image& m) { m.data = {static_cast<uint32_t>(short_data.size()), static_cast<uint32_t>(short_data.size()), short_data.data(), false}; },
       "data has 307193 bytes, height 480 x step 640 = 307200"},
      // The same kind of problem as the previous one (the message up to its numbers): no new
      // warning within the period.
      {"too much data", [&](dds::msg::Image& m) { m.data = {static_cast<uint32_t>(pad_data.size()), static_cast<uint32_t>(pad_data.size()), pad_data.data(), false}; },
       nullptr},
      {"step", [](dds::msg::Image& m) { m.step = 600; m.data._length = 600 * 480; }, "step 600 < width 640 x 1 bytes per pixel"},
      {"colour step", [](dds::msg::Image& m) { m.encoding = const_cast<char*>("rgb8"); }, "step 640 < width 640 x 3 bytes per pixel"},
  };
  for (const Case& k : cases) {
    const size_t before = warnings().size();
    r = send(k.mangle);
    ASSERT_TRUE(r.has_value()) << k.what;
    EXPECT_FALSE(r->found) << k.what;
    if (!k.says) {
      EXPECT_EQ(warnings().size(), before) << k.what << ": " << lastWarning();
      continue;
    }
    EXPECT_EQ(warnings().size(), before + 1) << k.what;
    EXPECT_NE(lastWarning().find(k.says), std::string::npos) << k.what << ": " << lastWarning();
    EXPECT_NE(lastWarning().find(ns_ + "/image_raw"), std::string::npos) << lastWarning();
  }
  // camera_info of another size.
  r = send(keep, true, Intrinsics::pinhole(320, 240, 275, 159.5, 119.5));
  ASSERT_TRUE(r.has_value());
  EXPECT_FALSE(r->found);
  EXPECT_NE(lastWarning().find("camera_info is 320x240 but " + ns_ + "/image_raw is 640x480"), std::string::npos)
      << lastWarning();
  // An image whose frame has no camera_info (the camera_info is for another frame).
  r = send(keep, true, sceneCamera(), "other_frame");
  ASSERT_TRUE(r.has_value());
  EXPECT_FALSE(r->found);
  EXPECT_NE(lastWarning().find("frame 'camera_optical_frame' has no camera_info"), std::string::npos)
      << lastWarning();
  EXPECT_NE(lastWarning().find("is for frame 'other_frame'"), std::string::npos) << lastWarning();
  // Uncalibrated camera_info.
  Intrinsics zero = sceneCamera();
  zero.fx = 0;
  r = send(keep, true, zero);
  ASSERT_TRUE(r.has_value());
  EXPECT_FALSE(r->found);
  EXPECT_NE(lastWarning().find("uncalibrated"), std::string::npos) << lastWarning();

  // Still serving.
  r = send(keep);
  ASSERT_TRUE(r.has_value());
  EXPECT_TRUE(r->found);
  EXPECT_LT(rotationError(r->cMo, good.cMo), 1 * kDeg);
  const auto s = c->stats();
  EXPECT_GE(s.rejected, 10);
  for (const auto& w : warnings()) EXPECT_EQ(w.find('\n'), std::string::npos);

  // Rate limit: the same problem again and again gives no new warning within the period.
  const size_t n = warnings().size();
  for (int i = 0; i < 4; ++i) {
    r = send([](dds::msg::Image& m) { m.encoding = const_cast<char*>("yuv422"); });
    ASSERT_TRUE(r.has_value());
    EXPECT_FALSE(r->found);
  }
  EXPECT_EQ(warnings().size(), n);
}

// Frames that come faster than the detector are dropped, not queued: the newest one is processed.
TEST_F(Component, NewestFrameWinsAndDropsAreCounted) {
  auto c = start({target("cereal_box", kTexture)});
  dds::Participant pp(domain_);
  CameraPublisher cam(pp, ns_);
  InfoListener infos(pp, ns_);
  ASSERT_TRUE(cam.waitForComponent(10));
  // Make sure the component has matched us (a first frame comes back).
  const Frame f = renderFrame(kTexture, 9);
  std::optional<InfoListener::Info> r = publishUntilAnswered(cam, infos, f.image, 1.0, "cereal_box");
  ASSERT_TRUE(r.has_value());
  // Every frame taken so far processed or dropped: on a loaded machine publishUntilAnswered may
  // have sent a second frame that is still in the detector when the first one's answer arrives.
  const auto quiet = [&c] {
    for (int i = 0; i < 400; ++i) {
      const auto s = c->stats();
      if (s.processed + s.dropped == s.received) return s;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return c->stats();
  };
  const auto before = quiet();
  const int kBurst = 30;
  for (int i = 0; i < kBurst; ++i) {
    cam.publish(f.image, 2.0 + i * 0.01, "camera");
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  const Seconds last = 2.0 + (kBurst - 1) * 0.01;
  r = infos.waitFor(last, "cereal_box", 20);
  ASSERT_TRUE(r.has_value()) << "the newest frame was not processed";
  EXPECT_TRUE(r->found);
  // Quiet: every frame taken was processed or dropped.
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const auto s = quiet();
  const long received = s.received - before.received, processed = s.processed - before.processed,
             dropped = s.dropped - before.dropped;
  EXPECT_LE(received, kBurst);
  EXPECT_EQ(processed + dropped, received);
  EXPECT_GT(dropped, 0);
  EXPECT_LT(processed, kBurst / 2) << "frames were queued, not dropped";
  // Fewer results than frames: one object_info per processed frame, the burst mostly unanswered.
  std::printf("burst of %d frames: %ld taken, %ld processed, %ld dropped\n", kBurst, received, processed, dropped);
}

TEST_F(Component, StereoPairsAreFusedInTheLeftFrame) {
  StereoRig rig;
  rig.left = rig.right = sceneCamera();
  rig.lMr = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.12, 0, 0));
  auto c = start({target("cereal_box", kTexture)}, rig);
  dds::Participant pp(domain_);
  CameraPublisher left(pp, ns_ + "/left"), right(pp, ns_ + "/right");
  InfoListener infos(pp, ns_);
  ASSERT_TRUE(left.waitForComponent(10));
  ASSERT_TRUE(right.waitForComponent(10));
  const cv::Mat tex = loadMedia(kTexture);
  const double h = kTargetWidth * tex.rows / tex.cols;
  const Pose lMo = Pose::fromRotationVector({0.2, -0.3, 0.05}, {0.03, 0.01, 0.7});
  SceneSpec sl, sr;
  sl.cMo = lMo;
  sr.cMo = rig.lMr.inverse() * lMo;
  sl.seed = 3;
  sr.seed = 4;
  const cv::Mat L = renderTarget(sceneCamera(), tex, kTargetWidth, h, sl).image;
  const cv::Mat R = renderTarget(sceneCamera(), tex, kTargetWidth, h, sr).image;
  std::optional<InfoListener::Info> r;
  for (int attempt = 0; attempt < 20 && !r; ++attempt) {
    const Seconds stamp = 20.0 + attempt;
    // An unpaired right image first, then the pair.
    right.publish(R, stamp - 0.5, "right");
    std::this_thread::sleep_for(std::chrono::milliseconds(100));  // keep last 1: let it be taken
    left.publish(L, stamp, "left");
    right.publish(R, stamp, "right");
    r = infos.waitFor(stamp, "cereal_box", 3);
  }
  ASSERT_TRUE(r.has_value());
  ASSERT_TRUE(r->found);
  EXPECT_EQ(r->frame, "left");
  EXPECT_LT(rotationError(r->cMo, lMo), 1 * kDeg);
  EXPECT_LT(translationError(r->cMo, lMo), 0.01 * lMo.t.norm());
  EXPECT_GT(c->stats().unpaired, 0);
}

TEST_F(Component, SeveralObjectsEachGetObjectInfo) {
  auto c = start({target("cereal_box", kTexture), target("tea_box", kTexture2)});
  dds::Participant pp(domain_);
  CameraPublisher cam(pp, ns_);
  InfoListener infos(pp, ns_);
  dds::Reader<dds::msg::PoseStamped> poses(pp, dds::ddsTopicName(ns_ + "/object_pose"), dds::QosProfile::reliable(50));
  ASSERT_TRUE(cam.waitForComponent(10));
  // Only the second object is in view: object_pose (the first object's) stays silent.
  const Frame f = renderFrame(kTexture2, 31);
  std::optional<InfoListener::Info> a, b;
  for (int attempt = 0; attempt < 20 && !b; ++attempt) {
    cam.publish(f.image, 30.0 + attempt, "camera");
    b = infos.waitFor(30.0 + attempt, "tea_box", 3);
    a = infos.waitFor(30.0 + attempt, "cereal_box", 1);
  }
  ASSERT_TRUE(a.has_value());
  ASSERT_TRUE(b.has_value());
  EXPECT_FALSE(a->found);
  EXPECT_TRUE(b->found);
  EXPECT_LT(rotationError(b->cMo, f.cMo), 1 * kDeg);
  dds::Sample<dds::msg::PoseStamped> ps;
  EXPECT_EQ(poses.takeNewest(&ps), 0);
}

// A 2D-only object (no reference_pose) with --track: its result is object_corners alone. The
// first detection is not published (not confirmed), the next confirms it, then the tracker
// follows with no detector run; corners within a fraction of a pixel of the truth, the
// homography maps the reference's pattern corners onto them; object_info says found = false
// and the service says why.
TEST_F(Component, TwoDOnlyObjectIsTrackedOnObjectCorners) {
  const TrackingSequence seq = twoDSequence(30, 200, 7);
  auto c = start({twoDModel()}, std::nullopt, 5, /*track=*/true);
  dds::Participant pp(domain_);
  CameraPublisher cam(pp, ns_);
  InfoListener infos(pp, ns_);
  CornersListener corners(pp, ns_);
  DetectClient client(pp, ns_ + "/detect");
  ASSERT_TRUE(cam.waitForComponent(10));
  ASSERT_TRUE(client.waitForService(10));
  std::string found, tracked;
  std::vector<double> errors;
  for (size_t k = 0; k < seq.mono.size(); ++k) {
    const Seconds stamp = 300.0 + 0.05 * static_cast<double>(k);
    const auto info = publishUntilAnswered(cam, infos, seq.mono[k].image, stamp, "target");
    ASSERT_TRUE(info.has_value()) << "frame " << k;
    EXPECT_FALSE(info->found) << "frame " << k << ": a 2D-only object has no pose";
    const auto r = corners.waitFor(stamp, "target", 3);
    ASSERT_TRUE(r.has_value()) << "frame " << k;
    found += r->found ? '1' : '0';
    tracked += r->tracked ? '1' : '0';
    if (!r->found) continue;
    const auto truth = twoDTruthCorners(seq, k);
    errors.push_back(cornerError(r->corners, truth));
    EXPECT_GT(r->inliers, 10) << "frame " << k;
    std::array<Eigen::Vector2d, 4> mapped;
    for (size_t i = 0; i < 4; ++i) mapped[i] = (r->H * twoDModel().corners_px[i].homogeneous()).hnormalized();
    EXPECT_LT(cornerError(mapped, r->corners), 0.01) << "frame " << k;
  }
  const auto s = c->stats();
  std::printf("2D-only --track: found %s, tracked %s; corner error median %.3f px, max %.3f px\n", found.c_str(),
              tracked.c_str(), quantile(errors, 0.5), quantile(errors, 1.0));
  EXPECT_EQ(found, "0" + std::string(seq.mono.size() - 1, '1'));
  EXPECT_EQ(tracked, "00" + std::string(seq.mono.size() - 2, '1'));
  EXPECT_GE(s.tracked, static_cast<long>(seq.mono.size()) - 4);
  // The tracker's own figures are 0.03 px median, 0.05 px max (HomographyTracking tests).
  EXPECT_LT(quantile(errors, 0.5), 0.15);
  EXPECT_LT(quantile(errors, 1.0), 0.3);
  const auto reply = callDetect(client, "target", 0, 5);
  ASSERT_TRUE(reply.has_value());
  EXPECT_FALSE((*reply)->found);
  EXPECT_EQ(std::string((*reply)->error),
            "target is 2D-only (no reference_pose): no pose; its corners are on " + ns_ + "/object_corners");
}

// Without --track every frame's detection is published at once: found, not tracked.
TEST_F(Component, TwoDOnlyObjectIsDetectedOnObjectCorners) {
  const TrackingSequence seq = twoDSequence(3, 200, 7);
  auto c = start({twoDModel()});
  dds::Participant pp(domain_);
  CameraPublisher cam(pp, ns_);
  InfoListener infos(pp, ns_);
  CornersListener corners(pp, ns_);
  ASSERT_TRUE(cam.waitForComponent(10));
  for (size_t k = 0; k < seq.mono.size(); ++k) {
    const Seconds stamp = 400.0 + 0.05 * static_cast<double>(k);
    ASSERT_TRUE(publishUntilAnswered(cam, infos, seq.mono[k].image, stamp, "target").has_value()) << "frame " << k;
    const auto r = corners.waitFor(stamp, "target", 3);
    ASSERT_TRUE(r.has_value()) << "frame " << k;
    EXPECT_TRUE(r->found) << "frame " << k;
    EXPECT_FALSE(r->tracked) << "frame " << k;
    // The single-frame detector on such sequences: 0.06 px median, 0.15 px p90 (TrackingDrift).
    EXPECT_LT(cornerError(r->corners, twoDTruthCorners(seq, k)), 0.5) << "frame " << k;
    EXPECT_GT(r->inliers, 10) << "frame " << k;
  }
}

TEST_F(Component, RejectsBadOptionsAndObjectsAtStartUp) {
  detector::Detector det;
  det.addObject(target("cereal_box", kTexture));
  VisionComponentOptions o;
  o.domain = 233;
  EXPECT_THROW(VisionComponent(detector::Detector(det), o), std::invalid_argument);
  o.domain = domain_;
  o.ns = "refgrasp";
  EXPECT_THROW(VisionComponent(detector::Detector(det), o), std::invalid_argument);
  o.ns = ns_;
  // A 2D-only object: no pose to fuse in stereo (mono serves its corners).
  detector::Detector flat;
  flat.addObject(detector::makeObjectModel("flat", loadMedia(kTexture), std::nullopt, std::nullopt));
  o.stereo = StereoRig{sceneCamera(), sceneCamera(), Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.12, 0, 0))};
  EXPECT_THROW(VisionComponent(std::move(flat), o), std::invalid_argument);
  o.stereo.reset();
  EXPECT_THROW(VisionComponent(detector::Detector(), o), std::invalid_argument);
}
