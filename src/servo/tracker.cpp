#include "servo/tracker.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <opencv2/video/tracking.hpp>
#include <utility>

#include "detector/pose.h"
#include "servo/surface_model.h"
#include "servo/tracker_mbt.h"

namespace refgrasp::servo {

const char* trackerMethodName(TrackerMethod m) {
  return m == TrackerMethod::kMbt ? "mbt" : "klt";
}

void TrackerOptions::check() const {
  auto need = [](bool ok, const char* field, const char* problem) {
    if (!ok) throw std::invalid_argument(std::string("TrackerOptions.") + field + ": " + problem);
  };
  need(min_features >= 4, "min_features", "must be >= 4");
  need(std::isfinite(min_feature_fraction) && min_feature_fraction >= 0 && min_feature_fraction <= 1,
       "min_feature_fraction", "must be in [0, 1]");
  need(std::isfinite(max_projection_error_px) && max_projection_error_px > 0,
       "max_projection_error_px", "must be > 0");
  need(std::isfinite(min_visible_fraction) && min_visible_fraction >= 0 && min_visible_fraction <= 1,
       "min_visible_fraction", "must be in [0, 1]");
  need(max_features >= min_features, "max_features", "must be >= min_features");
  need(std::isfinite(seed_min_facing_cos) && seed_min_facing_cos >= 0 && seed_min_facing_cos < 1,
       "seed_min_facing_cos", "must be in [0, 1)");
  need(std::isfinite(feature_quality) && feature_quality > 0 && feature_quality < 1,
       "feature_quality", "must be in (0, 1)");
  need(std::isfinite(feature_min_distance_px) && feature_min_distance_px >= 1,
       "feature_min_distance_px", "must be >= 1");
  need(klt_window_px >= 5 && klt_window_px % 2 == 1 && klt_window_px <= 101, "klt_window_px",
       "must be odd, 5..101");
  need(klt_pyramid_levels >= 0 && klt_pyramid_levels <= 6, "klt_pyramid_levels", "must be 0..6");
  need(klt_retry_pyramid_levels >= 0 && klt_retry_pyramid_levels <= 6, "klt_retry_pyramid_levels",
       "must be 0..6");
  need(std::isfinite(shift_search_px) && shift_search_px >= 1 && shift_search_px <= 1000,
       "shift_search_px", "must be 1..1000");
  need(std::isfinite(shift_min_score) && shift_min_score >= 0 && shift_min_score <= 1,
       "shift_min_score", "must be 0..1");
  need(std::isfinite(pattern_border_px) && pattern_border_px >= 0, "pattern_border_px", "must be >= 0");
  need(std::isfinite(inlier_threshold_px) && inlier_threshold_px > 0, "inlier_threshold_px",
       "must be > 0");
  need(std::isfinite(reseed_fraction) && reseed_fraction >= 0 && reseed_fraction <= 1,
       "reseed_fraction", "must be in [0, 1]");
  need(pose_iterations >= 1 && pose_iterations <= 100, "pose_iterations", "must be 1..100");
  need(std::isfinite(appearance_search_px) && appearance_search_px >= 1 && appearance_search_px <= 50,
       "appearance_search_px", "must be 1..50");
  need(std::isfinite(appearance_min_score) && appearance_min_score >= 0 && appearance_min_score <= 1,
       "appearance_min_score", "must be 0..1");
  need(max_unaligned_frames >= 1, "max_unaligned_frames", "must be >= 1");
  need(std::isfinite(klt_max_error) && klt_max_error > 0, "klt_max_error", "must be > 0");
  need(std::isfinite(min_aligned_fraction) && min_aligned_fraction >= 0 && min_aligned_fraction <= 1,
       "min_aligned_fraction", "must be in [0, 1]");
  need(std::isfinite(align_max_feature_rms_px) && align_max_feature_rms_px > 0,
       "align_max_feature_rms_px", "must be > 0");
  need(std::isfinite(align_max_corner_shift_px) && align_max_corner_shift_px > 0,
       "align_max_corner_shift_px", "must be > 0");
  need(align_max_template_px >= 64, "align_max_template_px", "must be >= 64");
  need(std::isfinite(align_min_correlation) && align_min_correlation >= -1 && align_min_correlation < 1,
       "align_min_correlation", "must be in [-1, 1)");
}

namespace {

std::string lostLine(const char* what, double value, const char* op, double limit) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "%s (%.3g %s %.3g)", what, value, op, limit);
  return buf;
}

