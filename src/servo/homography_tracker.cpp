#include "servo/homography_tracker.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <stdexcept>

namespace refgrasp::servo {

namespace {

Eigen::Vector2d mapH(const Eigen::Matrix3d& H, const Eigen::Vector2d& x) {
  const Eigen::Vector3d y = H * x.homogeneous();
  return y.hnormalized();
}

Eigen::Vector2d toImage(const Intrinsics& cam, const Eigen::Vector2d& und) {
  if (!cam.hasDistortion()) return und;
  return cam.distortNormalized(Eigen::Vector2d((und.x() - cam.cx) / cam.fx, (und.y() - cam.cy) / cam.fy));
}

Eigen::Vector2d toUndistorted(const Intrinsics& cam, const Eigen::Vector2d& px) {
  return cam.hasDistortion() ? cam.undistortPixel(px) : px;
}

/// Fraction of the quad's area (image px) inside the image; 0 when it is not convex.
double quadInView(const std::array<Eigen::Vector2d, 4>& q, const Intrinsics& cam) {
  std::vector<cv::Point2f> quad, frame{{0, 0}, {static_cast<float>(cam.width), 0},
                                       {static_cast<float>(cam.width), static_cast<float>(cam.height)},
                                       {0, static_cast<float>(cam.height)}};
  for (const auto& p : q) quad.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  if (!cv::isContourConvex(quad)) return 0;
  const double area = std::abs(cv::contourArea(quad));
  if (!(area > 1)) return 0;
  std::vector<cv::Point2f> inter;
  const double in = cv::intersectConvexConvex(quad, frame, inter, true);
  return std::clamp(in / area, 0.0, 1.0);
}

}  // namespace

std::array<Eigen::Vector2d, 4> cornersUnderH(const Eigen::Matrix3d& H,
                                             const std::array<Eigen::Vector2d, 4>& corners_ref,
                                             const Intrinsics& camera) {
  std::array<Eigen::Vector2d, 4> c;
  for (size_t i = 0; i < 4; ++i) c[i] = toImage(camera, mapH(H, corners_ref[i]));
  return c;
}

struct HomographyTracker::Impl {
  TrackerOptions opt;
  HomographyAligner align;
  std::array<Eigen::Vector2d, 4> corners_ref;  ///< undistorted reference px
  std::vector<Eigen::Vector2d> polygon_ref;    ///< undistorted reference px
  bool active = false;
  Eigen::Matrix3d H = Eigen::Matrix3d::Identity();
  std::vector<cv::Mat> prev_pyr;
  std::vector<cv::Point2f> pts;            ///< image px in the previous frame
  std::vector<Eigen::Vector2d> anchors;    ///< their undistorted reference px
  int features_started = 0;
  int unaligned = 0;

  std::vector<cv::Mat> pyramid(const cv::Mat& gray) const {
    std::vector<cv::Mat> pyr;
    const int levels = std::max(opt.klt_pyramid_levels, opt.klt_retry_pyramid_levels);
    cv::buildOpticalFlowPyramid(gray, pyr, cv::Size(opt.klt_window_px, opt.klt_window_px), levels);
    return pyr;
  }

  /// The pattern region under H, shrunk by pattern_border_px, as a mask of the image.
  cv::Mat patternMask(const Intrinsics& cam, const cv::Size& size) const {
    cv::Mat mask = cv::Mat::zeros(size, CV_8UC1);
    std::vector<cv::Point> poly;
    for (const auto& r : polygon_ref) {
      const Eigen::Vector2d p = toImage(cam, mapH(H, r));
      if (!p.allFinite()) return mask;
      poly.emplace_back(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
    }
    cv::fillPoly(mask, std::vector<std::vector<cv::Point>>{poly}, cv::Scalar(255));
    const int b = static_cast<int>(std::ceil(opt.pattern_border_px));
    if (b > 0) cv::erode(mask, mask, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * b + 1, 2 * b + 1)));
    return mask;
  }

