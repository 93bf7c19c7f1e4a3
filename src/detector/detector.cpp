#include "detector/detector.h"

#include <chrono>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/geometry.h"
#include "detector/homography.h"

namespace refgrasp::detector {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

void undistortKeypoints(std::vector<cv::KeyPoint>* kps, const Intrinsics& cam) {
  if (!cam.hasDistortion()) return;
  for (auto& k : *kps) {
    const Eigen::Vector2d u = cam.undistortPixel(Eigen::Vector2d(k.pt.x, k.pt.y));
    k.pt = cv::Point2f(static_cast<float>(u.x()), static_cast<float>(u.y()));
  }
}

// Undistorted pixel -> real image pixel.
Eigen::Vector2d distortPixel(const Intrinsics& cam, const Eigen::Vector2d& und) {
  if (!cam.hasDistortion()) return und;
  return cam.distortNormalized(Eigen::Vector2d((und.x() - cam.cx) / cam.fx,
                                               (und.y() - cam.cy) / cam.fy));
}

}  // namespace

void DetectorOptions::check() const {
  sift.check();
  match.check();
  pose_options.check();
  dense.check();
  sanity.check();
}

const Detection* DetectionResult::find(int object, int instance) const {
  for (const auto& d : detections)
    if (d.found && d.object == object && d.instance == instance) return &d;
  return nullptr;
}

Detector::Detector(DetectorOptions opt) : opt_(std::move(opt)) { opt_.check(); }

int Detector::addObject(const ObjectModel& object) {
  if (object.reference.empty() || object.reference.type() != CV_8UC1)
    throw ConfigError(object.source.empty() ? object.name : object.source, "reference_image",
                      "expected a non-empty 8-bit grayscale image");
  Entry e;
  e.model = object;
  Features f = extractSift(object.reference, opt_.sift);
  std::vector<Eigen::Vector2d> polygon = object.pattern_polygon_px;
  if (object.camera) {
    undistortKeypoints(&f.keypoints, *object.camera);
    for (auto& p : polygon) p = object.camera->undistortPixel(p);
  }
  for (int i = 0; i < 4; ++i)
    e.corners_und_px[i] =
        object.camera ? object.camera->undistortPixel(object.corners_px[i]) : object.corners_px[i];
  e.index = buildReferenceIndex(std::move(f), polygon, opt_.match);
  // Dense refinement needs an undistorted reference whose pattern region is its bounding box.
  if (object.target && (!object.camera || !object.camera->hasDistortion())) {
    double minx = 1e300, miny = 1e300, maxx = -1e300, maxy = -1e300;
    for (const Eigen::Vector2d& p : polygon) {
      minx = std::min(minx, p.x()), maxx = std::max(maxx, p.x());
      miny = std::min(miny, p.y()), maxy = std::max(maxy, p.y());
    }
    if (std::abs(signedArea(polygon)) >= 0.98 * (maxx - minx) * (maxy - miny))
      e.pyramid = buildReferencePyramid(object.reference);
  }
  objects_.push_back(std::move(e));
  return static_cast<int>(objects_.size()) - 1;
}

std::string Detector::validateImage(const cv::Mat& image, const Intrinsics& camera) {
  if (image.empty()) return "empty image";
  if (image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3 &&
                                 image.channels() != 4))
    return "unsupported pixel type (expected 8-bit gray, BGR or BGRA)";
  try {
    camera.check();
  } catch (const std::invalid_argument& e) {
    return std::string("invalid camera: ") + e.what();
  }
  if (image.cols != camera.width || image.rows != camera.height)
    return "image size " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
           " differs from the camera's " + std::to_string(camera.width) + "x" +
           std::to_string(camera.height);
  return "";
}

Features Detector::extract(const cv::Mat& gray, const Intrinsics& camera) const {
  Features f = extractSift(gray, opt_.sift);
  undistortKeypoints(&f.keypoints, camera);
  if (gray.type() == CV_8UC1) f.image = gray;
  return f;
}