/// The detector's alignment (Detector::alignPose) aligns a planar pattern with its reference
/// image; a cylinder's label or several views have no such single plane.
bool alignable(const detector::ObjectModel& object) {
  return object.has3d() && !object.isCylinder() && !object.isMultiView();
}

/// A frame features were seeded in, and the pose they were anchored with.
struct SeenIn {
  cv::Mat gray;
  Pose cMo;
};

/// KLT features anchored on the object's textured surfaces + robust pose (TrackerMethod::kKlt).
class KltTracker : public FrameTracker {
 public:
  KltTracker(const detector::ObjectModel& object, const TrackerOptions& opt, PoseAligner align)
      : opt_(opt), align_(opt.align_to_reference && alignable(object) ? std::move(align) : nullptr),
        surfaces_(object) {}

  TrackStep start(const cv::Mat& gray, const Intrinsics& cam, const Pose& cMo) override {
    try {
      running_ = false;
      X_o_.clear();
      n_o_.clear();
      seen_.clear();
      TrackStep s;
      s.cMo = cMo;
      s.quality.visible_fraction = surfaces_.visibleFraction(cMo, cam);
      if (!cMo.isFinite() || s.quality.visible_fraction < opt_.min_visible_fraction) {
        s.lost_reason = lostLine("pattern out of view", s.quality.visible_fraction, "<",
                                 opt_.min_visible_fraction);
        return s;
      }
      std::vector<cv::Point2f> pts;
      seed(gray, cam, cMo, &pts, &X_o_, &n_o_, &seen_);
      std::vector<long> ids(pts.size());
      for (size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<long>(i);
      next_id_ = static_cast<long>(ids.size());
      pyramid(gray, &prev_pyr_);
      pts_ = pts;
      ids_ = ids;
      s.quality.features = s.quality.features_started = static_cast<int>(pts.size());
      started_ = s.quality.features;
      if (s.quality.features < opt_.min_features) {
        s.lost_reason = lostLine("too few features", s.quality.features, "<", opt_.min_features);
        return s;
      }
      s.ok = running_ = true;
      unaligned_ = 0;
      cMo_ = cMo;
      return s;
    } catch (const std::exception& e) {
      running_ = false;
      TrackStep s;
      s.lost_reason = std::string("tracker start failed: ") + e.what();
      return s;
    }
  }

  TrackStep track(const cv::Mat& gray, const Intrinsics& cam,
                  const std::optional<Pose>& predicted) override {
    TrackStep s;
    if (!running_) {
      s.lost_reason = "not started";
      return s;
    }
    try {
      s = step(gray, cam, predicted && predicted->isFinite() ? *predicted : cMo_);
    } catch (const std::exception& e) {
      s = TrackStep();
      s.lost_reason = std::string("tracking failed: ") + e.what();
    }
    running_ = s.ok;
    if (s.ok) cMo_ = s.cMo;
    return s;
  }

 private:
  /// Features (goodFeaturesToTrack) inside the projected textured surfaces facing the camera,
  /// shrunk by the border, at least feature_min_distance_px from `keep`; their points on the
  /// surfaces by pose cMo.
  void seed(const cv::Mat& gray, const Intrinsics& cam, const Pose& cMo,
            std::vector<cv::Point2f>* pts, std::vector<Eigen::Vector3d>* X,
            std::vector<Eigen::Vector3d>* normals, std::vector<std::shared_ptr<const SeenIn>>* seen,
            const std::vector<cv::Point2f>& keep = {}, int wanted = -1) const {
    cv::Mat mask = surfaces_.mask(cMo, cam, opt_.pattern_border_px, opt_.seed_min_facing_cos);
    const int r = static_cast<int>(std::ceil(opt_.feature_min_distance_px));
    for (const cv::Point2f& k : keep) cv::circle(mask, k, r, cv::Scalar(0), cv::FILLED);
    std::vector<cv::Point2f> found;
    const int n = wanted < 0 ? opt_.max_features : wanted;
    if (n <= 0 || cv::countNonZero(mask) == 0) return;
    cv::goodFeaturesToTrack(gray, found, n, opt_.feature_quality, opt_.feature_min_distance_px, mask, 7,
                            false, 0.04);
    // A small target (a can 30 px wide) holds too few features at that spacing for the tracker
    // to start or go on: seed it again, 3 px apart.
    const double close_px = std::min(3.0, opt_.feature_min_distance_px);
    if (static_cast<int>(found.size() + keep.size()) < opt_.min_features && close_px < opt_.feature_min_distance_px) {
      found.clear();
      cv::goodFeaturesToTrack(gray, found, n, opt_.feature_quality, close_px, mask, 7, false, 0.04);
    }
    if (found.empty()) return;
    const std::shared_ptr<const SeenIn> frame =
        align_ ? nullptr : std::make_shared<const SeenIn>(SeenIn{gray.clone(), cMo});
    cv::cornerSubPix(gray, found, cv::Size(5, 5), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 0.03));
    for (const cv::Point2f& f : found) {
      const std::optional<SurfaceHit> hit = surfaces_.intersect(cMo, cam, Eigen::Vector2d(f.x, f.y));
      if (!hit) continue;
      pts->push_back(f);
      X->push_back(hit->X_o);
      normals->push_back(hit->n_o);
      seen->push_back(frame);
    }
  }