  /// Seeds features in the pattern under H, away from those kept, up to max_features in all.
  void seed(const cv::Mat& gray, const Intrinsics& cam) {
    cv::Mat mask = patternMask(cam, gray.size());
    const int r = static_cast<int>(std::ceil(opt.feature_min_distance_px));
    for (const cv::Point2f& k : pts) cv::circle(mask, k, r, cv::Scalar(0), cv::FILLED);
    const int wanted = opt.max_features - static_cast<int>(pts.size());
    if (wanted <= 0 || cv::countNonZero(mask) == 0) return;
    std::vector<cv::Point2f> found;
    cv::goodFeaturesToTrack(gray, found, wanted, opt.feature_quality, opt.feature_min_distance_px, mask, 7, false,
                            0.04);
    // A small pattern holds too few features at that spacing: seed it again, 3 px apart.
    const double close_px = std::min(3.0, opt.feature_min_distance_px);
    if (static_cast<int>(found.size() + pts.size()) < opt.min_features && close_px < opt.feature_min_distance_px) {
      found.clear();
      cv::goodFeaturesToTrack(gray, found, wanted, opt.feature_quality, close_px, mask, 7, false, 0.04);
    }
    if (found.empty()) return;
    cv::cornerSubPix(gray, found, cv::Size(5, 5), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 0.03));
    const Eigen::Matrix3d Hinv = H.inverse();
    for (const cv::Point2f& f : found) {
      const Eigen::Vector2d a = mapH(Hinv, toUndistorted(cam, Eigen::Vector2d(f.x, f.y)));
      if (!a.allFinite()) continue;
      pts.push_back(f);
      anchors.push_back(a);
    }
    features_started = static_cast<int>(pts.size());
  }

  HomographyStep lose(HomographyStep s, const std::string& why) {
    active = false;
    s.ok = false;
    s.lost_reason = why;
    return s;
  }

  HomographyStep result(const TrackQuality& q, const Intrinsics& cam) const {
    HomographyStep s;
    s.ok = true;
    s.H = H;
    s.corners = cornersUnderH(H, corners_ref, cam);
    s.quality = q;
    return s;
  }

  HomographyStep start(const cv::Mat& gray, const Intrinsics& cam, const Eigen::Matrix3d& H0) {
    HomographyStep s;
    active = false;
    pts.clear();
    anchors.clear();
    unaligned = 0;
    if (!H0.allFinite() || std::abs(H0.determinant()) < 1e-12) return lose(s, "degenerate homography");
    H = H0;
    seed(gray, cam);
    s.quality.features = s.quality.features_started = features_started;
    s.quality.visible_fraction = quadInView(cornersUnderH(H, corners_ref, cam), cam);
    if (features_started < opt.min_features)
      return lose(s, "too few features (" + std::to_string(features_started) + " < " +
                         std::to_string(opt.min_features) + ")");
    prev_pyr = pyramid(gray);
    active = true;
    return result(s.quality, cam);
  }

  /// KLT from the previous frame, each feature starting where `guess` maps its anchor; keeps
  /// the features KLT followed with a small window error. Returns the kept ones' positions.
  std::vector<cv::Point2f> follow(const std::vector<cv::Mat>& pyr, const Intrinsics& cam, const Eigen::Matrix3d& guess) {
    std::vector<cv::Point2f> next(pts.size());
    for (size_t i = 0; i < pts.size(); ++i) {
      const Eigen::Vector2d g = toImage(cam, mapH(guess, anchors[i]));
      next[i] = g.allFinite() ? cv::Point2f(static_cast<float>(g.x()), static_cast<float>(g.y())) : pts[i];
    }
    std::vector<uchar> status;
    std::vector<float> err;
    cv::calcOpticalFlowPyrLK(prev_pyr, pyr, pts, next, status, err, cv::Size(opt.klt_window_px, opt.klt_window_px),
                             opt.klt_pyramid_levels,
                             cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 0.03),
                             cv::OPTFLOW_USE_INITIAL_FLOW);
    std::vector<float> e;
    for (size_t i = 0; i < status.size(); ++i)
      if (status[i]) e.push_back(err[i]);
    float limit = static_cast<float>(opt.klt_max_error);
    if (!e.empty()) {
      std::nth_element(e.begin(), e.begin() + static_cast<long>(e.size() / 2), e.end());
      limit = std::max(limit, 3 * e[e.size() / 2]);
    }
    std::vector<cv::Point2f> kept;
    std::vector<Eigen::Vector2d> kept_anchors;
    for (size_t i = 0; i < status.size(); ++i)
      if (status[i] && err[i] <= limit) {
        kept.push_back(next[i]);
        kept_anchors.push_back(anchors[i]);
      }
    anchors = std::move(kept_anchors);
    return kept;
  }

  /// Robust H (anchors -> undistorted image px) from the followed features; drops the outliers.
  std::optional<Eigen::Matrix3d> fitFeatures(std::vector<cv::Point2f>* cur, const Intrinsics& cam) {
    if (static_cast<int>(cur->size()) < std::max(opt.min_features, 4)) return std::nullopt;
    std::vector<cv::Point2f> src, dst;
    for (size_t i = 0; i < cur->size(); ++i) {
      const Eigen::Vector2d u = toUndistorted(cam, Eigen::Vector2d((*cur)[i].x, (*cur)[i].y));
      src.emplace_back(static_cast<float>(anchors[i].x()), static_cast<float>(anchors[i].y()));
      dst.emplace_back(static_cast<float>(u.x()), static_cast<float>(u.y()));
    }
    std::vector<uchar> inlier;
    // Deterministic: OpenCV's RANSAC draws from a fixed-seed generator.
    cv::Mat Hcv = cv::findHomography(src, dst, cv::RANSAC, opt.inlier_threshold_px, inlier, 2000, 0.999);
    if (Hcv.empty()) return std::nullopt;
    std::vector<cv::Point2f> kept;
    std::vector<Eigen::Vector2d> kept_anchors;
    for (size_t i = 0; i < inlier.size(); ++i)
      if (inlier[i]) {
        kept.push_back((*cur)[i]);
        kept_anchors.push_back(anchors[i]);
      }
    *cur = std::move(kept);
    anchors = std::move(kept_anchors);
    Eigen::Matrix3d Hf;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) Hf(r, c) = Hcv.at<double>(r, c);
    if (!Hf.allFinite()) return std::nullopt;
    return Hf;
  }

  /// RMS distance (undistorted px) of the features from where H maps their anchors.
  double featureRms(const std::vector<cv::Point2f>& cur, const Intrinsics& cam, const Eigen::Matrix3d& Hm) const {
    double sum = 0;
    for (size_t i = 0; i < cur.size(); ++i)
      sum += (mapH(Hm, anchors[i]) - toUndistorted(cam, Eigen::Vector2d(cur[i].x, cur[i].y))).squaredNorm();
    return cur.empty() ? 0 : std::sqrt(sum / static_cast<double>(cur.size()));
  }

  HomographyStep track(const cv::Mat& gray, const Intrinsics& cam, const std::optional<Eigen::Matrix3d>& pred);
};

