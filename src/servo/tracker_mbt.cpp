#include "servo/tracker_mbt.h"

#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <unistd.h>
#include <visp3/core/vpImageConvert.h>
#include <visp3/mbt/vpMbGenericTracker.h>

#include "servo/pose_conversions.h"

namespace refgrasp::servo {

namespace {

/// The pattern polygon as a ViSP .cao model (one face from its points, counter-clockwise as
/// seen from the camera side, -z of the pattern plane frame).
std::string caoModel(const detector::ObjectModel& object) {
  std::vector<Eigen::Vector3d> poly;
  for (const Eigen::Vector2d& px : object.pattern_polygon_px) {
    const Eigen::Vector2d und = object.camera ? object.camera->undistortPixel(px) : px;
    const auto X = object.target->backProject(und);
    if (!X) throw std::invalid_argument(object.name + ": pattern polygon vertex off the pattern plane");
    poly.push_back(*X);
  }
  std::string s = "V1\n# points\n" + std::to_string(poly.size()) + "\n";
  char buf[160];
  for (const auto& X : poly) {
    std::snprintf(buf, sizeof buf, "%.17g %.17g %.17g\n", X.x(), X.y(), X.z());
    s += buf;
  }
  s += "# lines\n0\n# faces from lines\n0\n# faces from points\n1\n" + std::to_string(poly.size());
  // Image order (TL, TR, BR, BL) is clockwise on screen; ViSP wants counter-clockwise.
  for (size_t i = poly.size(); i-- > 0;) s += " " + std::to_string(i);
  s += "\n# cylinders\n0\n# circles\n0\n";
  return s;
}

class MbtPlanarTracker : public FrameTracker {
 public:
  MbtPlanarTracker(const detector::ObjectModel& object, const TrackerOptions& opt)
      : object_(object), opt_(opt) {
    // vpMbGenericTracker reads its model from a file only: a private temporary file, removed at once.
    static std::atomic<int> counter{0};
    const std::filesystem::path path =
        std::filesystem::temp_directory_path() /
        ("refgrasp_mbt_" + std::to_string(::getpid()) + "_" + std::to_string(counter++) + ".cao");
    {
      std::ofstream f(path);
      f << caoModel(object);
      if (!f) throw std::invalid_argument(path.string() + ": cannot write the tracker model");
    }
    const int type = vpMbGenericTracker::KLT_TRACKER | (opt.mbt_edges ? vpMbGenericTracker::EDGE_TRACKER : 0);
    tracker_ = std::make_unique<vpMbGenericTracker>(1, type);
    // ViSP prints the model's element counts on std::cout even when not verbose.
    std::streambuf* out = std::cout.rdbuf(nullptr);
    try {
      tracker_->loadModel(path.string());
    } catch (const std::exception& e) {
      std::cout.rdbuf(out);
      std::filesystem::remove(path);
      throw std::invalid_argument(object.name + ": tracker model: " + e.what());
    }
    std::cout.rdbuf(out);
    std::filesystem::remove(path);
    vpKltOpencv klt;
    klt.setMaxFeatures(opt.max_features);
    klt.setWindowSize(opt.klt_window_px);
    klt.setQuality(opt.feature_quality);
    klt.setMinDistance(opt.feature_min_distance_px);
    klt.setHarrisFreeParameter(0.04);
    klt.setBlockSize(7);
    klt.setPyramidLevels(opt.klt_pyramid_levels);
    tracker_->setKltOpencv(klt);
    tracker_->setKltMaskBorder(static_cast<unsigned>(std::ceil(opt.pattern_border_px)));
    if (opt.mbt_edges) {
      vpMe me;
      me.setMaskSize(5);
      me.setMaskNumber(180);
      me.setRange(8);
      me.setThreshold(10000);
      me.setMu1(0.5);
      me.setMu2(0.5);
      me.setSampleStep(4);
      tracker_->setMovingEdge(me);
    }
    tracker_->setAngleAppear(vpMath::rad(85));
    tracker_->setAngleDisappear(vpMath::rad(89));
    tracker_->setNearClippingDistance(0.01);
    tracker_->setFarClippingDistance(100);
    tracker_->setClipping(tracker_->getClipping() | vpPolygon3D::FOV_CLIPPING);
  }

  TrackStep start(const cv::Mat& gray, const Intrinsics& cam, const Pose& cMo) override {
    TrackStep s;
    s.cMo = cMo;
    running_ = false;
    try {
      setCamera(cam);
      toVispImage(gray, cam);
      tracker_->initFromPose(I_, toVisp(cMo));
      return finish(cam, cMo, true);
    } catch (const std::exception& e) {
      s.lost_reason = std::string("tracker start failed: ") + e.what();
      return s;
    }
  }