  int maxLevels() const { return std::max(opt_.klt_pyramid_levels, opt_.klt_retry_pyramid_levels); }

  void pyramid(const cv::Mat& gray, std::vector<cv::Mat>* pyr) const {
    cv::buildOpticalFlowPyramid(gray, *pyr, cv::Size(opt_.klt_window_px, opt_.klt_window_px), maxLevels());
  }

  /// The image shift the prediction missed (full-resolution px, to add to `guess`): the previous
  /// frame's feature region (the pattern, little background) matched (normalised correlation)
  /// in this frame within shift_search_px of where the prediction puts it, on the coarsest
  /// pyramid level (at most 2) where the region is still >= 32 px across. Empty when the region
  /// is too small, the best match is weak (< shift_min_score) or on the search area's edge.
  std::optional<cv::Point2f> missedShift(const std::vector<cv::Mat>& pyr,
                                         const std::vector<cv::Point2f>& guess) const {
    if (pts_.size() < 3 || guess.size() != pts_.size()) return std::nullopt;
    const cv::Rect2f box = cv::boundingRect(pts_);
    int L = std::min(2, maxLevels());
    while (L > 0 && std::min(box.width, box.height) / static_cast<float>(1 << L) < 32) --L;
    const size_t idx = static_cast<size_t>(2 * L);  // image, derivatives, image, ... (withDerivatives)
    if (idx >= pyr.size() || idx >= prev_pyr_.size()) return std::nullopt;
    const cv::Mat& prev = prev_pyr_[idx];
    const cv::Mat& cur = pyr[idx];
    if (prev.size() != cur.size() || prev.type() != CV_8UC1) return std::nullopt;
    const float scale = static_cast<float>(1 << L);
    std::vector<float> ox, oy;
    for (size_t i = 0; i < pts_.size(); ++i) {
      ox.push_back(guess[i].x - pts_[i].x);
      oy.push_back(guess[i].y - pts_[i].y);
    }
    const auto median = [](std::vector<float> v) {
      std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
      return v[v.size() / 2];
    };
    const cv::Point2f predicted_shift(median(ox), median(oy));  // full-resolution px
    const cv::Rect img(0, 0, prev.cols, prev.rows);
    const cv::Rect tr = cv::Rect(cv::Point(cvCeil(box.x / scale), cvCeil(box.y / scale)),
                                 cv::Point(cvFloor(box.br().x / scale) + 1, cvFloor(box.br().y / scale) + 1)) & img;
    if (tr.width < 16 || tr.height < 16) return std::nullopt;
    const int r = static_cast<int>(std::ceil(opt_.shift_search_px / scale));
    const cv::Point off(cvRound(predicted_shift.x / scale), cvRound(predicted_shift.y / scale));
    const cv::Rect wanted(tr.x + off.x - r, tr.y + off.y - r, tr.width + 2 * r, tr.height + 2 * r);
    const cv::Rect sr = wanted & img;
    if (sr.width < tr.width + 2 || sr.height < tr.height + 2) return std::nullopt;
    cv::Mat score;
    cv::matchTemplate(cur(sr), prev(tr), score, cv::TM_CCOEFF_NORMED);
    double best = 0;
    cv::Point at;
    cv::minMaxLoc(score, nullptr, &best, nullptr, &at);
    if (!(best >= opt_.shift_min_score)) return std::nullopt;
    // A best match on the edge of the searched area (not the image's) is no peak.
    if ((at.x == 0 && sr.x == wanted.x) || (at.y == 0 && sr.y == wanted.y) ||
        (at.x == score.cols - 1 && sr.br().x == wanted.br().x) ||
        (at.y == score.rows - 1 && sr.br().y == wanted.br().y))
      return std::nullopt;
    // Sub-pixel peak (parabola through the neighbours).
    const auto sub = [&](float a, float b, float c) {
      const float d = a - 2 * b + c;
      return std::abs(d) > 1e-6f ? std::clamp(0.5f * (a - c) / d, -0.5f, 0.5f) : 0.f;
    };
    float dx = 0, dy = 0;
    if (at.x > 0 && at.x < score.cols - 1)
      dx = sub(score.at<float>(at.y, at.x - 1), score.at<float>(at.y, at.x), score.at<float>(at.y, at.x + 1));
    if (at.y > 0 && at.y < score.rows - 1)
      dy = sub(score.at<float>(at.y - 1, at.x), score.at<float>(at.y, at.x), score.at<float>(at.y + 1, at.x));
    const cv::Point2f motion((static_cast<float>(sr.x + at.x - tr.x) + dx) * scale,
                             (static_cast<float>(sr.y + at.y - tr.y) + dy) * scale);
    return motion - predicted_shift;
  }

