#include "detector/detector.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <new>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/geometry.h"
#include "detector/detector_internal.h"
#include "detector/homography.h"

namespace refgrasp::detector {

struct RegisteredObject {
  ObjectModel model;
  ReferenceIndex index;
  std::array<Eigen::Vector2d, 4> corners_und_px;  ///< pattern corners, undistorted ref px
  std::vector<Eigen::Vector2d> polygon_und_px;    ///< pattern region, undistorted ref px
  std::vector<cv::Mat> pyramid;  ///< reference pyramid (verification; dense refinement)
  bool dense_usable = false;     ///< dense refinement possible (undistorted reference, exact region)
  bool region_is_rect = true;    ///< the region is its bounding box (no mask needed)
  std::vector<Eigen::Vector2d> periods;  ///< repeatPeriods(index): a repeated motif's other alignments
};

namespace {

using Clock = std::chrono::steady_clock;
// A pose whose pattern corners lie farther than this from the matched homography's is refused.
constexpr double kMaxPoseGapPx = 4.0;
constexpr double kMaxPoseGapFraction = 0.1;  // of the pattern's diagonal in the image
// poseFromDenseH with a prior: the pose continuing it is kept unless the other fits this much
// better (RMS px over the grid of densely aligned pattern points).
constexpr double kAmbiguityMarginPx = 0.5;
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

// Empty string when the image can be used with this camera, else the problem.
std::string validateImage(const cv::Mat& image, const Intrinsics& camera) {
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

// Empty string when the query can be used with `objects` registered objects, else the problem.
std::string validateQuery(const DetectionQuery& q, int objects) {
  if (q.roi && (q.roi->width <= 0 || q.roi->height <= 0)) return "query.roi: empty rectangle";
  std::vector<char> seen(objects, 0);
  for (size_t i = 0; i < q.priors.size(); ++i) {
    const ObjectPrior& p = q.priors[i];
    const std::string field = "query.priors[" + std::to_string(i) + "].";
    if (p.object < 0 || p.object >= objects)
      return field + "object: no object " + std::to_string(p.object) + " (" +
             std::to_string(objects) + " registered)";
    if (seen[p.object]++) return field + "object: a second prior for object " + std::to_string(p.object);
    if (p.cMo && !p.cMo->isFinite()) return field + "cMo: must be finite";
    if (p.roi.width < 0 || p.roi.height < 0) return field + "roi: negative size";
    if (!(std::isfinite(p.roi_margin) && p.roi_margin >= 0)) return field + "roi_margin: must be >= 0";
    if (!(std::isfinite(p.scale_margin) && p.scale_margin >= 1))
      return field + "scale_margin: must be >= 1";
  }
  return "";
}

// what() of an exception on one line (OpenCV's end with a newline).
std::string oneLine(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

Features extractFeatures(const cv::Mat& gray, const Intrinsics& camera, const SiftOptions& sift,
                         const ExtractRegion& region) {
  Features f = extractSiftUnchecked(gray, sift, region);
  undistortKeypoints(&f.keypoints, camera);
  if (gray.type() == CV_8UC1) f.image = gray;
  return f;
}

// The region of the reference an instance is verified on: the pattern region, or when that only
// bounds the pattern, its part inside the convex hull of the instance's inliers.
std::vector<Eigen::Vector2d> verificationRegion(const RegisteredObject& e, const MatchCandidate& cand) {
  if (e.model.pattern_region_exact) return e.polygon_und_px;
  std::vector<cv::Point2f> pts, hull;
  for (const Correspondence& c : cand.inliers) pts.push_back(e.index.features.keypoints[static_cast<size_t>(c.ref)].pt);
  if (pts.size() < 3) return {};
  cv::convexHull(pts, hull);
  std::vector<Eigen::Vector2d> convex;
  for (const cv::Point2f& p : hull) convex.emplace_back(p.x, p.y);
  return clipToConvex(e.polygon_und_px, convex);
}

// Dense refinement of H (undistorted reference px -> undistorted scene px) on `image`.
DenseRefineResult refineDense(const RegisteredObject& e, const Eigen::Matrix3d& H,
                              const cv::Mat& image, const Intrinsics& camera,
                              const DenseRefineOptions& opt) {
  // The template is the region's bounding box; a polygon region masks it.
  std::array<Eigen::Vector2d, 4> rect = e.corners_und_px;
  const std::vector<Eigen::Vector2d>* mask = nullptr;
  if (!e.region_is_rect) {
    Eigen::Vector2d lo = e.polygon_und_px[0], hi = lo;
    for (const auto& p : e.polygon_und_px) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    rect = {lo, Eigen::Vector2d(hi.x(), lo.y()), hi, Eigen::Vector2d(lo.x(), hi.y())};
    mask = &e.polygon_und_px;
  }
  if (!camera.hasDistortion())
    return refineHomographyDense(e.pyramid, image, H, rect, opt, mask);
  // H lives in undistorted pixels: resample only the pattern's neighbourhood of the image onto
  // the ideal pinhole grid (never the whole frame), refine there, and move H back.
  Eigen::Vector2d lo(1e9, 1e9), hi(-1e9, -1e9);
  for (const auto& c : rect) {
    const Eigen::Vector2d p = applyHomography(H, c);
    if (!p.allFinite()) return {};
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double margin = opt.max_corner_shift_px + 8;
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
  DenseRefineResult r = refineHomographyDense(e.pyramid, crop, T * H, rect, opt, mask);
  r.H = T.inverse() * r.H;
  return r;
}

// Pose from a grid of pattern points mapped by a densely refined H (undistorted reference px ->
// undistorted scene px).
// prior (tracking): of the planar ambiguity's two poses, the one continuing the prior unless the
// other fits clearly better (estimatePoseRefinedNear).
PoseResult poseFromDenseH(const RegisteredObject& e, const DetectorOptions& opt,
                          const Eigen::Matrix3d& H, const Intrinsics& camera,
                          const Pose* prior = nullptr) {
  const PlanarTarget& target = *e.model.target;
  const int n = opt.dense.pose_grid;
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
      y.push_back(applyHomography(H, r));
    }
  if (prior && prior->isFinite())
    return estimatePoseRefinedNear(X, y, target, camera.K(), opt.pose_options, *prior, kAmbiguityMarginPx);
  return estimatePoseRefined(X, y, target, camera.K(), opt.pose_options);
}

// dense: the dense refinement of match.H with opt.dense when the caller already ran it.
// *from_features (when given): true when the pose was fitted to the matched features (refined
// method without a usable dense alignment), false for the paper pose or the dense grid.
PoseResult estimatePose(const RegisteredObject& e, const DetectorOptions& opt,
                        const MatchCandidate& match, const Features& scene,
                        const Intrinsics& camera, PoseMethod method,
                        const DenseRefineResult* dense = nullptr, bool* from_features = nullptr) {
  if (from_features) *from_features = false;
  if (!e.model.target) return {};
  const PlanarTarget& target = *e.model.target;
  if (method == PoseMethod::kPaper)
    return estimatePosePaper(match.H, target, camera.K(), opt.pose_options);
  if (opt.dense.enabled && e.dense_usable && !scene.image.empty()) {
    const DenseRefineResult dr = dense ? *dense : refineDense(e, match.H, scene.image, camera, opt.dense);
    if (dr.ok) {
      const PoseResult p = poseFromDenseH(e, opt, dr.H, camera);
      if (p.ok) return p;
    }
  }
  if (from_features) *from_features = true;
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> y;
  std::vector<double> sigma;
  X.reserve(match.inliers.size());
  y.reserve(match.inliers.size());
  const double k = opt.pose_options.keypoint_sigma_per_size;
  for (const auto& c : match.inliers) {
    const cv::Point2f& pr = e.index.features.keypoints[c.ref].pt;
    const auto Xo = target.backProject(Eigen::Vector2d(pr.x, pr.y));
    if (!Xo) continue;
    const cv::KeyPoint& ks = scene.keypoints[c.scene];
    X.push_back(*Xo);
    y.emplace_back(ks.pt.x, ks.pt.y);
    if (k > 0) sigma.push_back(std::max(0.05, k * ks.size));
  }
  return estimatePoseRefined(X, y, target, camera.K(), opt.pose_options, sigma);
}

// The pattern's diagonal under H (undistorted scene px): the mean of its two corner diagonals.
double patternDiagonal(const RegisteredObject& e, const Eigen::Matrix3d& H) {
  std::array<Eigen::Vector2d, 4> q;
  for (int i = 0; i < 4; ++i) q[i] = applyHomography(H, e.corners_und_px[i]);
  return 0.5 * ((q[2] - q[0]).norm() + (q[3] - q[1]).norm());
}

// H moved by each of the reference's repeat periods (displacements in its rectified plane,
// e.index.rectify_px); empty without periods or with a singular rectification.
std::vector<Eigen::Matrix3d> movedByPeriods(const RegisteredObject& e, const Eigen::Matrix3d& H) {
  std::vector<Eigen::Matrix3d> moved;
  const Eigen::Matrix3d& R = e.index.rectify_px;
  const Eigen::Matrix3d Ri = R.inverse();
  if (e.periods.empty() || !Ri.allFinite()) return moved;
  for (const Eigen::Vector2d& d : e.periods) {
    Eigen::Matrix3d T = Eigen::Matrix3d::Identity();
    T(0, 2) = d.x();
    T(1, 2) = d.y();
    moved.push_back(H * Ri * T * R);
  }
  return moved;
}

// Photometric re-alignment of a candidate (VerifyOptions::realign). The dense refinement of
// cand.H (opt.dense, as the refined pose runs it; returned in *dense) normally moves the pattern
// by a pixel or two. When it converges well but wants to move a corner further than
// dense.max_corner_shift_px, the features' alignment is doubtful: on a repeated motif (a
// facade's windows) a consensus of matches one period off fits a stretched homography, and on a
// small oblique target a few features fit one a few pixels off. Then the alignment is refined
// again with room to move (half the pattern's diagonal), the features are matched again under it
// (matchUnderHomography), and that candidate replaces cand when the features support it as well
// (at least as many inliers, or a consensus at least as significant: log10 NFA) and its warped
// reference agrees better with the scene (verifyInstance). Whichever candidate is kept, when its
// own dense refinement is still refused for the distance, the wide refinement from it becomes
// its alignment if it correlates at least verify.realign_trusted_correlation (H and *dense), or
// if its warped reference verifies clearly better (verify.realign_verified_*).
// Fraction of the pattern's projection under H (undistorted scene px) inside the frame; 0 when
// it is degenerate or crosses the vanishing line.
double inViewFraction(const RegisteredObject& e, const Eigen::Matrix3d& H, const Intrinsics& camera) {
  std::vector<Eigen::Vector2d> q;
  double w0 = 0;
  for (const auto& c : e.corners_und_px) {
    const Eigen::Vector3d p = H * c.homogeneous();
    if (q.empty()) w0 = p.z();
    if (!(p.z() * w0 > 0)) return 0;
    q.push_back(p.hnormalized());
  }
  const double area = std::abs(signedArea(q));
  if (!(area > 1e-9) || !std::isfinite(area)) return 0;
  const auto in = clipToBox(q, Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(camera.width - 0.5, camera.height - 0.5));
  return in.size() < 3 ? 0 : std::min(1.0, std::abs(signedArea(in)) / area);
}

MatchCandidate realign(const RegisteredObject& e, const DetectorOptions& opt, const MatchCandidate& cand,
                       const Features& scene, const GridIndex& grid, const Intrinsics& camera,
                       DenseRefineResult* dense) {
  auto tooFar = [&](const DenseRefineResult& d) {
    return !d.ok && d.corner_shift_px > opt.dense.max_corner_shift_px && d.correlation >= opt.dense.min_correlation;
  };
  // The refinement from H with room to move (ok = false when that room is not finite).
  auto wideRefine = [&](const Eigen::Matrix3d& H) {
    DenseRefineOptions wide = opt.dense;
    wide.max_corner_shift_px = std::max(wide.max_corner_shift_px, 0.5 * patternDiagonal(e, H));
    if (!std::isfinite(wide.max_corner_shift_px)) return DenseRefineResult{};
    return refineDense(e, H, scene.image, camera, wide);
  };
  // c, aligned by its wide refinement w when w is trusted: by its ECC correlation, or because its
  // warped reference verifies clearly better than c's.
  auto adopt = [&](const MatchCandidate& c, const DenseRefineResult& w) {
    if (!w.ok) return c;
    const VerifyOptions& vo = opt.verify;
    bool take = vo.realign_trusted_correlation < 1 && w.correlation >= vo.realign_trusted_correlation;
    // Not on a reference with repeat periods: there a consensus one period off verifies as well.
    if (!take && vo.realign_verified_correlation <= 1 && movedByPeriods(e, c.H).empty()) {
      const std::vector<Eigen::Vector2d> region = verificationRegion(e, c);
      const VerifyResult vw = verifyInstance(e.pyramid, region, scene.image, camera, w.H, vo);
      if (vw.ok && vw.correlation >= vo.realign_verified_correlation && vw.strong_cells >= vo.realign_verified_cells) {
        const VerifyResult vc = verifyInstance(e.pyramid, region, scene.image, camera, c.H, vo);
        take = vw.correlation >= vc.correlation + vo.realign_verified_gain;
      }
    }
    if (!take) return c;
    MatchCandidate out = c;
    out.H = w.H;
    *dense = w;
    return out;
  };
  *dense = refineDense(e, cand.H, scene.image, camera, opt.dense);
  if (!tooFar(*dense)) return cand;
  const DenseRefineResult w = wideRefine(cand.H);
  if (!w.ok) return cand;
  const std::optional<MatchCandidate> again = matchUnderHomography(e.index, scene, grid, opt.match, w.H);
  if (!again) return adopt(cand, w);
  const bool supported = again->inliers.size() >= cand.inliers.size() ||
                         (std::isfinite(cand.log10_nfa) && again->log10_nfa <= cand.log10_nfa);
  if (!supported) return adopt(cand, w);
  const VerifyResult v0 = verifyInstance(e.pyramid, verificationRegion(e, cand), scene.image, camera, cand.H, opt.verify);
  const VerifyResult v1 = verifyInstance(e.pyramid, verificationRegion(e, *again), scene.image, camera, again->H, opt.verify);
  if (!(v1.ok && v1.correlation > v0.correlation)) return adopt(cand, w);
  *dense = refineDense(e, again->H, scene.image, camera, opt.dense);
  if (!tooFar(*dense)) return *again;
  return adopt(*again, wideRefine(again->H));
}

// A repeated motif's other alignments (VerifyOptions::realign): cand moved by each of the
// reference's repeat periods (in the rectified pattern plane), its features matched again there.
// A distinct alignment (corners farther than the pose check allows) whose consensus is more
// significant (lower log10 NFA) is returned (nullopt: none); the caller checks it like any
// candidate and keeps it only if it correlates at least as well. The matcher's search stops at
// its first candidate, which on a facade can be the consensus one window off.
std::optional<MatchCandidate> alignAcrossPeriods(const RegisteredObject& e, const DetectorOptions& opt,
                                                 const MatchCandidate& cand, const Features& scene,
                                                 const GridIndex& grid) {
  const std::vector<Eigen::Matrix3d> moved = movedByPeriods(e, cand.H);
  if (moved.empty()) return std::nullopt;
  std::array<Eigen::Vector2d, 4> q;
  for (int i = 0; i < 4; ++i) q[i] = applyHomography(cand.H, e.corners_und_px[i]);
  const double distinct = std::max(kMaxPoseGapPx, kMaxPoseGapFraction * patternDiagonal(e, cand.H));
  const std::optional<MatchCandidate>* best = nullptr;
  const auto found = matchUnderHomographies(e.index, scene, grid, opt.match, moved);
  for (const auto& c : found) {
    if (!c || !(c->log10_nfa < cand.log10_nfa) || (best && !(c->log10_nfa < (*best)->log10_nfa))) continue;
    double gap = 0;
    for (int i = 0; i < 4; ++i) gap = std::max(gap, (applyHomography(c->H, e.corners_und_px[i]) - q[i]).norm());
    if (gap > distinct) best = &c;
  }
  if (!best) return std::nullopt;
  return **best;
}

// Photometric peaks around an instance (VerifyOptions::peak_search_*): the reference warped by
// H into the scene, on a grid of at most 48 px on the pattern's diagonal, compared by masked
// zero-mean NCC (cv::matchTemplate) with the scene at every translation up to peak_search_reach
// x the diagonal. Returns H moved by the translations of the (at most peak_search_count) best
// local maxima that correlate better than H itself (its best within a grid px) by more than
// peak_search_margin and are more than 3 scene px from it. A few features on a small target can
// fit a homography several pixels off whose own neighbourhood holds a better photometric
// alignment that ECC, started from H, does not reach. The scene image is the camera's raw one:
// the pattern is placed there by the distortion's displacement at its centre (locally a
// translation), and the translations found are applied to H in undistorted px.
std::vector<Eigen::Matrix3d> photometricPeaks(const RegisteredObject& e, const Eigen::Matrix3d& H,
                                              const std::vector<Eigen::Vector2d>& polygon, const cv::Mat& scene,
                                              const Intrinsics& camera, const VerifyOptions& opt) {
  std::vector<Eigen::Matrix3d> out;
  if (e.pyramid.empty() || scene.empty() || polygon.size() < 3) return out;
  std::vector<Eigen::Vector2d> proj;
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  double w0 = 0;
  for (const auto& p : polygon) {
    const Eigen::Vector3d q = H * p.homogeneous();
    if (proj.empty()) w0 = q.z();
    if (!(q.z() * w0 > 0)) return out;  // the whole polygon in front of the vanishing line
    proj.push_back(q.hnormalized());
    lo = lo.cwiseMin(proj.back());
    hi = hi.cwiseMax(proj.back());
  }
  const double diag = patternDiagonal(e, H);
  if (!(diag > 8) || !(diag < 1e5) || !lo.allFinite() || !hi.allFinite()) return out;
  const Eigen::Vector2d mid = 0.5 * (lo + hi), shift = distortPixel(camera, mid) - mid;
  lo += shift;
  hi += shift;
  // Bounded before the casts to int below (NaN fails too).
  if (!(lo.cwiseAbs().maxCoeff() < 1e5) || !(hi.cwiseAbs().maxCoeff() < 1e5)) return out;
  for (auto& p : proj) p += shift;
  const double k = std::min(1.0, 48.0 / diag);  // grid px per scene px
  const double r = opt.peak_search_reach * diag;
  const cv::Rect img(0, 0, scene.cols, scene.rows);
  const cv::Rect crop = cv::Rect(cv::Point(static_cast<int>(std::floor(lo.x() - r)), static_cast<int>(std::floor(lo.y() - r))),
                                 cv::Point(static_cast<int>(std::ceil(hi.x() + r)) + 1, static_cast<int>(std::ceil(hi.y() + r)) + 1)) & img;
  const int tw = static_cast<int>(std::ceil((hi.x() - lo.x()) * k)) + 1, th = static_cast<int>(std::ceil((hi.y() - lo.y()) * k)) + 1;
  if (crop.area() <= 0 || tw < 6 || th < 6) return out;
  cv::Mat sc;
  if (k < 1) cv::resize(scene(crop), sc, cv::Size(), k, k, cv::INTER_AREA);
  else sc = scene(crop);
  if (sc.cols < tw || sc.rows < th) return out;
  // Reference level: about one reference px per grid px.
  const double a_ref = std::abs(signedArea(polygon)), a_scene = std::abs(signedArea(proj)) * k * k;
  if (!(a_ref > 0) || !(a_scene > 16)) return out;
  const int L = std::clamp(static_cast<int>(std::floor(0.5 * std::log2(a_ref / a_scene))), 0, static_cast<int>(e.pyramid.size()) - 1);
  const double ls = std::ldexp(1.0, L);
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();  // level px -> ref px
  A(0, 0) = A(1, 1) = ls;
  Eigen::Matrix3d G = Eigen::Matrix3d::Identity();  // scene px -> template px
  G(0, 0) = G(1, 1) = k;
  G(0, 2) = -k * lo.x();
  G(1, 2) = -k * lo.y();
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();  // undistorted px -> raw px, near the pattern
  D(0, 2) = shift.x();
  D(1, 2) = shift.y();
  const Eigen::Matrix3d W = G * D * H * A;
  cv::Mat warp(3, 3, CV_64F);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) warp.at<double>(i, j) = W(i, j);
  cv::Mat templ, mask = cv::Mat::zeros(th, tw, CV_8UC1);
  cv::warpPerspective(e.pyramid[L], templ, warp, cv::Size(tw, th), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  std::vector<cv::Point> poly;
  for (const auto& p : proj)
    poly.emplace_back(static_cast<int>(std::lround(k * (p.x() - lo.x()))), static_cast<int>(std::lround(k * (p.y() - lo.y()))));
  cv::fillPoly(mask, std::vector<std::vector<cv::Point>>{poly}, cv::Scalar(255));
  cv::erode(mask, mask, cv::Mat());
  if (cv::countNonZero(mask) < 24) return out;
  cv::Mat tf, sf, res;
  templ.convertTo(tf, CV_32F);
  sc.convertTo(sf, CV_32F);
  cv::GaussianBlur(tf, tf, cv::Size(3, 3), 0.7);
  cv::GaussianBlur(sf, sf, cv::Size(3, 3), 0.7);
  try {
    cv::matchTemplate(sf, tf, res, cv::TM_CCOEFF_NORMED, mask);
  } catch (const cv::Exception&) {
    return out;
  }
  cv::patchNaNs(res, -1);
  for (int v = 0; v < res.rows; ++v)
    for (int u = 0; u < res.cols; ++u)
      if (!std::isfinite(res.at<float>(v, u)) || std::abs(res.at<float>(v, u)) > 1.0001f) res.at<float>(v, u) = -1;
  const cv::Point2d p0(k * (lo.x() - crop.x), k * (lo.y() - crop.y));
  const int i0 = std::clamp(static_cast<int>(std::lround(p0.x)), 0, res.cols - 1), j0 = std::clamp(static_cast<int>(std::lround(p0.y)), 0, res.rows - 1);
  float at0 = -1;  // best within a grid pixel of H
  for (int dv = -1; dv <= 1; ++dv)
    for (int du = -1; du <= 1; ++du) {
      const int u = i0 + du, v = j0 + dv;
      if (u >= 0 && v >= 0 && u < res.cols && v < res.rows) at0 = std::max(at0, res.at<float>(v, u));
    }
  const double away = 3.0 * k;  // grid px
  const int nms = std::max(2, static_cast<int>(std::lround(away)));
  for (int n = 0; n < opt.peak_search_count; ++n) {
    double mx;
    cv::Point pm;
    cv::minMaxLoc(res, nullptr, &mx, nullptr, &pm);
    if (!(mx > at0 + opt.peak_search_margin)) break;
    const double dx = (pm.x - p0.x) / k, dy = (pm.y - p0.y) / k;
    cv::rectangle(res, cv::Rect(pm.x - nms, pm.y - nms, 2 * nms + 1, 2 * nms + 1), cv::Scalar(-1), cv::FILLED);
    if (std::hypot(pm.x - p0.x, pm.y - p0.y) <= away) continue;
    Eigen::Matrix3d T = Eigen::Matrix3d::Identity();
    T(0, 2) = dx;
    T(1, 2) = dy;
    out.push_back(T * H);
  }
  return out;
}

// Repeat-period ambiguity (VerifyOptions::period_ambiguity_*): cand, which passed every check,
// moved by each of the reference's repeat periods and to its photometric peaks
// (photometricPeaks, VerifyOptions::peak_search_*), and aligned there photometrically (dense
// refinement with room to move: 0.3 x its diagonal). Ambiguous when one of those alignments
// agrees with the scene clearly better than cand itself (verifyInstance: correlation higher by
// more than the margin and at least period_ambiguity_cells more strong cells); `better` is then
// the best such alignment when it agrees strongly everywhere (9 strong cells, correlation >=
// period_switch_correlation).
struct PeriodTest {
  bool ambiguous = false;
  std::optional<DenseRefineResult> better;
};
PeriodTest periodTest(const RegisteredObject& e, const DetectorOptions& opt, const MatchCandidate& cand,
                      const Features& scene, const Intrinsics& camera) {
  PeriodTest out;
  if (opt.verify.period_ambiguity_cells > 9) return out;
  std::vector<Eigen::Matrix3d> moved = movedByPeriods(e, cand.H);
  if (moved.empty() && opt.verify.peak_search_count == 0) return out;
  const std::vector<Eigen::Vector2d> region = verificationRegion(e, cand);
  const VerifyResult v0 = verifyInstance(e.pyramid, region, scene.image, camera, cand.H, opt.verify);
  // No alignment can have period_ambiguity_cells more strong cells than 9 - that many: nothing to try.
  if (!v0.ok || v0.strong_cells + opt.verify.period_ambiguity_cells > 9) return out;
  if (opt.verify.peak_search_count > 0) {
    const std::vector<Eigen::Matrix3d> peaks = photometricPeaks(e, cand.H, region, scene.image, camera, opt.verify);
    moved.insert(moved.end(), peaks.begin(), peaks.end());
  }
  if (moved.empty()) return out;
  DenseRefineOptions wide = opt.dense;
  wide.max_corner_shift_px = 0.3 * patternDiagonal(e, cand.H);
  if (!std::isfinite(wide.max_corner_shift_px)) return out;
  VerifyResult best;
  for (const Eigen::Matrix3d& Hp : moved) {
    VerifyResult v = verifyInstance(e.pyramid, region, scene.image, camera, Hp, opt.verify);
    const DenseRefineResult dr = refineDense(e, Hp, scene.image, camera, wide);
    bool refined = false;
    if (dr.ok) {
      const VerifyResult vr = verifyInstance(e.pyramid, region, scene.image, camera, dr.H, opt.verify);
      if (vr.correlation > v.correlation) {
        v = vr;
        refined = true;
      }
    }
    if (!(v.ok && v.correlation > v0.correlation + opt.verify.period_ambiguity_margin &&
          v.strong_cells >= v0.strong_cells + opt.verify.period_ambiguity_cells))
      continue;
    if (out.ambiguous && !(v.correlation > best.correlation)) continue;
    out.ambiguous = true;
    best = v;
    out.better.reset();
    if (refined && v.strong_cells >= 9 && v.correlation >= opt.verify.period_switch_correlation) out.better = dr;
  }
  return out;
}

// What one object searches in a frame.
struct Search {
  bool searched = true;  // false: only_priors and no prior
  cv::Rect roi;          // clipped to the image; empty: nothing of the region is in the image
  ExtractRegion region;  // what the extraction is asked for (roi empty = whole image)
  bool sameExtraction(const Search& o) const {
    return region.roi == o.region.roi && region.min_size_px == o.region.min_size_px &&
           region.max_size_px == o.region.max_size_px && region.inner_margin_px == o.region.inner_margin_px;
  }
};

// The region a predicted pose gives: the projected pattern's bounding box (real image px) grown
// by roi_margin, and the reference keypoint sizes scaled by the predicted homography's local
// scale, widened by scale_margin. False when the pattern is not in front of the camera.
bool predictRegion(const RegisteredObject& e, const ObjectPrior& p, const Intrinsics& cam,
                   cv::Rect* roi, double* min_size, double* max_size, double* margin_px) {
  const PlanarTarget& t = *e.model.target;
  std::vector<Eigen::Vector2d> ref(4), und(4);
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d Xc = *p.cMo * t.corners_o[i];
    if (!(Xc.z() > 1e-6)) return false;
    ref[i] = t.corners_ref_px[i];
    und[i] = projectPinhole(cam.K(), Xc);
    const Eigen::Vector2d px = cam.project(Xc);
    lo = lo.cwiseMin(px);
    hi = hi.cwiseMax(px);
  }
  const Eigen::Matrix3d H = fitHomographyLeastSquares(ref, und);
  if (!H.allFinite() || !lo.allFinite() || !hi.allFinite()) return false;
  double smin = 1e300, smax = 0;
  for (const cv::KeyPoint& k : e.index.features.keypoints) {
    const Eigen::Vector3d y = H * Eigen::Vector3d(k.pt.x, k.pt.y, 1);
    const double u = y.x() / y.z(), v = y.y() / y.z();
    Eigen::Matrix2d J;  // d(scene px) / d(reference px)
    J << H(0, 0) - u * H(2, 0), H(0, 1) - u * H(2, 1), H(1, 0) - v * H(2, 0), H(1, 1) - v * H(2, 1);
    const double s = k.size * std::sqrt(std::abs(J.determinant())) / std::abs(y.z());
    if (!std::isfinite(s)) continue;
    smin = std::min(smin, s);
    smax = std::max(smax, s);
  }
  if (smax <= 0) return false;
  *min_size = smin / p.scale_margin;
  *max_size = smax * p.scale_margin;
  // Grown by the margin, clamped just outside the image (the caller clips it to the image).
  const double m = p.roi_margin * std::max(hi.x() - lo.x(), hi.y() - lo.y());
  *margin_px = std::floor(m);
  auto clampX = [&](double x) { return static_cast<int>(std::clamp(x, -1.0, cam.width + 1.0)); };
  auto clampY = [&](double y) { return static_cast<int>(std::clamp(y, -1.0, cam.height + 1.0)); };
  *roi = cv::Rect(cv::Point(clampX(std::floor(lo.x() - m)), clampY(std::floor(lo.y() - m))),
                  cv::Point(clampX(std::ceil(hi.x() + m) + 1), clampY(std::ceil(hi.y() + m) + 1)));
  return true;
}

Search searchFor(const RegisteredObject& e, const ObjectPrior* prior, const DetectionQuery& q,
                 const Intrinsics& camera) {
  Search s;
  if (!prior && q.only_priors) {
    s.searched = false;
    return s;
  }
  const cv::Rect full(0, 0, camera.width, camera.height);
  cv::Rect roi = full;
  if (prior) {
    cv::Rect predicted;
    double margin_px = 0;
    const bool has_prediction = prior->cMo && e.model.target &&
                                predictRegion(e, *prior, camera, &predicted, &s.region.min_size_px,
                                              &s.region.max_size_px, &margin_px);
    if (prior->roi.area() > 0) {
      roi = prior->roi;
    } else if (has_prediction) {
      roi = predicted;
      // The pattern lies margin_px inside the region: that much of the crop's context is there.
      if (!q.roi || (roi & *q.roi) == roi) s.region.inner_margin_px = margin_px;
    }
  }
  if (q.roi) roi &= *q.roi;
  s.roi = roi & full;
  s.region.roi = s.roi == full ? cv::Rect() : s.roi;
  return s;
}

// Why nothing was accepted, from what the matcher reports.
MissReason matcherMiss(const MatchResult& m, int scene_features, int reference_features) {
  if (scene_features < 4 || reference_features < 4) return MissReason::kTooFewFeatures;
  if (m.global_matches == 0) return MissReason::kNoGlobalMatches;
  if (m.rejected.narrow_inlier_spread > 0) return MissReason::kNarrowInlierSpread;
  if (m.rejected.not_significant > 0) return MissReason::kNotSignificant;
  if (m.rejected.implausible_homography > 0) return MissReason::kImplausibleHomography;
  if (m.rejected.too_few_inliers > 0) return MissReason::kTooFewInliers;
  return MissReason::kTooFewLocalMatches;
}

}  // namespace

const char* missReasonName(MissReason r) {
  switch (r) {
    case MissReason::kNone: return "none";
    case MissReason::kNotSearched: return "not searched";
    case MissReason::kTooFewFeatures: return "too few features";
    case MissReason::kNoGlobalMatches: return "no global matches";
    case MissReason::kTooFewLocalMatches: return "too few local matches";
    case MissReason::kTooFewInliers: return "too few inliers";
    case MissReason::kImplausibleHomography: return "implausible homography";
    case MissReason::kNarrowInlierSpread: return "narrow inlier spread";
    case MissReason::kPoseFailed: return "pose failed";
    case MissReason::kSanity: return "sanity check";
    case MissReason::kNotSignificant: return "not significant";
    case MissReason::kNotVerified: return "not verified";
  }
  return "?";
}

void DetectorOptions::check() const {
  sift.check();
  match.check();
  pose_options.check();
  dense.check();
  sanity.check();
  verify.check();
}

std::optional<Detection> DetectionResult::find(int object, int instance) const {
  for (const auto& d : detections)
    if (d.found && d.object == object && d.instance == instance) return d;
  return std::nullopt;
}

Detector::Detector(DetectorOptions opt) : opt_(std::move(opt)) { opt_.check(); }
Detector::~Detector() = default;
Detector::Detector(const Detector&) = default;
Detector::Detector(Detector&&) noexcept = default;
Detector& Detector::operator=(const Detector&) = default;
Detector& Detector::operator=(Detector&&) noexcept = default;

int Detector::objectCount() const { return static_cast<int>(objects_.size()); }
const ObjectModel& Detector::object(int id) const { return objects_.at(id).model; }

int Detector::addObject(const ObjectModel& object) {
  if (object.reference.empty() || object.reference.type() != CV_8UC1)
    throw ConfigError(object.source.empty() ? object.name : object.source, "reference_image",
                      "expected a non-empty 8-bit grayscale image");
  RegisteredObject e;
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
  if (object.target) {
    // Reference px -> the pattern plane (its frame oMp; metres scaled to about the reference's
    // px): the inverse of x_ref ~ K_ref [r1 r2 t] (x, y, 1), [r1 r2 t] of the reference's cMp
    // (as in poseFromHomography).
    const PlanarTarget& t = *object.target;
    const Pose ref_cMp = t.ref_cMo * t.oMp;
    Eigen::Matrix3d A_ref;
    A_ref << ref_cMp.R.col(0), ref_cMp.R.col(1), ref_cMp.t;
    const double scale = e.index.diagonal_px / std::max(1e-12, (t.corners_o[2] - t.corners_o[0]).norm());
    const Eigen::Matrix3d R = Eigen::Vector3d(scale, scale, 1).asDiagonal() * (t.K_ref * A_ref).inverse();
    if (R.allFinite()) e.index.rectify_px = R;
  }
  e.polygon_und_px = e.index.polygon_px;
  e.periods = repeatPeriods(e.index);
  e.pyramid = buildReferencePyramid(object.reference);
  // Dense refinement needs an undistorted reference and a region that is the pattern (one that
  // is not its bounding box is a mask on the template).
  e.dense_usable = (!object.camera || !object.camera->hasDistortion()) && object.pattern_region_exact;
  double minx = 1e300, miny = 1e300, maxx = -1e300, maxy = -1e300;
  for (const Eigen::Vector2d& p : e.polygon_und_px) {
    minx = std::min(minx, p.x()), maxx = std::max(maxx, p.x());
    miny = std::min(miny, p.y()), maxy = std::max(maxy, p.y());
  }
  e.region_is_rect = std::abs(signedArea(e.polygon_und_px)) >= 0.98 * (maxx - minx) * (maxy - miny);
  objects_.push_back(std::move(e));
  return static_cast<int>(objects_.size()) - 1;
}

DetectionResult Detector::detect(const cv::Mat& image, const Intrinsics& camera,
                                 const FrameStamp& frame, const DetectionQuery& query) const {
  const auto t0 = Clock::now();
  DetectionResult res;
  auto fail = [&](const std::string& error) {
    res = DetectionResult{};
    res.ok = false;
    res.error = error;
  };
  try {
    std::string problem = validateImage(image, camera);
    if (problem.empty()) problem = validateQuery(query, objectCount());
    if (!problem.empty()) {
      fail(problem);
    } else {
      cv::Mat gray = image;
      if (image.channels() == 3) cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
      if (image.channels() == 4) cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
      res = detectGray(gray, camera, query);
    }
  } catch (const cv::Exception& e) {
    fail("detection failed: " + oneLine(e.what()));
  } catch (const std::bad_alloc&) {
    fail("detection failed: out of memory");
  } catch (const std::exception& e) {
    fail("detection failed: " + oneLine(e.what()));
  } catch (...) {
    fail("detection failed: unknown exception");
  }
  res.frame = frame;
  res.time_ms.total = msSince(t0);
  return res;
}

DetectionResult Detector::detectGray(const cv::Mat& gray, const Intrinsics& camera,
                                     const DetectionQuery& query) const {
  const DetectorOptions& opt = opt_;
  DetectionResult res;
  std::vector<const ObjectPrior*> prior_of(objectCount(), nullptr);
  for (const ObjectPrior& p : query.priors) prior_of[p.object] = &p;

  // One extraction per distinct region, in object order.
  auto t = Clock::now();
  struct Extraction {
    Search search;
    Features features;
    GridIndex grid;
  };
  std::vector<Search> searches;
  std::vector<Extraction> extractions;
  std::vector<int> extraction_of;
  for (int id = 0; id < objectCount(); ++id) {
    searches.push_back(searchFor(objects_[id], prior_of[id], query, camera));
    const Search& s = searches.back();
    int x = -1;
    if (s.searched && s.roi.area() > 0) {
      for (size_t k = 0; k < extractions.size() && x < 0; ++k)
        if (extractions[k].search.sameExtraction(s)) x = static_cast<int>(k);
      if (x < 0) {
        Features f = extractFeatures(gray, camera, opt.sift, s.region);
        GridIndex grid(f.keypoints, f.image_size);
        res.scene_features += f.size();
        extractions.push_back({s, std::move(f), std::move(grid)});
        x = static_cast<int>(extractions.size()) - 1;
      }
    }
    extraction_of.push_back(x);
  }
  res.time_ms.extract = msSince(t);

  const Features no_features;
  for (int id = 0; id < objectCount(); ++id) {
    const RegisteredObject& e = objects_[id];
    const Search& s = searches[id];
    const Extraction* x = extraction_of[id] >= 0 ? &extractions[extraction_of[id]] : nullptr;
    const Features& scene = x ? x->features : no_features;
    ObjectStats st;
    st.object = id;
    st.roi = s.roi;
    st.min_keypoint_px = s.region.min_size_px;
    st.max_keypoint_px = s.region.max_size_px;
    st.scene_features = scene.size();

    t = Clock::now();
    MatchResult m;
    if (x) m = matchObjectUnchecked(e.index, scene, x->grid, opt.match);
    res.time_ms.match += msSince(t);
    st.global_matches = m.global_matches;
    st.hypotheses_evaluated = m.hypotheses_evaluated;
    st.candidates = static_cast<int>(m.instances.size());
    st.rejected = m.rejected;

    t = Clock::now();
    int found = 0, pose_failures = 0, sanity_failures = 0, verify_failures = 0;
    SanityStatus rejected = SanityStatus::kOk;
    // The checks of one candidate (pose, its plausibility, sanity, verification); fills d.
    enum class Check { kOk, kPoseFailed, kPoseDisagrees, kSanity, kNotVerified };
    auto check = [&](const MatchCandidate& cand, const DenseRefineResult* dense, Detection* out) {
      Detection& d = *out;
      d.object = id;
      d.H = cand.H;
      d.inliers = static_cast<int>(cand.inliers.size());
      d.score = cand.score;
      d.log10_nfa = cand.log10_nfa;
      if (e.model.target) {
        bool from_features = false;
        const PoseResult p = estimatePose(e, opt, cand, scene, camera, opt.pose, dense, &from_features);
        if (!p.ok) return Check::kPoseFailed;
        d.cMo = p.cMo;
        d.pose_rms_px = p.rms_px;
        for (int i = 0; i < 4; ++i) d.corners[i] = camera.project(p.cMo * e.model.target->corners_o[i]);
        // Plausibility of the pose: it must put the pattern where the matches put it (a pose
        // caught in the wrong one of a plane's two solutions, or pulled by a few bad points,
        // does not).
        double diag = 0, gap = 0;
        std::array<Eigen::Vector2d, 4> hc;
        for (int i = 0; i < 4; ++i) hc[i] = distortPixel(camera, applyHomography(cand.H, e.corners_und_px[i]));
        diag = 0.5 * ((hc[2] - hc[0]).norm() + (hc[3] - hc[1]).norm());
        for (int i = 0; i < 4; ++i) gap = std::max(gap, (hc[i] - d.corners[i]).norm());
        if (!(gap <= std::max(kMaxPoseGapPx, kMaxPoseGapFraction * diag))) return Check::kPoseDisagrees;
        // A pose fitted to the features that reprojects them poorly: the consensus does not
        // come from one rigid plane (on a facade, matches spanning two windows).
        if (opt.verify.enabled && from_features && !(p.rms_px <= opt.verify.max_feature_pose_rms_px))
          return Check::kNotVerified;
      } else {
        // 2D-only: the dense alignment's H when it converged (every pixel of the pattern, not a
        // few keypoints) on a template not much coarser than the scene, the features' otherwise.
        if (opt.dense.enabled && e.dense_usable && !scene.image.empty()) {
          const DenseRefineResult dr = dense ? *dense : refineDense(e, cand.H, scene.image, camera, opt.dense);
          if (dr.ok && dr.level >= 0) {
            std::array<Eigen::Vector2d, 4> q;
            for (int i = 0; i < 4; ++i) q[i] = applyHomography(dr.H, e.corners_und_px[i]);
            const double coarsening = std::ldexp(1.0, dr.level) *
                                      std::sqrt(std::abs(signedArea(q)) / std::abs(signedArea(e.corners_und_px)));
            if (coarsening <= opt.dense.max_2d_coarsening) d.H = dr.H;
          }
        }
        for (int i = 0; i < 4; ++i)
          d.corners[i] = distortPixel(camera, applyHomography(d.H, e.corners_und_px[i]));
      }
      d.sanity = checkDetection(d.corners, d.cMo, camera.width, camera.height, opt.sanity);
      if (d.sanity != SanityStatus::kOk) return Check::kSanity;
      if (opt.verify.enabled) {
        const VerifyResult v = verifyInstance(e.pyramid, verificationRegion(e, cand), scene.image, camera, cand.H, opt.verify);
        d.correlation = v.correlation;
        if (!v.ok) return Check::kNotVerified;
        // On a repeated motif cells agree by chance under a wrong lattice map: more must agree.
        if (!e.periods.empty() && v.strong_cells < std::min(opt.verify.periodic_min_strong_cells, v.textured_cells))
          return Check::kNotVerified;
      }
      return Check::kOk;
    };
    auto consider = [&](const MatchCandidate& matched) {
      DenseRefineResult dense;
      const bool try_realign = x && e.dense_usable && opt.verify.enabled && opt.verify.realign &&
                               !scene.image.empty() && inViewFraction(e, matched.H, camera) >= opt.verify.realign_min_in_view;
      const MatchCandidate cand = try_realign ? realign(e, opt, matched, scene, x->grid, camera, &dense) : matched;
      Detection d;
      Check c = check(cand, try_realign ? &dense : nullptr, &d);
      if (c == Check::kOk && try_realign) {
        // Only an instance that passed every check is compared with its repeat-period
        // alignments, and one of them replaces it only when it passes them too and its warped
        // reference correlates at least as well.
        const std::optional<MatchCandidate> other = alignAcrossPeriods(e, opt, cand, scene, x->grid);
        Detection od;
        const MatchCandidate* kept = &cand;
        if (other && check(*other, nullptr, &od) == Check::kOk && od.correlation >= d.correlation) {
          d = od;
          kept = &*other;
        }
        // The kept one is refused when a period away (or at a photometric peak beside it) it
        // would agree clearly better, unless that
        // alignment agrees strongly everywhere, its features match there and it passes every check:
        // then it replaces it.
        const PeriodTest pt = periodTest(e, opt, *kept, scene, camera);
        if (pt.ambiguous) {
          c = Check::kNotVerified;
          std::optional<MatchCandidate> moved;
          if (pt.better) moved = matchUnderHomography(e.index, scene, x->grid, opt.match, pt.better->H);
          Detection md;
          if (moved) {
            moved->H = pt.better->H;
            if (check(*moved, &*pt.better, &md) == Check::kOk) {
              d = md;
              c = Check::kOk;
            }
          }
        }
      }
      switch (c) {
        case Check::kOk:
          d.found = true;
          d.instance = found++;
          res.detections.push_back(d);
          break;
        case Check::kPoseFailed:
          rejected = SanityStatus::kNotFinite;
          ++pose_failures;
          break;
        case Check::kPoseDisagrees:
          if (found == 0) rejected = SanityStatus::kPoseDisagrees;
          if (sanity_failures++ == 0) st.sanity = SanityStatus::kPoseDisagrees;
          break;
        case Check::kSanity:
          if (found == 0) rejected = d.sanity;
          if (sanity_failures++ == 0) st.sanity = d.sanity;
          break;
        case Check::kNotVerified:
          ++verify_failures;
          break;
      }
    };
    for (const MatchCandidate& matched : m.instances) consider(matched);
    double spare_ms = 0;  // the spare candidate's matching: match time, not pose time
    // The matcher's search ends once it has max_instances candidates. When every one of them
    // failed the checks (on a facade, a consensus one window off that the pose check refuses),
    // the matcher is asked for one more (verify.spare_candidate) and the new ones are checked
    // the same way; frames where a candidate passes, or where there was none, pay nothing.
    if (found == 0 && x && opt.verify.enabled && opt.verify.spare_candidate && !m.instances.empty() &&
        static_cast<int>(m.instances.size()) >= opt.match.max_instances) {
      const auto t_spare = Clock::now();
      MatchOptions more = opt.match;
      ++more.max_instances;
      const MatchResult spare = matchObjectUnchecked(e.index, scene, x->grid, more);
      spare_ms = msSince(t_spare);
      res.time_ms.match += spare_ms;
      for (const MatchCandidate& c : spare.instances) {
        const bool tried = std::any_of(m.instances.begin(), m.instances.end(),
                                       [&](const MatchCandidate& o) { return o.H == c.H; });
        if (!tried) consider(c);
      }
    }
    if (found == 0) {
      res.detections.emplace_back();
      res.detections.back().object = id;
      res.detections.back().sanity = rejected;
      if (!s.searched) st.miss = MissReason::kNotSearched;
      else if (verify_failures > 0) st.miss = MissReason::kNotVerified;
      else if (sanity_failures > 0) st.miss = MissReason::kSanity;
      else if (pose_failures > 0) st.miss = MissReason::kPoseFailed;
      else st.miss = matcherMiss(m, scene.size(), e.index.features.size());
    }
    res.stats.push_back(st);
    res.time_ms.pose += msSince(t) - spare_ms;
  }
  return res;
}

PoseAlignment Detector::alignPose(const cv::Mat& image, const Intrinsics& camera, int object,
                                 const Pose& cMo, const DenseRefineOptions* dense) const {
  PoseAlignment out;
  try {
    if (object < 0 || object >= objectCount() || !cMo.isFinite()) return out;
    const RegisteredObject& e = objects_[static_cast<size_t>(object)];
    if (!e.model.target || !e.dense_usable || !validateImage(image, camera).empty()) return out;
    cv::Mat gray = image;
    if (image.channels() == 3) cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
    if (image.channels() == 4) cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
    // The homography cMo predicts: undistorted reference px -> undistorted scene px.
    std::vector<Eigen::Vector2d> ref(4), und(4);
    for (int i = 0; i < 4; ++i) {
      const Eigen::Vector3d Xc = cMo * e.model.target->corners_o[i];
      if (!(Xc.z() > 1e-6)) return out;
      ref[i] = e.corners_und_px[i];
      und[i] = projectPinhole(camera.K(), Xc);
    }
    const Eigen::Matrix3d H = fitHomographyLeastSquares(ref, und);
    if (!H.allFinite()) return out;
    const DenseRefineResult dr = refineDense(e, H, gray, camera, dense ? *dense : opt_.dense);
    out.correlation = dr.correlation;
    out.corner_shift_px = dr.corner_shift_px;
    out.used_fraction = 1 - dr.masked_fraction;
    if (!dr.ok) return out;
    const PoseResult p = poseFromDenseH(e, opt_, dr.H, camera, &cMo);
    if (!p.ok || !p.cMo.isFinite()) return out;
    out.ok = true;
    out.cMo = p.cMo;
  } catch (...) {  // OpenCV, out of memory: not aligned
    out.ok = false;
  }
  return out;
}

StereoDetectionResult Detector::detectStereo(const cv::Mat& left, const cv::Mat& right,
                                             const StereoRig& rig, const FrameStamp& frame) const {
  StereoDetectionResult out;
  out.frame = frame;
  out.left = detect(left, rig.left, frame);
  out.right = detect(right, rig.right, frame);
  if (!out.left.ok || !out.right.ok) {
    out.ok = false;
    out.error = !out.left.ok ? "left: " + out.left.error : "right: " + out.right.error;
    return out;
  }
  try {
    for (int id = 0; id < objectCount(); ++id) {
      StereoDetection s;
      s.object = id;
      s.left.object = s.right.object = id;
      if (const auto d = out.left.find(id)) s.left = *d;
      if (const auto d = out.right.find(id)) s.right = *d;
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
  } catch (const std::exception& e) {  // out of memory
    out.objects.clear();
    out.ok = false;
    out.error = "fusion failed: " + oneLine(e.what());
  }
  return out;
}

Features DetectorInternals::extract(const Detector& det, const cv::Mat& gray,
                                    const Intrinsics& camera, const ExtractRegion& region) {
  return extractFeatures(gray, camera, det.opt_.sift, region);
}

const ReferenceIndex& DetectorInternals::referenceIndex(const Detector& det, int object) {
  return det.objects_.at(object).index;
}

PoseResult DetectorInternals::estimatePose(const Detector& det, int object,
                                           const MatchCandidate& match, const Features& scene,
                                           const Intrinsics& camera, PoseMethod method) {
  return detector::estimatePose(det.objects_.at(object), det.opt_, match, scene, camera, method);
}

}  // namespace refgrasp::detector