DenseRefineResult Detector::refineDense(const Entry& e, const Eigen::Matrix3d& H,
                                        const cv::Mat& image, const Intrinsics& camera) const {
  if (!camera.hasDistortion())
    return refineHomographyDense(e.pyramid, image, H, e.corners_und_px, opt_.dense);
  // H lives in undistorted pixels: resample only the pattern's neighbourhood of the image onto
  // the ideal pinhole grid (never the whole frame), refine there, and move H back.
  Eigen::Vector2d lo(1e9, 1e9), hi(-1e9, -1e9);
  for (const auto& c : e.corners_und_px) {
    const Eigen::Vector2d p = applyHomography(H, c);
    if (!p.allFinite()) return {};
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double margin = opt_.dense.max_corner_shift_px + 8;
  const int x0 = static_cast<int>(std::floor(lo.x() - margin));
  const int y0 = static_cast<int>(std::floor(lo.y() - margin));
  const int w = static_cast<int>(std::ceil(hi.x() + margin)) - x0 + 1;
  const int h = static_cast<int>(std::ceil(hi.y() + margin)) - y0 + 1;
  if (w <= 0 || h <= 0 || w > 4 * camera.width || h > 4 * camera.height) return {};
  cv::Mat mapx(h, w, CV_32FC1), mapy(h, w, CV_32FC1);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      const Eigen::Vector2d d = camera.distortNormalized(
          Eigen::Vector2d((x0 + u - camera.cx) / camera.fx, (y0 + v - camera.cy) / camera.fy));
      mapx.at<float>(v, u) = static_cast<float>(d.x());
      mapy.at<float>(v, u) = static_cast<float>(d.y());
    }
  cv::Mat crop;
  cv::remap(image, crop, mapx, mapy, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  Eigen::Matrix3d T = Eigen::Matrix3d::Identity();  // undistorted px -> crop px
  T(0, 2) = -x0;
  T(1, 2) = -y0;
  DenseRefineResult r =
      refineHomographyDense(e.pyramid, crop, T * H, e.corners_und_px, opt_.dense);
  r.H = T.inverse() * r.H;
  return r;
}

PoseResult Detector::estimatePose(int object, const MatchCandidate& match, const Features& scene,
                                  const Intrinsics& camera, PoseMethod method) const {
  const Entry& e = objects_.at(object);
  if (!e.model.target) return {};
  const PlanarTarget& target = *e.model.target;
  if (method == PoseMethod::kPaper)
    return estimatePosePaper(match.H, target, camera.K(), opt_.pose_options);
  if (opt_.dense.enabled && !e.pyramid.empty() && !scene.image.empty()) {
    const DenseRefineResult dr = refineDense(e, match.H, scene.image, camera);
    if (dr.ok) {
      // Pose from a grid of pattern points mapped by the refined H.
      const int n = opt_.dense.pose_grid;
      std::vector<Eigen::Vector3d> X;
      std::vector<Eigen::Vector2d> y;
      const auto& c = e.corners_und_px;
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
          const double a = (i + 0.5) / n, b = (j + 0.5) / n;
          const Eigen::Vector2d r =
              (1 - b) * ((1 - a) * c[0] + a * c[1]) + b * ((1 - a) * c[3] + a * c[2]);
          const auto Xo = target.backProject(r);
          if (!Xo) continue;
          X.push_back(*Xo);
          y.push_back(applyHomography(dr.H, r));
        }
      const PoseResult p = estimatePoseRefined(X, y, target, camera.K(), opt_.pose_options);
      if (p.ok) return p;
    }
  }
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> y;
  std::vector<double> sigma;
  X.reserve(match.inliers.size());
  y.reserve(match.inliers.size());
  const double k = opt_.pose_options.keypoint_sigma_per_size;
  for (const auto& c : match.inliers) {
    const cv::Point2f& pr = e.index.features.keypoints[c.ref].pt;
    const auto Xo = target.backProject(Eigen::Vector2d(pr.x, pr.y));
    if (!Xo) continue;
    const cv::KeyPoint& ks = scene.keypoints[c.scene];
    X.push_back(*Xo);
    y.emplace_back(ks.pt.x, ks.pt.y);
    if (k > 0) sigma.push_back(std::max(0.05, k * ks.size));
  }
  return estimatePoseRefined(X, y, target, camera.K(), opt_.pose_options, sigma);
}