  /// One KLT measurement with `levels` pyramid levels from the predicted positions, then the
  /// robust pose: features (index into ids_), their positions, and which are inliers.
  struct Measurement {
    std::vector<size_t> feature;
    std::vector<cv::Point2f> pts;
    std::vector<char> inlier;
    int inliers = 0;
    bool pose_ok = false;
    Pose cMo;
    std::vector<Eigen::Vector3d> Xi;  ///< inliers' anchors
    std::vector<Eigen::Vector2d> yi;  ///< and their undistorted positions
  };

  Measurement measure(const std::vector<cv::Mat>& pyr, const std::vector<cv::Point2f>& guess,
                      int levels, const Intrinsics& cam, const Pose& predicted) const {
    Measurement m;
    std::vector<cv::Point2f> next = guess;
    std::vector<uchar> status;
    std::vector<float> err;
    cv::calcOpticalFlowPyrLK(prev_pyr_, pyr, pts_, next, status, err,
                             cv::Size(opt_.klt_window_px, opt_.klt_window_px), levels,
                             cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 0.03),
                             cv::OPTFLOW_USE_INITIAL_FLOW);
    std::vector<Eigen::Vector3d> X;
    std::vector<Eigen::Vector2d> y;
    // A window whose content changed (an occluder's edge dragging the feature, a glint) leaves a
    // large photometric error: those features are dropped.
    std::vector<float> e;
    for (size_t i = 0; i < status.size(); ++i)
      if (status[i]) e.push_back(err[i]);
    float max_err = static_cast<float>(opt_.klt_max_error);
    if (!e.empty()) {
      std::nth_element(e.begin(), e.begin() + static_cast<long>(e.size() / 2), e.end());
      max_err = std::max(max_err, 3 * e[e.size() / 2]);
    }
    for (size_t i = 0; i < status.size(); ++i)
      if (status[i] && err[i] > max_err) status[i] = 0;
    for (size_t i = 0; i < status.size(); ++i)
      if (status[i]) {
        m.feature.push_back(i);
        m.pts.push_back(next[i]);
        X.push_back(X_o_[i]);
        y.push_back(cam.undistortPixel(Eigen::Vector2d(next[i].x, next[i].y)));
      }
    fitPose(X, y, cam, predicted, &m);
    return m;
  }

  /// Robust pose of the pairs (X, y) from `start`, then the pairs within the inlier threshold
  /// (m->inlier, Xi, yi, inliers, pose_ok, cMo).
  void fitPose(const std::vector<Eigen::Vector3d>& X, const std::vector<Eigen::Vector2d>& y,
               const Intrinsics& cam, const Pose& start, Measurement* out) const {
    Measurement& m = *out;
    m.inlier.assign(X.size(), 0);
    m.Xi.clear();
    m.yi.clear();
    m.inliers = 0;
    m.pose_ok = false;
    if (static_cast<int>(X.size()) < opt_.min_features) return;
    // Robust pose from the prediction, then the survivors within the inlier threshold.
    const Eigen::Matrix3d K = cam.K();
    detector::PoseResult pr = detector::refinePoseLM(X, y, K, start, opt_.pose_iterations, 1.0);
    if (!pr.ok || !pr.cMo.isFinite()) return;
    for (size_t i = 0; i < X.size(); ++i) {
      const Eigen::Vector2d r = detector::projectPinhole(K, pr.cMo * X[i]) - y[i];
      if (r.norm() < opt_.inlier_threshold_px) {
        m.inlier[i] = 1;
        m.Xi.push_back(X[i]);
        m.yi.push_back(y[i]);
      }
    }
    m.inliers = static_cast<int>(m.Xi.size());
    if (m.inliers >= opt_.min_features && m.Xi.size() < X.size()) {
      const detector::PoseResult p2 = detector::refinePoseLM(m.Xi, m.yi, K, pr.cMo, 5, 1.0);
      if (p2.ok && p2.cMo.isFinite()) pr = p2;
    }
    m.pose_ok = true;
    m.cMo = pr.cMo;
  }

  /// Where feature f (KLT position p) lies in `gray` by its appearance in the frame it was seeded
  /// in, warped to the pose cMo through its tangent plane there, found by normalised correlation
  /// within appearance_search_px of p. Empty when the match is weak, on the search area's edge,
  /// or the window leaves either image.
  std::optional<cv::Point2f> appearanceMatch(const cv::Mat& gray, const Intrinsics& cam, const Pose& cMo,
                                             size_t f, const cv::Point2f& p) const {
    const SeenIn& seen = *seen_[f];
    const Eigen::Vector3d& X = X_o_[f];
    const Eigen::Vector3d Xs = seen.cMo * X, Xc = cMo * X;
    if (!(Xs.z() > 1e-6) || !(Xc.z() > 1e-6)) return std::nullopt;
    const int half = opt_.klt_window_px / 2, r = static_cast<int>(std::ceil(opt_.appearance_search_px));
    // Four points on the tangent plane half a window from X (in the seeding image).
    const Eigen::Vector3d e1 = n_o_[f].unitOrthogonal(), e2 = n_o_[f].cross(e1);
    const double a = half * Xs.z() / cam.fx;
    std::vector<cv::Point2f> from, to;
    for (const auto& [s1, s2] : {std::pair{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}) {
      const Eigen::Vector3d P = X + a * (s1 * e1 + s2 * e2);
      const Eigen::Vector3d Ps = seen.cMo * P, Pc = cMo * P;
      if (!(Ps.z() > 1e-6) || !(Pc.z() > 1e-6)) return std::nullopt;
      const Eigen::Vector2d qs = cam.project(Ps), qc = cam.project(Pc);
      from.emplace_back(static_cast<float>(qs.x()), static_cast<float>(qs.y()));
      to.emplace_back(static_cast<float>(qc.x()), static_cast<float>(qc.y()));
    }
    const Eigen::Vector2d c0 = cam.project(Xc);
    cv::Mat H = cv::getPerspectiveTransform(from, to);  // seeding image -> this image
    const cv::Matx33d shift(1, 0, half - c0.x(), 0, 1, half - c0.y(), 0, 0, 1);
    cv::Mat tmpl;
    cv::warpPerspective(seen.gray, tmpl, cv::Mat(shift) * H, cv::Size(2 * half + 1, 2 * half + 1),
                        cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    const cv::Rect roi(cvRound(p.x) - half - r, cvRound(p.y) - half - r, 2 * (half + r) + 1,
                       2 * (half + r) + 1);
    if ((roi & cv::Rect(0, 0, gray.cols, gray.rows)) != roi) return std::nullopt;
    cv::Mat score;
    cv::matchTemplate(gray(roi), tmpl, score, cv::TM_CCOEFF_NORMED);
    double best = 0;
    cv::Point at;
    cv::minMaxLoc(score, nullptr, &best, nullptr, &at);
    if (!(best >= opt_.appearance_min_score) || at.x == 0 || at.y == 0 || at.x == score.cols - 1 ||
        at.y == score.rows - 1)
      return std::nullopt;
    const auto sub = [](float l, float c, float rr) {
      const float d = l - 2 * c + rr;
      return std::abs(d) > 1e-6f ? std::clamp(0.5f * (l - rr) / d, -0.5f, 0.5f) : 0.f;
    };
    const float dx = sub(score.at<float>(at.y, at.x - 1), score.at<float>(at.y, at.x), score.at<float>(at.y, at.x + 1));
    const float dy = sub(score.at<float>(at.y - 1, at.x), score.at<float>(at.y, at.x), score.at<float>(at.y + 1, at.x));
    return cv::Point2f(static_cast<float>(roi.x + at.x + half) + dx, static_cast<float>(roi.y + at.y + half) + dy);
  }

  /// Without an aligner: the features KLT kept, each moved to where its seeding appearance is
  /// (appearanceMatch), and the pose again from them. KLT follows a window from frame to frame
  /// and slides a little each time (noise, blur, the window's change of shape as the surface
  /// turns); the seeding appearance warped by the model does not accumulate that.
  void rematch(const cv::Mat& gray, const Intrinsics& cam, Measurement* m) const {
    std::vector<Eigen::Vector3d> X;
    std::vector<Eigen::Vector2d> y;
    for (size_t i = 0; i < m->feature.size(); ++i) {
      const size_t f = m->feature[i];
      if (const std::optional<cv::Point2f> q = appearanceMatch(gray, cam, m->cMo, f, m->pts[i])) m->pts[i] = *q;
      X.push_back(X_o_[f]);
      y.push_back(cam.undistortPixel(Eigen::Vector2d(m->pts[i].x, m->pts[i].y)));
    }
    fitPose(X, y, cam, m->cMo, m);
  }

  TrackStep step(const cv::Mat& gray, const Intrinsics& cam, const Pose& predicted) {
    TrackStep s;
    s.quality.features_started = started_;
    // Features moved to where the prediction puts them (initial flow).
    std::vector<cv::Point2f> guess(ids_.size());
    for (size_t i = 0; i < ids_.size(); ++i) {
      const Eigen::Vector3d Xc = predicted * X_o_[i];
      const Eigen::Vector2d px = Xc.z() > 1e-6 ? cam.project(Xc) : Eigen::Vector2d(-1e4, -1e4);
      guess[i] = cv::Point2f(static_cast<float>(px.x()), static_cast<float>(px.y()));
    }
    std::vector<cv::Mat> pyr;
    pyramid(gray, &pyr);
    // The pose is solved from the prediction when an alignment follows; without one, from the last
    // pose: the features of a small target barely observe some directions (its depth against
    // its tilt), the solution lands anywhere along them near its start, and a prediction by the
    // last motion would extrapolate that error frame after frame.
    const Pose& start = align_ ? predicted : cMo_;
    Measurement m = measure(pyr, guess, opt_.klt_pyramid_levels, cam, start);
    // A poor prediction (a sudden change of motion) needs the coarser levels, or the shift the
    // prediction missed measured on the whole pattern region at once (a partly hidden or partly
    // out-of-view pattern leaves coarse KLT windows to the background).
    if (2 * m.inliers < static_cast<int>(ids_.size()) &&
        opt_.klt_retry_pyramid_levels > opt_.klt_pyramid_levels) {
      Measurement again = measure(pyr, guess, opt_.klt_retry_pyramid_levels, cam, start);
      if (again.inliers > m.inliers) m = std::move(again);
    }
    if (2 * m.inliers < static_cast<int>(ids_.size()) && opt_.shift_retry) {
      if (const std::optional<cv::Point2f> d = missedShift(pyr, guess)) {
        std::vector<cv::Point2f> shifted = guess;
        for (cv::Point2f& g : shifted) g += *d;
        Pose moved = predicted;  // the prediction moved by the shift at the pattern's depth
        const Eigen::Vector3d c = predicted.t;
        if (c.z() > 1e-6) {
          moved.t.x() += d->x * c.z() / cam.fx;
          moved.t.y() += d->y * c.z() / cam.fy;
        }
        Measurement again = measure(pyr, shifted, opt_.klt_pyramid_levels, cam, moved);
        if (again.inliers > m.inliers) m = std::move(again);
      }
    }
    prev_pyr_ = pyr;
    if (!align_ && opt_.appearance_match && m.pose_ok) {
      Measurement again = m;
      rematch(gray, cam, &again);
      if (again.pose_ok) m = std::move(again);
    }
    if (!m.pose_ok || m.inliers < opt_.min_features) {
      s.quality.features = m.inliers;
      s.lost_reason = lostLine("too few features", m.inliers, "<", opt_.min_features);
      return s;
    }
    detector::PoseResult pr;
    pr.cMo = m.cMo;
    const Eigen::Matrix3d K = cam.K();
    const std::vector<Eigen::Vector3d>& Xi = m.Xi;
    const std::vector<Eigen::Vector2d>& yi = m.yi;
    // Photometric alignment with the reference: the pose the features give no longer drifts. An
    // alignment the features disagree with (an occluder pulled it) is refused.
    if (align_) {
      const detector::PoseAlignment a = align_(gray, cam, pr.cMo);
      s.quality.correlation = a.correlation;
      s.quality.aligned_fraction = a.used_fraction;
      bool ok = a.ok;
      if (ok) {
        double sq_a = 0;
        for (size_t i = 0; i < Xi.size(); ++i)
          sq_a += (detector::projectPinhole(K, a.cMo * Xi[i]) - yi[i]).squaredNorm();
        ok = std::sqrt(sq_a / static_cast<double>(Xi.size())) <= opt_.align_max_feature_rms_px;
      }
      if (ok) {
        pr.cMo = a.cMo;
        s.quality.aligned = true;
      }
      unaligned_ = ok ? 0 : unaligned_ + 1;
    }
    double sq = 0;
    for (size_t i = 0; i < Xi.size(); ++i)
      sq += (detector::projectPinhole(K, pr.cMo * Xi[i]) - yi[i]).squaredNorm();
    s.cMo = pr.cMo;
    s.quality.features = static_cast<int>(Xi.size());
    s.quality.projection_error_px = Xi.empty() ? 0 : std::sqrt(sq / static_cast<double>(Xi.size()));
    s.quality.visible_fraction = surfaces_.visibleFraction(s.cMo, cam);

    // Keep the inliers only; after an alignment, re-anchored on the aligned pose.
    std::vector<cv::Point2f> kept_pts;
    std::vector<long> kept_ids;
    std::vector<Eigen::Vector3d> kept_X, kept_n;
    std::vector<std::shared_ptr<const SeenIn>> kept_seen;
    for (size_t i = 0; i < m.feature.size(); ++i) {
      if (!m.inlier[i]) continue;
      std::optional<Eigen::Vector3d> Xo = X_o_[m.feature[i]];
      if (s.quality.aligned) {
        const std::optional<SurfaceHit> hit =
            surfaces_.intersect(s.cMo, cam, Eigen::Vector2d(m.pts[i].x, m.pts[i].y));
        Xo = hit ? std::optional<Eigen::Vector3d>(hit->X_o) : std::nullopt;
      }
      if (!Xo) continue;
      kept_pts.push_back(m.pts[i]);
      kept_ids.push_back(ids_[m.feature[i]]);
      kept_X.push_back(*Xo);
      kept_n.push_back(n_o_[m.feature[i]]);
      kept_seen.push_back(seen_[m.feature[i]]);
    }

    if (s.quality.features < opt_.min_features) {
      s.lost_reason = lostLine("too few features", s.quality.features, "<", opt_.min_features);
    } else if (s.quality.features < opt_.min_feature_fraction * started_) {
      s.lost_reason = lostLine("too few features", s.quality.features, "<",
                               opt_.min_feature_fraction * started_);
    } else if (s.quality.projection_error_px > opt_.max_projection_error_px) {
      s.lost_reason = lostLine("projection error px", s.quality.projection_error_px, ">",
                               opt_.max_projection_error_px);
    } else if (s.quality.visible_fraction < opt_.min_visible_fraction) {
      s.lost_reason = lostLine("pattern out of view", s.quality.visible_fraction, "<",
                               opt_.min_visible_fraction);
    } else if (s.quality.aligned && s.quality.aligned_fraction < opt_.min_aligned_fraction) {
      s.lost_reason = lostLine("too little of the pattern in view and unoccluded",
                               s.quality.aligned_fraction, "<", opt_.min_aligned_fraction);
    } else if (unaligned_ >= opt_.max_unaligned_frames) {
      s.lost_reason = lostLine("frames not aligned with the reference", unaligned_, ">=",
                               opt_.max_unaligned_frames);
    } else {
      s.ok = true;
    }
    if (!s.ok) return s;

    // Re-seed in the visible pattern when too few features are left (on a box, the faces that
    // came into view).
    if (static_cast<int>(kept_pts.size()) < opt_.reseed_fraction * opt_.max_features) {
      std::vector<cv::Point2f> more;
      std::vector<Eigen::Vector3d> more_X, more_n;
      std::vector<std::shared_ptr<const SeenIn>> more_seen;
      seed(gray, cam, s.cMo, &more, &more_X, &more_n, &more_seen, kept_pts,
           opt_.max_features - static_cast<int>(kept_pts.size()));
      for (size_t i = 0; i < more.size(); ++i) {
        kept_pts.push_back(more[i]);
        kept_ids.push_back(next_id_++);
        kept_X.push_back(more_X[i]);
        kept_n.push_back(more_n[i]);
        kept_seen.push_back(more_seen[i]);
      }
      started_ = static_cast<int>(kept_pts.size());
    }
    pts_ = kept_pts;
    ids_ = kept_ids;
    X_o_ = kept_X;
    n_o_ = kept_n;
    seen_ = kept_seen;
    return s;
  }

  TrackerOptions opt_;
  PoseAligner align_;  ///< empty: KLT alone (no aligner given, or the object is not one plane)
  SurfaceModel surfaces_;
  std::vector<cv::Mat> prev_pyr_;      ///< LK pyramid of the previous frame
  std::vector<cv::Point2f> pts_;       ///< feature positions in the previous frame
  std::vector<long> ids_;              ///< KLT ids of the features, in KLT order
  std::vector<Eigen::Vector3d> X_o_;   ///< their points on the object's surfaces, object frame
  std::vector<Eigen::Vector3d> n_o_;   ///< the surfaces' outward normals there, object frame
  /// The frame each feature was seeded in (without an aligner: appearanceMatch); null otherwise.
  std::vector<std::shared_ptr<const SeenIn>> seen_;
  long next_id_ = 0;
  int started_ = 0;
  int unaligned_ = 0;  ///< frames in a row the aligner refused
  bool running_ = false;
  Pose cMo_;
};

}  // namespace