HomographyStep HomographyTracker::Impl::track(const cv::Mat& gray, const Intrinsics& cam,
                                              const std::optional<Eigen::Matrix3d>& pred) {
  HomographyStep s;
  if (!active) return lose(s, "not started");
  const std::vector<cv::Mat> pyr = pyramid(gray);
  const Eigen::Matrix3d guess = pred && pred->allFinite() ? *pred : H;
  std::vector<cv::Point2f> cur = follow(pyr, cam, guess);
  TrackQuality& q = s.quality;
  q.features_started = features_started;
  const std::optional<Eigen::Matrix3d> Hf = fitFeatures(&cur, cam);
  q.features = static_cast<int>(cur.size());
  const int need = std::max(opt.min_features, static_cast<int>(std::ceil(opt.min_feature_fraction * features_started)));
  if (!Hf || q.features < need)
    return lose(s, "too few features (" + std::to_string(q.features) + " < " + std::to_string(need) + ")");
  q.projection_error_px = featureRms(cur, cam, *Hf);
  if (!(q.projection_error_px <= opt.max_projection_error_px))
    return lose(s, "feature error " + std::to_string(q.projection_error_px) + " px");
  q.visible_fraction = quadInView(cornersUnderH(*Hf, corners_ref, cam), cam);
  if (q.visible_fraction < opt.min_visible_fraction) return lose(s, "pattern out of view");
  Eigen::Matrix3d Hn = *Hf;
  if (align) {
    const detector::HomographyAlignment a = align(gray, cam, *Hf);
    q.correlation = a.correlation;
    q.aligned_fraction = a.used_fraction;
    const double rms = a.ok ? featureRms(cur, cam, a.H) : 0;
    q.aligned = a.ok && rms <= opt.align_max_feature_rms_px;
    if (q.aligned && a.used_fraction < opt.min_aligned_fraction)
      return lose(s, "aligned fraction " + std::to_string(a.used_fraction) + " < " +
                         std::to_string(opt.min_aligned_fraction));
    if (q.aligned) {
      Hn = a.H;
      unaligned = 0;
    } else if (++unaligned >= opt.max_unaligned_frames) {
      return lose(s, a.ok ? "the features disagree with the alignment (" + std::to_string(rms) + " px RMS > " +
                                std::to_string(opt.align_max_feature_rms_px) + ")"
                          : "not aligned with the reference (correlation " + std::to_string(a.correlation) +
                                ", corner shift " + std::to_string(a.corner_shift_px) + " px)");
    }
  }
  H = Hn;
  // Re-anchor: each feature's reference pixel is where the (aligned) H puts it now, so KLT's
  // frame-to-frame slide does not accumulate in the anchors.
  const Eigen::Matrix3d Hinv = H.inverse();
  for (size_t i = 0; i < cur.size(); ++i)
    anchors[i] = mapH(Hinv, toUndistorted(cam, Eigen::Vector2d(cur[i].x, cur[i].y)));
  pts = std::move(cur);
  if (static_cast<double>(pts.size()) < opt.reseed_fraction * opt.max_features) seed(gray, cam);
  prev_pyr = pyr;
  return result(q, cam);
}

