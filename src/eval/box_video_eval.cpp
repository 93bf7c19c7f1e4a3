#include "eval/box_video_eval.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>
#include <opencv2/videoio.hpp>

#include "core/camera.h"
#include "core/error.h"
#include "core/file.h"
#include "detector/object.h"
#include "servo/replay.h"
#include "servo/tracker.h"

namespace refgrasp::eval {

namespace {

void need(bool ok, const char* field, const char* problem) {
  if (!ok) throw std::invalid_argument(std::string("BoxVideoOptions.") + field + ": " + problem);
}

/// cMo of a box of size_m fitted to one frame's labels (SQPnP, then Levenberg-Marquardt), and
/// the squared reprojection errors' sum.
Pose fitBoxPose(const BoxLabel& label, const Eigen::Vector3d& size_m, const cv::Matx33d& K, double* sum_sq_px) {
  std::vector<cv::Point3d> model;
  std::vector<cv::Point2d> image;
  for (const Eigen::Vector3d& p : boxLabelPoints(size_m)) model.emplace_back(p.x(), p.y(), p.z());
  for (const Eigen::Vector2d& p : label.corners_px) image.emplace_back(p.x(), p.y());
  cv::Mat r, t;
  cv::solvePnP(model, image, K, cv::noArray(), r, t, false, cv::SOLVEPNP_SQPNP);
  cv::solvePnP(model, image, K, cv::noArray(), r, t, true, cv::SOLVEPNP_ITERATIVE);
  std::vector<cv::Point2d> projected;
  cv::projectPoints(model, r, t, K, cv::noArray(), projected);
  *sum_sq_px = 0;
  for (size_t i = 0; i < image.size(); ++i) *sum_sq_px += std::pow(cv::norm(projected[i] - image[i]), 2);
  cv::Matx33d R;
  cv::Rodrigues(r, R);
  Pose cMo;
  for (int i = 0; i < 3; ++i) {
    cMo.t(i) = t.at<double>(i);
    for (int j = 0; j < 3; ++j) cMo.R(i, j) = R(i, j);
  }
  return cMo;
}

cv::Matx33d pinholeK(double f_px, int width, int height) {
  return {f_px, 0, (width - 1) / 2.0, 0, f_px, (height - 1) / 2.0, 0, 0, 1};
}

double rotationGapDeg(const Pose& a, const Pose& b) {
  return Eigen::AngleAxisd(a.R.transpose() * b.R).angle() * 180.0 / M_PI;
}

}  // namespace

void BoxVideoOptions::check() const {
  need(!video.empty(), "video", "is empty");
  need(!camera.empty(), "camera", "is empty");
  need(!object.empty(), "object", "is empty");
  need(box_size_m.allFinite() && box_size_m.minCoeff() > 0, "box_size_m", "must be > 0");
  need(max_frames >= 0, "max_frames", "must be >= 0");
  need(view_stride >= 0, "view_stride", "must be >= 0");
  need(std::isfinite(wrong_px) && wrong_px > 0, "wrong_px", "must be > 0");
  detector.check();
}

std::vector<BoxLabel> loadBoxLabels(const std::string& path) {
  std::vector<BoxLabel> labels;
  forEachLine(path, 1 << 20, 4096, [&](const TextLine& line) {
    const std::string text(line.text);
    const size_t start = text.find_first_not_of(" \t\r");
    if (start == std::string::npos || text[start] == '#') return true;
    std::istringstream in(text);
    BoxLabel label;
    in >> label.frame;
    for (Eigen::Vector2d& c : label.corners_px) in >> c.x() >> c.y();
    std::string rest;
    if (in.fail() || (in >> rest) || label.frame < 0 || !std::isfinite(label.corners_px[4].y()))
      throw ConfigError(path, "line " + std::to_string(line.number) +
                                  ": expected a frame number and 10 coordinates (A B C D F, u v each)");
    labels.push_back(label);
    return true;
  });
  return labels;
}

std::array<Eigen::Vector3d, 5> boxLabelPoints(const Eigen::Vector3d& s) {
  const double w = s.x() / 2, h = s.y() / 2, d = s.z();
  return {Eigen::Vector3d(-w, -h, 0), Eigen::Vector3d(w, -h, 0), Eigen::Vector3d(w, h, 0),
          Eigen::Vector3d(-w, h, 0), Eigen::Vector3d(w, -h, d)};
}

BoxVideoResult runBoxVideo(const BoxVideoOptions& opt) {
  opt.check();
  const Intrinsics camera = loadCameraFile(opt.camera);
  const detector::ObjectModel box = detector::loadObjectDefinition(opt.object);
  if (!box.isMultiView()) throw ConfigError(opt.object, "not a several-view object");
  const std::vector<BoxLabel> labels = opt.labels.empty() ? std::vector<BoxLabel>{} : loadBoxLabels(opt.labels);
  const std::array<Eigen::Vector3d, 5> points_o = boxLabelPoints(opt.box_size_m);

  // The pipeline, wired as pose_replay wires it.
  detector::Detector pipeline_detector(opt.detector);
  pipeline_detector.addObject(box);
  servo::ReplayOptions ropt;
  ropt.track = opt.track;
  servo::PoseReplay replay(pipeline_detector, ropt,
                           servo::planarTrackerFactory(ropt.pipeline.tracker, &pipeline_detector));
  // Each view as an object of its own.
  detector::Detector view_detector(opt.detector);
  BoxVideoResult out;
  for (const detector::ObjectView& v : box.views) {
    view_detector.addObject(*v.model);
    out.view_names.push_back(v.name);
  }
  out.view_found.assign(box.views.size(), 0);

  cv::VideoCapture video(opt.video, cv::CAP_FFMPEG);
  if (!video.isOpened()) throw ConfigError(opt.video, "cannot open as a video");
  robot::MonoFrame frame;
  const double fps = video.get(cv::CAP_PROP_FPS) > 0 ? video.get(cv::CAP_PROP_FPS) : 30.0;
  for (int k = 0; (opt.max_frames == 0 || k < opt.max_frames) && video.read(frame.image); ++k) {
    frame.index = k;
    frame.stamp = k / fps;
    const servo::ReplayFrame r = replay.process(k, frame, camera);
    ++out.frames;
    const servo::ObjectFrame& o = r.objects.at(0);
    ++(o.mode == servo::TrackMode::kDetect ? out.detect : o.mode == servo::TrackMode::kTrack ? out.track : out.lost);
    for (const BoxLabel& label : labels) {
      if (label.frame != k) continue;
      BoxLabelCheck c;
      c.frame = k;
      c.mode = o.mode;
      c.has_pose = o.cMo.has_value();
      if (c.has_pose) {
        for (size_t i = 0; i < points_o.size(); ++i) {
          const double e = (camera.project(*o.cMo * points_o[i]) - label.corners_px[i]).norm();
          c.corner_px[i] = e;
          c.max_px = std::max(c.max_px, e);
          c.mean_px += e / points_o.size();
        }
        if (c.mean_px > opt.wrong_px) ++out.wrong;
      }
      out.labelled.push_back(c);
    }

    if (opt.view_stride == 0 || k % opt.view_stride != 0) continue;
    ++out.view_frames;
    const detector::DetectionResult d = view_detector.detect(frame.image, camera, frame.frameStamp());
    std::vector<std::optional<Pose>> cMo(box.views.size());
    for (size_t v = 0; v < box.views.size(); ++v) {
      const std::optional<detector::Detection> best = d.find(static_cast<int>(v));
      if (!best || !best->found || !best->cMo) continue;
      ++out.view_found[v];
      cMo[v] = *best->cMo * box.views[v].oMv.inverse();
    }
    if (box.views.size() == 2 && cMo[0] && cMo[1]) {
      BoxViewAgreement a;
      a.frame = k;
      a.distance_m = (cMo[0]->t.norm() + cMo[1]->t.norm()) / 2;
      a.translation_m = (cMo[0]->t - cMo[1]->t).norm();
      a.rotation_deg = rotationGapDeg(*cMo[0], *cMo[1]);
      a.by_views = d.stats.at(0).views_matched || d.stats.at(1).views_matched;
      out.agreement.push_back(a);
    }
  }
  if (out.frames == 0) throw ConfigError(opt.video, "no frame decoded: nothing to do");
  return out;
}

BoxFit fitBoxToLabels(const std::vector<BoxLabel>& labels, double f_px, int image_width, int image_height) {
  if (labels.empty() || !(f_px > 0)) throw std::invalid_argument("fitBoxToLabels: no labels or f_px <= 0");
  const cv::Matx33d K = pinholeK(f_px, image_width, image_height);
  auto rms = [&](double h, double d) {
    double sum = 0;
    for (const BoxLabel& label : labels) {
      double s = 0;
      fitBoxPose(label, {1, h, d}, K, &s);
      sum += s;
    }
    return std::sqrt(sum / (5.0 * labels.size()));
  };
  // A 0.02 grid, then a 0.005 one within 0.02 of its best.
  BoxFit best{f_px, 0, 0, INFINITY};
  for (double step : {0.02, 0.005}) {
    const BoxFit coarse = best;
    for (int i = 0; 0.2 + i * step <= 0.5 + 1e-9; ++i) {
      for (int j = 0; 0.4 + j * step <= 1.0 + 1e-9; ++j) {
        const double h = 0.2 + i * step, d = 0.4 + j * step;
        if (step < 0.02 && (std::abs(h - coarse.h_over_w) > 0.02 + 1e-9 || std::abs(d - coarse.d_over_w) > 0.02 + 1e-9))
          continue;
        const double e = rms(h, d);
        if (e < best.rms_px) best = {f_px, h, d, e};
      }
    }
  }
  return best;
}

std::array<Eigen::Vector2d, 6> fittedBoxCorners(const BoxLabel& label, const Eigen::Vector3d& size_m,
                                                const Intrinsics& camera) {
  double unused = 0;
  const cv::Matx33d K(camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1);
  const Pose cMo = fitBoxPose(label, size_m, K, &unused);
  std::array<Eigen::Vector2d, 6> out;
  const std::array<Eigen::Vector3d, 5> p = boxLabelPoints(size_m);
  for (size_t i = 0; i < p.size(); ++i) out[i] = camera.project(cMo * p[i]);
  out[5] = camera.project(cMo * Eigen::Vector3d(-size_m.x() / 2, -size_m.y() / 2, size_m.z()));
  return out;
}

}  // namespace refgrasp::eval