double visibleFraction(const detector::ObjectModel& object, const Pose& cMo, const Intrinsics& camera) {
  if (!object.hasPose()) return 0;
  return SurfaceModel(object).visibleFraction(cMo, camera);
}

std::unique_ptr<FrameTracker> makePlanarTracker(const detector::ObjectModel& object,
                                                const TrackerOptions& options, PoseAligner align) {
  options.check();
  if (!object.hasPose())
    throw std::invalid_argument(object.name + ": tracking needs a 3D object (reference_pose, cylinder "
                                              "or views)");
  if (options.method == TrackerMethod::kMbt) {
    if (object.isCylinder() || object.isMultiView())
      throw std::invalid_argument(object.name + ": the mbt tracker follows one planar pattern; use klt "
                                                "for a cylinder or several views");
    return makeMbtTracker(object, options);
  }
  return std::make_unique<KltTracker>(object, options, std::move(align));
}

TrackerFactory planarTrackerFactory(const TrackerOptions& options, const detector::Detector* detector) {
  options.check();
  return [options, detector](const detector::ObjectModel& object) {
    PoseAligner align;
    if (detector)
      for (int id = 0; id < detector->objectCount(); ++id)
        if (&detector->object(id) == &object) {
          detector::DenseRefineOptions dense = detector->options().dense;
          dense.max_corner_shift_px = options.align_max_corner_shift_px;
          dense.min_correlation = options.align_min_correlation;
          dense.robust = true;
          align = [detector, id, dense](const cv::Mat& gray, const Intrinsics& cam, const Pose& cMo) {
            return detector->alignPose(gray, cam, id, cMo, &dense);
          };
          break;
        }
    return makePlanarTracker(object, options, std::move(align));
  };
}

}  // namespace refgrasp::servo