  /// predicted_cMo is not used: vpMbGenericTracker::setPose would re-seed the KLT features.
  TrackStep track(const cv::Mat& gray, const Intrinsics& cam, const std::optional<Pose>&) override {
    TrackStep s;
    if (!running_) {
      s.lost_reason = "not started";
      return s;
    }
    try {
      setCamera(cam);
      toVispImage(gray, cam);
      tracker_->track(I_);
      vpHomogeneousMatrix M;
      tracker_->getPose(M);
      return finish(cam, fromVisp(M), false);
    } catch (const std::exception& e) {
      running_ = false;
      s.lost_reason = std::string("tracking failed: ") + e.what();
      return s;
    }
  }

 private:
  TrackStep finish(const Intrinsics& cam, const Pose& cMo, bool starting) {
    TrackStep s;
    s.cMo = cMo;
    s.quality.features = static_cast<int>(tracker_->getKltNbPoints());
    if (starting) started_ = s.quality.features;
    s.quality.features_started = started_;
    const vpColVector err = tracker_->getError();
    double sq = 0;
    for (unsigned i = 0; i < err.size(); ++i) sq += err[i] * err[i];
    // KLT residuals are normalised image coordinates, two per feature.
    s.quality.projection_error_px =
        err.size() > 0 ? std::sqrt(2 * sq / err.size()) * 0.5 * (cam.fx + cam.fy) : 0;
    s.quality.visible_fraction = visibleFraction(object_, cMo, cam);
    char buf[128];
    if (!cMo.isFinite()) {
      s.lost_reason = "pose not finite";
    } else if (s.quality.features < opt_.min_features) {
      std::snprintf(buf, sizeof buf, "too few features (%d < %d)", s.quality.features, opt_.min_features);
      s.lost_reason = buf;
    } else if (!starting && s.quality.features < opt_.min_feature_fraction * started_) {
      std::snprintf(buf, sizeof buf, "too few features (%d < %.3g)", s.quality.features,
                    opt_.min_feature_fraction * started_);
      s.lost_reason = buf;
    } else if (s.quality.projection_error_px > opt_.max_projection_error_px) {
      std::snprintf(buf, sizeof buf, "projection error px (%.3g > %.3g)", s.quality.projection_error_px,
                    opt_.max_projection_error_px);
      s.lost_reason = buf;
    } else if (s.quality.visible_fraction < opt_.min_visible_fraction) {
      std::snprintf(buf, sizeof buf, "pattern out of view (%.3g < %.3g)", s.quality.visible_fraction,
                    opt_.min_visible_fraction);
      s.lost_reason = buf;
    } else {
      s.ok = true;
    }
    running_ = s.ok;
    return s;
  }

  void setCamera(const Intrinsics& cam) {
    if (cam.fx == cam_.fx && cam.fy == cam_.fy && cam.cx == cam_.cx && cam.cy == cam_.cy &&
        cam.width == cam_.width && cam.height == cam_.height && cam.dist == cam_.dist)
      return;
    cam_ = cam;
    tracker_->setCameraParameters(vpCameraParameters(cam.fx, cam.fy, cam.cx, cam.cy));
    map_x_.release();
    map_y_.release();
    if (cam.hasDistortion()) {
      // ViSP's distortion model is not OpenCV's: track on the ideal pinhole image.
      map_x_.create(cam.height, cam.width, CV_32FC1);
      map_y_.create(cam.height, cam.width, CV_32FC1);
      for (int v = 0; v < cam.height; ++v)
        for (int u = 0; u < cam.width; ++u) {
          const Eigen::Vector2d d =
              cam.distortNormalized(Eigen::Vector2d((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy));
          map_x_.at<float>(v, u) = static_cast<float>(d.x());
          map_y_.at<float>(v, u) = static_cast<float>(d.y());
        }
    }
  }

  void toVispImage(const cv::Mat& gray, const Intrinsics& cam) {
    cv::Mat g = gray;
    if (cam.hasDistortion()) cv::remap(gray, g, map_x_, map_y_, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    vpImageConvert::convert(g, I_);
  }

  const detector::ObjectModel& object_;
  TrackerOptions opt_;
  std::unique_ptr<vpMbGenericTracker> tracker_;
  vpImage<unsigned char> I_;
  Intrinsics cam_;
  cv::Mat map_x_, map_y_;
  int started_ = 0;
  bool running_ = false;
};

}  // namespace

std::unique_ptr<FrameTracker> makeMbtTracker(const detector::ObjectModel& object,
                                             const TrackerOptions& options) {
  return std::make_unique<MbtPlanarTracker>(object, options);
}

}  // namespace refgrasp::servo