HomographyTracker::HomographyTracker(const detector::ObjectModel& object, const TrackerOptions& options,
                                     HomographyAligner align)
    : p_(std::make_unique<Impl>()) {
  options.check();
  if (object.isMultiView() || object.isCylinder() || object.reference.empty())
    throw std::invalid_argument(object.name + ": the homography tracker follows one planar reference image");
  p_->opt = options;
  p_->align = std::move(align);
  for (size_t i = 0; i < 4; ++i)
    p_->corners_ref[i] = object.camera ? object.camera->undistortPixel(object.corners_px[i]) : object.corners_px[i];
  for (const auto& v : object.pattern_polygon_px)
    p_->polygon_ref.push_back(object.camera ? object.camera->undistortPixel(v) : v);
  if (p_->polygon_ref.empty()) p_->polygon_ref.assign(p_->corners_ref.begin(), p_->corners_ref.end());
}

HomographyTracker::~HomographyTracker() = default;

HomographyStep HomographyTracker::start(const cv::Mat& gray, const Intrinsics& camera, const Eigen::Matrix3d& H) {
  try {
    return p_->start(gray, camera, H);
  } catch (const std::exception& e) {  // OpenCV, out of memory
    HomographyStep s;
    p_->active = false;
    s.lost_reason = std::string("tracking failed: ") + e.what();
    return s;
  }
}

HomographyStep HomographyTracker::track(const cv::Mat& gray, const Intrinsics& camera,
                                        const std::optional<Eigen::Matrix3d>& predicted_H) {
  try {
    return p_->track(gray, camera, predicted_H);
  } catch (const std::exception& e) {
    HomographyStep s;
    p_->active = false;
    s.lost_reason = std::string("tracking failed: ") + e.what();
    return s;
  }
}

std::unique_ptr<HomographyTracker> makeHomographyTracker(const detector::Detector& detector, int id,
                                                         const TrackerOptions& options) {
  detector::DenseRefineOptions dense = detector.options().dense;
  dense.max_corner_shift_px = options.align_max_corner_shift_px;
  dense.min_correlation = options.align_min_correlation;
  dense.robust = true;
  dense.max_template_px = options.align_max_template_px;
  HomographyAligner align;
  if (options.align_to_reference)
    align = [&detector, id, dense](const cv::Mat& gray, const Intrinsics& cam, const Eigen::Matrix3d& H) {
      return detector.alignHomography(gray, cam, id, H, &dense);
    };
  return std::make_unique<HomographyTracker>(detector.object(id), options, std::move(align));
}

}  // namespace refgrasp::servo
