#include "eval/pairs_eval.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>

#include "core/pose.h"
#include "detector/homography.h"
#include "detector/object.h"
#include "eval/classic.h"
#include "eval/eval_util.h"
#include "robot/sim/realistic_scene.h"
#include "robot/sim/render.h"
#include "robot/sim/synthetic_scene.h"

namespace refgrasp::eval {

namespace {

constexpr double kDeg = M_PI / 180;
constexpr double kMetresPerTexel = 0.001;

using detail::median;
using detail::mix;
using detail::uni;

}  // namespace

std::vector<std::string> pairTextures() {
  std::vector<std::string> t = testing::photoTextures();
  for (const auto& p : testing::targetTextures()) t.push_back(p);
  return t;
}

uint64_t pairSeed(uint64_t split_seed, int texture_index) {
  return mix(split_seed, static_cast<uint64_t>(texture_index));
}

const char* pairFamilyName(PairFamily f) {
  switch (f) {
    case PairFamily::kViewpoint: return "viewpoint";
    case PairFamily::kZoomRotation: return "zoom+rotation";
    case PairFamily::kBlur: return "blur";
    case PairFamily::kLight: return "light";
    case PairFamily::kJpeg: return "jpeg";
    case PairFamily::kNearLight: return "near-light";
    case PairFamily::kNearJpeg: return "near-jpeg";
  }
  return "?";
}

namespace {

const double kTilt[kPairLevels] = {20, 30, 40, 50, 60};            // deg
const double kZoom[kPairLevels] = {1.3, 1.7, 2.1, 2.5, 2.9};       // scene px per reference px
const double kRoll[kPairLevels] = {10, 20, 30, 40, 50};            // deg
const double kBlur[kPairLevels] = {1, 2, 3, 4, 5};                 // defocus sigma, px
const double kGain[kPairLevels] = {0.7, 0.55, 0.4, 0.3, 0.2};
const int kJpeg[kPairLevels] = {40, 25, 15, 8, 4};
const int kNearWidth[kPairLevels] = {800, 1000, 1200, 1400, 1600};  // px
const int kNearJpeg[kPairLevels] = {90, 70, 50, 30, 10};

// The reference's own camera: a mild look (gain and gamma within 10 %, noise 0.5-1.5, JPEG 90).
void applyReferenceLook(cv::Mat& reference, std::mt19937_64& rng) {
  testing::CameraLook look;
  look.gain = uni(rng, 0.9, 1.1);
  look.gamma = uni(rng, 0.9, 1.1);
  look.noise_sigma = uni(rng, 0.5, 1.5);
  look.jpeg_quality = 90;
  testing::applyCameraLook(reference, look, rng);
}

// The scene camera's mild look (gain within 10 %, noise 1-2.5, defocus up to 0.6 px, JPEG 85),
// which each family then changes in its own way.
testing::CameraLook mildSceneLook(std::mt19937_64& rng) {
  testing::CameraLook look;
  look.gain = uni(rng, 0.9, 1.1);
  look.noise_sigma = uni(rng, 1, 2.5);
  look.defocus_sigma_px = uni(rng, 0, 0.6);
  look.jpeg_quality = 85;
  return look;
}

// The near-identity families (pairs_eval.h): the picture at `width` px as the reference, the
// scene a second photo of it from nearly the same place.
ViewPair makeNearIdentityPair(const cv::Mat& tex, ViewPair p, int width, std::mt19937_64& rng) {
  const double r = static_cast<double>(width) / tex.cols;
  cv::Mat base;
  cv::resize(tex, base, cv::Size(width, static_cast<int>(std::lround(r * tex.rows))), 0, 0,
             r > 1 ? cv::INTER_CUBIC : cv::INTER_AREA);
  p.reference = base.clone();
  applyReferenceLook(p.reference, rng);
  const int margin = base.cols / 4;
  sim::TexturedPlane plane;
  plane.texture = testing::photoClutterBackground(rng(), base.cols + 2 * margin, base.rows + 2 * margin, {p.texture});
  base.copyTo(plane.texture(cv::Rect(margin, margin, base.cols, base.rows)));
  plane.width_m = plane.texture.cols * kMetresPerTexel;
  plane.height_m = plane.texture.rows * kMetresPerTexel;
  const double s = uni(rng, 0.97, 1.03), tilt = uni(rng, 0, 2) * kDeg, roll = uni(rng, -2, 2) * kDeg;
  const double phi = uni(rng, 0, 2 * M_PI);
  const Eigen::Matrix3d R =
      axisAngle(Eigen::Vector3d::UnitZ(), roll) * axisAngle(Eigen::Vector3d(std::cos(phi), std::sin(phi), 0), tilt);
  const double f = 1.2 * base.cols;
  p.camera = Intrinsics::pinhole(base.cols, base.rows, f, 0.5 * (base.cols - 1), 0.5 * (base.rows - 1));
  const double z = f * kMetresPerTexel / s;
  const Eigen::Vector3d ray(uni(rng, -5, 5) / f, uni(rng, -5, 5) / f, 1);
  // The plane frame's origin is the canvas centre, the picture's: aimed at it.
  plane.cMp = Pose(R, z * ray);
  p.scene = sim::renderView(p.camera, {plane}, cv::Mat());
  testing::CameraLook look = mildSceneLook(rng);
  if (p.family == PairFamily::kNearLight) {
    look.gain = uni(rng, 0.6, 1.4);
    look.gamma = uni(rng, 0.7, 1.4);
    look.gradient = uni(rng, 0.1, 0.3);
    look.gradient_angle_rad = uni(rng, 0, 2 * M_PI);
  } else {
    look.jpeg_quality = kNearJpeg[p.level];
  }
  testing::applyCameraLook(p.scene, look, rng);
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();  // reference px -> canvas texels
  A(0, 2) = margin;
  A(1, 2) = margin;
  p.H_true = sim::textureToImage(p.camera, plane) * A;
  return p;
}

}  // namespace

std::string pairLevelLabel(PairFamily f, int level) {
  char buf[64];
  switch (f) {
    case PairFamily::kViewpoint: std::snprintf(buf, sizeof buf, "%g deg", kTilt[level]); break;
    case PairFamily::kZoomRotation: std::snprintf(buf, sizeof buf, "%gx, %g deg", kZoom[level], kRoll[level]); break;
    case PairFamily::kBlur: std::snprintf(buf, sizeof buf, "sigma %g px", kBlur[level]); break;
    case PairFamily::kLight: std::snprintf(buf, sizeof buf, "gain %g", kGain[level]); break;
    case PairFamily::kJpeg: std::snprintf(buf, sizeof buf, "quality %d", kJpeg[level]); break;
    case PairFamily::kNearLight: std::snprintf(buf, sizeof buf, "%d px", kNearWidth[level]); break;
    case PairFamily::kNearJpeg: std::snprintf(buf, sizeof buf, "quality %d", kNearJpeg[level]); break;
  }
  return buf;
}

ViewPair makeViewPair(const std::string& texture, PairFamily family, int level, uint64_t seed) {
  std::mt19937_64 rng(mix(seed, static_cast<uint64_t>(family) * 16 + static_cast<uint64_t>(level)));
  const cv::Mat tex = testing::loadMedia(texture);
  ViewPair p;
  p.texture = texture;
  p.family = family;
  p.level = level;
  if (family == PairFamily::kNearLight) return makeNearIdentityPair(tex, p, kNearWidth[level], rng);
  if (family == PairFamily::kNearJpeg)
    return makeNearIdentityPair(tex, p, static_cast<int>(std::lround(uni(rng, 800, 1600))), rng);
  // Reference: the picture alone, at most 640 px wide, with a mild look of its own camera.
  const double r = std::min(1.0, 640.0 / tex.cols);
  if (r < 1)
    cv::resize(tex, p.reference, cv::Size(), r, r, cv::INTER_AREA);
  else
    p.reference = tex.clone();
  applyReferenceLook(p.reference, rng);
  const double rx = static_cast<double>(p.reference.cols) / tex.cols, ry = static_cast<double>(p.reference.rows) / tex.rows;
  // The picture on a wall of clutter three times its size.
  sim::TexturedPlane plane;
  plane.texture = testing::photoClutterBackground(rng(), 3 * tex.cols, 3 * tex.rows, {texture});
  tex.copyTo(plane.texture(cv::Rect(tex.cols, tex.rows, tex.cols, tex.rows)));
  plane.width_m = plane.texture.cols * kMetresPerTexel;
  plane.height_m = plane.texture.rows * kMetresPerTexel;
  // Scene pose: scale s (scene px per reference px) at the point aimed at, tilt, roll.
  double s = uni(rng, 0.7, 0.85), tilt = uni(rng, 0, 8) * kDeg, roll = uni(rng, -5, 5) * kDeg;
  if (family == PairFamily::kViewpoint) tilt = kTilt[level] * kDeg;
  if (family == PairFamily::kZoomRotation) {
    s = kZoom[level];
    tilt = uni(rng, 0, 5) * kDeg;
    roll = (rng() % 2 ? 1 : -1) * kRoll[level] * kDeg;
  }
  const double phi = uni(rng, 0, 2 * M_PI);
  const Eigen::Matrix3d R =
      axisAngle(Eigen::Vector3d::UnitZ(), roll) * axisAngle(Eigen::Vector3d(std::cos(phi), std::sin(phi), 0), tilt);
  p.camera = Intrinsics::pinhole(640, 480, 700, 319.5, 239.5);
  const double z = p.camera.fx * kMetresPerTexel / (s * std::sqrt(rx * ry));
  const Eigen::Vector3d P(uni(rng, -0.1, 0.1) * tex.cols * kMetresPerTexel, uni(rng, -0.1, 0.1) * tex.rows * kMetresPerTexel, 0);
  const Eigen::Vector3d ray((uni(rng, -20, 20)) / p.camera.fx, (uni(rng, -20, 20)) / p.camera.fy, 1);
  plane.cMp = Pose(R, z * ray - R * P);
  p.scene = sim::renderView(p.camera, {plane}, cv::Mat());
  // The scene's look: mild, but for the family's own change.
  testing::CameraLook look = mildSceneLook(rng);
  if (family == PairFamily::kBlur) look.defocus_sigma_px = kBlur[level];
  if (family == PairFamily::kLight) {
    look.gain = kGain[level];
    look.gradient = 0.2;
    look.gradient_angle_rad = uni(rng, 0, 2 * M_PI);
  }
  if (family == PairFamily::kJpeg) look.jpeg_quality = kJpeg[level];
  testing::applyCameraLook(p.scene, look, rng);
  // Reference px -> canvas texels (pixel centres) -> scene px.
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();
  A(0, 0) = 1 / rx;
  A(1, 1) = 1 / ry;
  A(0, 2) = 0.5 / rx - 0.5 + tex.cols;
  A(1, 2) = 0.5 / ry - 0.5 + tex.rows;
  p.H_true = sim::textureToImage(p.camera, plane) * A;
  return p;
}

double worstCornerError(const ViewPair& p, const Eigen::Matrix3d& H) {
  const double w = p.reference.cols - 1.0, h = p.reference.rows - 1.0;
  const Eigen::Vector2d c[4] = {{0, 0}, {w, 0}, {w, h}, {0, h}};
  double err = 0;
  for (const auto& x : c) err = std::max(err, (detector::applyHomography(H, x) - detector::applyHomography(p.H_true, x)).norm());
  return std::isfinite(err) ? err : 1e9;
}

std::vector<PairOutcome> evaluatePairs(const detector::DetectorOptions& opt, int seeds, uint64_t first_seed,
                                       int only_family, const std::function<void(int, int)>& progress) {
  const auto textures = pairTextures();
  std::vector<PairOutcome> out;
  const int families = only_family >= 0 ? 1 : kPairFamilies;
  const int total = seeds * families * kPairLevels * static_cast<int>(textures.size());
  for (int k = 0; k < seeds; ++k)
    for (int f = 0; f < kPairFamilies; ++f) {
      if (only_family >= 0 && f != only_family) continue;
      for (int l = 0; l < kPairLevels; ++l)
        for (size_t t = 0; t < textures.size(); ++t) {
          const uint64_t seed = pairSeed(first_seed + static_cast<uint64_t>(k), static_cast<int>(t));
          const ViewPair p = makeViewPair(textures[t], static_cast<PairFamily>(f), l, seed);
          const detector::ObjectModel model = detector::makeObjectModel(textures[t], p.reference, std::nullopt, std::nullopt);
          PairOutcome o;
          o.texture = textures[t];
          o.family = p.family;
          o.level = l;
          o.seed = first_seed + static_cast<uint64_t>(k);
          detector::Detector det(opt);
          det.addObject(model);
          detector::DetectionResult res;
          o.r_ms = detail::timed(true, [&] { res = det.detect(p.scene, p.camera); });
          if (const auto d = res.find(0)) {
            o.r_reported = true;
            o.r_err = worstCornerError(p, d->H);
            o.r_inliers = d->inliers;
          } else if (res.ok && !res.stats.empty()) {
            o.r_miss = detector::missReasonName(res.stats[0].miss);
          } else {
            o.r_miss = res.error;
          }
          const ClassicPipeline classic(model);
          ClassicResult c;
          o.c_ms = detail::timed(true, [&] { c = classic.detect(p.scene, p.camera); });
          if (c.found) {
            o.c_reported = true;
            o.c_err = worstCornerError(p, c.H);
            o.c_inliers = c.inliers;
          }
          out.push_back(o);
          if (progress) progress(static_cast<int>(out.size()), total);
        }
    }
  return out;
}

PairCounts countPairs(const std::vector<PairOutcome>& rows, double tol_px) {
  PairCounts c;
  for (const auto& r : rows) {
    ++c.n;
    c.within_r += r.r_reported && r.r_err <= tol_px;
    c.within_c += r.c_reported && r.c_err <= tol_px;
    c.reported_r += r.r_reported;
    c.reported_c += r.c_reported;
    c.wrong_r += r.r_reported && r.r_err > 10 * tol_px;
    c.wrong_c += r.c_reported && r.c_err > 10 * tol_px;
  }
  return c;
}

std::string formatPairTables(const std::vector<PairOutcome>& rows, double tol_px) {
  std::ostringstream o;
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "| pairs: refgrasp / classic | pairs | corners within %g px | reported | wrong (> %g px) | "
                "median worst-corner error where both within %g px | median time per scene, ms |\n"
                "|---|---|---|---|---|---|---|\n",
                tol_px, 10 * tol_px, 10 * tol_px);
  o << buf;
  auto line = [&](const std::string& label, const std::vector<PairOutcome>& rs) {
    const PairCounts c = countPairs(rs, tol_px);
    std::vector<double> er, ec, tr, tc;
    for (const auto& r : rs) {
      tr.push_back(r.r_ms);
      tc.push_back(r.c_ms);
    }
    for (const auto& r : rs)
      if (r.r_reported && r.c_reported && r.r_err <= 10 * tol_px && r.c_err <= 10 * tol_px) {
        er.push_back(r.r_err);
        ec.push_back(r.c_err);
      }
    std::snprintf(buf, sizeof buf, "| %s | %d | **%d** / %d | %d / %d | %d / %d | **%.2f** / %.2f | %.0f / %.0f |\n",
                  label.c_str(), c.n, c.within_r, c.within_c, c.reported_r, c.reported_c, c.wrong_r, c.wrong_c, median(er),
                  median(ec), median(tr), median(tc));
    o << buf;
  };
  for (int f = 0; f < kPairFamilies; ++f) {
    std::vector<PairOutcome> fam;
    for (int l = 0; l < kPairLevels; ++l) {
      std::vector<PairOutcome> rs;
      for (const auto& r : rows)
        if (static_cast<int>(r.family) == f && r.level == l) rs.push_back(r);
      if (rs.empty()) continue;
      line(std::string(pairFamilyName(static_cast<PairFamily>(f))) + " " + pairLevelLabel(static_cast<PairFamily>(f), l), rs);
      fam.insert(fam.end(), rs.begin(), rs.end());
    }
    if (!fam.empty()) line(std::string("**") + pairFamilyName(static_cast<PairFamily>(f)) + "**", fam);
  }
  line("**all**", rows);
  return o.str();
}

}  // namespace refgrasp::eval