DetectionResult Detector::detect(const cv::Mat& image, const Intrinsics& camera) const {
  const auto t0 = Clock::now();
  DetectionResult res;
  res.error = validateImage(image, camera);
  if (!res.error.empty()) {
    res.ok = false;
    return res;
  }
  cv::Mat gray = image;
  if (image.channels() == 3) cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  if (image.channels() == 4) cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  res = detectGray(gray, camera);
  res.time_ms.total = msSince(t0);
  return res;
}

DetectionResult Detector::detectGray(const cv::Mat& gray, const Intrinsics& camera) const {
  DetectionResult res;
  auto t = Clock::now();
  const Features scene = extract(gray, camera);
  const GridIndex grid(scene.keypoints, scene.image_size);
  res.time_ms.extract = msSince(t);
  res.scene_features = scene.size();

  for (int id = 0; id < objectCount(); ++id) {
    const Entry& e = objects_[id];
    t = Clock::now();
    const MatchResult m = matchObject(e.index, scene, grid, opt_.match);
    res.time_ms.match += msSince(t);

    t = Clock::now();
    int found = 0;
    SanityStatus rejected = SanityStatus::kOk;
    for (const MatchCandidate& cand : m.instances) {
      Detection d;
      d.object = id;
      d.H = cand.H;
      d.inliers = static_cast<int>(cand.inliers.size());
      d.score = cand.score;
      if (e.model.target) {
        const PoseResult p = estimatePose(id, cand, scene, camera, opt_.pose);
        if (!p.ok) {
          rejected = SanityStatus::kNotFinite;
          continue;
        }
        d.cMo = p.cMo;
        d.pose_rms_px = p.rms_px;
        for (int i = 0; i < 4; ++i) d.corners[i] = camera.project(p.cMo * e.model.target->corners_o[i]);
      } else {
        for (int i = 0; i < 4; ++i)
          d.corners[i] = distortPixel(camera, applyHomography(cand.H, e.corners_und_px[i]));
      }
      d.sanity = checkDetection(d.corners, d.cMo, camera.width, camera.height, opt_.sanity);
      if (d.sanity != SanityStatus::kOk) {
        if (found == 0) rejected = d.sanity;
        continue;
      }
      d.found = true;
      d.instance = found++;
      res.detections.push_back(d);
    }
    if (found == 0) {
      res.detections.emplace_back();
      res.detections.back().object = id;
      res.detections.back().sanity = rejected;
    }
    res.time_ms.pose += msSince(t);
  }
  return res;
}

StereoDetectionResult Detector::detectStereo(const cv::Mat& left, const cv::Mat& right,
                                             const StereoRig& rig) const {
  StereoDetectionResult out;
  out.left = detect(left, rig.left);
  out.right = detect(right, rig.right);
  if (!out.left.ok || !out.right.ok) {
    out.ok = false;
    out.error = !out.left.ok ? "left: " + out.left.error : "right: " + out.right.error;
    return out;
  }
  for (int id = 0; id < objectCount(); ++id) {
    StereoDetection s;
    s.object = id;
    s.left.object = s.right.object = id;
    if (const Detection* d = out.left.find(id)) s.left = *d;
    if (const Detection* d = out.right.find(id)) s.right = *d;
    s.fused = fuseStereo(s.left.found ? s.left.cMo : std::nullopt,
                         s.right.found ? s.right.cMo : std::nullopt, rig);
    // 2D-only objects: report the eyes that saw them even without a pose.
    if (!objects_[id].model.target && s.fused.eyes == EyesUsed::kNone) {
      if (s.left.found && s.right.found) s.fused.eyes = EyesUsed::kBoth;
      else if (s.left.found) s.fused.eyes = EyesUsed::kLeft;
      else if (s.right.found) s.fused.eyes = EyesUsed::kRight;
    }
    out.objects.push_back(s);
  }
  return out;
}

}  // namespace refgrasp::detector
