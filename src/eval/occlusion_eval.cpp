#include "eval/occlusion_eval.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>

#include "core/geometry.h"
#include "detector/detector_internal.h"
#include "eval/classic.h"
#include "eval/eval_util.h"
#include "robot/sim/render.h"
#include "robot/sim/synthetic_scene.h"
#include "robot/sim/synthetic_sequence.h"
#include "servo/replay.h"
#include "servo/tracker.h"

namespace refgrasp::eval {

namespace {

constexpr double kDeg = M_PI / 180;
constexpr double kWidth = 0.2;        // target width, m (the realistic sets' 20 cm pattern)
constexpr double kWallBehind = 0.6;   // photo-clutter wall behind the target, m
constexpr double kWallWidth = 2.4;    // wide enough to fill the view from 0.85 m at 25 deg

using detail::mix;
using detail::uni;

// The camera's slow sway about the target, t in [0, 1]: one period of distance, half a turn of
// the tilt direction; the phases and ranges are the sequence's.
struct SwayParams {
  double distance = 0.65, distance_amp = 0.1, tilt = 15 * kDeg, tilt_dir = 0, roll = 0.1, phase = 0;
};

testing::ViewPoint sway(const SwayParams& p, double t) {
  const double a = 2 * M_PI * t + p.phase;
  testing::ViewPoint v;
  v.distance_m = p.distance + p.distance_amp * std::sin(a);
  v.tilt_rad = p.tilt * (0.6 + 0.4 * std::sin(0.5 * a));
  v.tilt_dir_rad = p.tilt_dir + 0.5 * M_PI * t;
  v.roll_rad = p.roll * std::sin(0.7 * a);
  v.look_x_m = 0.02 * std::sin(1.3 * a);
  v.look_y_m = 0.015 * std::cos(0.9 * a);
  return v;
}

std::vector<cv::Point2f> projected(const Intrinsics& cam, const Pose& cMp, double w, double h) {
  std::vector<cv::Point2f> q;
  for (const auto& c : sim::projectPlaneCorners(cam, sim::TexturedPlane{cv::Mat(), w, h, cMp}))
    q.emplace_back(static_cast<float>(c.x()), static_cast<float>(c.y()));
  return q;
}

// Fraction of the convex quad `target` that `card` covers.
double coverOf(const std::vector<cv::Point2f>& target, const std::vector<cv::Point2f>& card) {
  std::vector<cv::Point2f> inter;
  const double area = std::abs(cv::contourArea(target));
  return area > 0 ? cv::intersectConvexConvex(target, card, inter, true) / area : 0;
}

}  // namespace

std::vector<OcclusionSequenceSpec> occlusionSequences(uint64_t seed, int count, int frames) {
  const auto& photos = testing::photoTextures();
  const auto& targets = testing::targetTextures();
  std::vector<OcclusionSequenceSpec> out;
  for (int k = 0; k < count; ++k) {
    std::mt19937_64 rng(mix(seed, 0x0CC1 + static_cast<uint64_t>(k)));
    OcclusionSequenceSpec s;
    s.texture = k % 2 == 0 ? photos[(k / 2) % photos.size()] : targets[(k / 2) % targets.size()];
    // The card: another photograph (never the target's picture, nor the scene showing it).
    std::vector<std::string> pool;
    for (const auto& p : photos)
      if (p != s.texture) pool.push_back(p);
    s.occluder = pool[static_cast<size_t>(3 * k + 1) % pool.size()];
    s.frames = frames;
    s.seed = rng();
    out.push_back(s);
  }
  return out;
}

OcclusionSequence::OcclusionSequence(OcclusionSequenceSpec spec) : spec_(std::move(spec)) {
  std::mt19937_64 rng(mix(spec_.seed, 0xABCD));
  const cv::Mat tex = testing::loadMedia(spec_.texture);
  object_.texture = spec_.texture;
  object_.width_m = kWidth;
  object_.height_m = kWidth * tex.rows / tex.cols;
  testing::ReferencePhotoSpec ps;
  ps.tilt_rad = uni(rng, 0, 30 * kDeg);
  ps.width_px = uni(rng, 180, 360);
  ps.look_strength = uni(rng, 0.2, 0.6);
  ps.seed = rng();
  object_.photo = testing::photographReference(tex, object_.width_m, object_.height_m, ps);
  const std::string name = spec_.texture.substr(spec_.texture.find('/') + 1);
  object_.model = detector::makeObjectModel(name, object_.photo.image, object_.photo.camera, object_.photo.cMo,
                                            object_.photo.polygon_px);
  // The card's picture: a crop of 40-80 % of the occluder photograph (its own texture).
  const cv::Mat pic = testing::loadMedia(spec_.occluder);
  const double f = uni(rng, 0.4, 0.8);
  const int cw = std::max(8, static_cast<int>(f * pic.cols)), ch = std::max(8, static_cast<int>(f * pic.rows));
  const cv::Rect crop(static_cast<int>(uni(rng, 0, pic.cols - cw)), static_cast<int>(uni(rng, 0, pic.rows - ch)), cw, ch);
  card_ = pic(crop).clone();
  if (uni(rng, 0, 1) < 0.5) cv::rotate(card_, card_, cv::ROTATE_90_CLOCKWISE);
  wall_ = testing::photoClutterBackground(rng(), 1280, 960, {spec_.texture});
  card_depth_ = uni(rng, 0.15, 0.4);
  card_angle_ = uni(rng, -15, 15) * kDeg;
  entry_dir_ = uni(rng, 0, 2 * M_PI);
  sway_seed_ = rng();
}

OcclusionFrame OcclusionSequence::frame(int i) const {
  std::mt19937_64 prng(mix(sway_seed_, 0));
  SwayParams sp;
  sp.distance = uni(prng, 0.45, 0.6);
  sp.distance_amp = uni(prng, 0.03, 0.08);
  sp.tilt = uni(prng, 5, 25) * kDeg;
  sp.tilt_dir = uni(prng, 0, 2 * M_PI);
  sp.roll = uni(prng, 0.05, 0.2);
  sp.phase = uni(prng, 0, 2 * M_PI);
  const double look_strength = uni(prng, 0.2, 0.6);
  const uint64_t look_seed = prng();

  const double t = spec_.frames > 1 ? static_cast<double>(i) / (spec_.frames - 1) : 0;
  const Intrinsics cam = testing::sceneCamera();
  const Pose cMo = testing::viewPointPose(sway(sp, t)).inverse();
  const cv::Mat tex = testing::loadMedia(spec_.texture);
  const double w = object_.width_m, h = object_.height_m;

  // The card in the object frame: entering along e, rotated by card_angle_ (plus a hand's slow
  // wobble) in a plane parallel to the target, card_depth_ of the mean distance in front of it.
  const Eigen::Vector2d e(std::cos(entry_dir_), std::sin(entry_dir_)), n(-e.y(), e.x());
  const double along = std::abs(w * e.x()) + std::abs(h * e.y());   // target's extent along e
  const double across = std::abs(w * n.x()) + std::abs(h * n.y());  // and across it
  const double card_along = 0.8 * along, card_across = 1.15 * across;
  const double angle = entry_dir_ + card_angle_ + 3 * kDeg * std::sin(5 * t);
  const Eigen::Matrix3d R = axisAngle(Eigen::Vector3d::UnitZ(), angle) * axisAngle(Eigen::Vector3d::UnitX(), 4 * kDeg);
  const double depth = card_depth_ * sp.distance;
  const auto cardAt = [&](double s) {
    const Eigen::Vector2d c = s * e + 0.1 * across * std::sin(3 * t) * n;
    return cMo * Pose(R, Eigen::Vector3d(c.x(), c.y(), -depth));
  };
  const double goal = spec_.min_cover + (spec_.max_cover - spec_.min_cover) * 0.5 * (1 - std::cos(2 * M_PI * t));
  const std::vector<cv::Point2f> target_quad = projected(cam, cMo, w, h);
  // Coverage grows with s from the card outside (behind the far side of -e) until its trailing
  // edge enters: bisection for the goal between the two.
  double lo = -along, hi = 0.5 * along - 0.5 * card_along;
  for (int it = 0; it < 40; ++it) {
    const double mid = 0.5 * (lo + hi);
    (coverOf(target_quad, projected(cam, cardAt(mid), card_along, card_across)) < goal ? lo : hi) = mid;
  }
  const Pose cMcard = cardAt(hi);

  const sim::TexturedPlane target{tex, w, h, cMo};
  const sim::TexturedPlane card{card_, card_along, card_across, cMcard};
  const double wall_h = kWallWidth * wall_.rows / wall_.cols;
  const sim::TexturedPlane wall{wall_, kWallWidth, wall_h, cMo * Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, kWallBehind))};
  OcclusionFrame out;
  SetFrame& f = out.frame;
  f.camera = cam;
  f.image = sim::renderView(cam, {wall, target, card}, cv::Mat());
  // One camera look for the sequence; its noise new in every frame.
  std::mt19937_64 look_rng(look_seed);
  const testing::CameraLook look = testing::randomCameraLook(look_rng, look_strength, Eigen::Vector2d(320, 240));
  std::mt19937_64 noise_rng(mix(look_seed, 1 + static_cast<uint64_t>(i)));
  testing::applyCameraLook(f.image, look, noise_rng);
  f.object = 0;
  f.cMo = cMo;
  f.corners = sim::projectPlaneCorners(cam, target);
  f.distance_m = cMo.t.norm();
  f.tilt_rad = std::acos(std::min(1.0, std::abs(cMo.R.col(2).dot(cMo.t.normalized()))));
  f.size_px = std::sqrt(std::abs(signedArea(f.corners)));
  out.covered = coverOf(target_quad, projected(cam, cMcard, card_along, card_across));
  return out;
}

int occlusionBin(double covered) {
  const auto& e = occlusionBinEdges();
  for (size_t b = 0; b + 1 < e.size(); ++b)
    if (covered < e[b + 1]) return static_cast<int>(b);
  return static_cast<int>(e.size()) - 2;
}

std::string occlusionBinName(int bin) {
  static const char* names[] = {"10-20 %", "20-40 %", "40-60 %"};
  return bin >= 0 && bin < 3 ? names[bin] : "all";
}

std::vector<OcclusionRow> evaluateOcclusion(const OcclusionSequence& seq, int sequence_index,
                                            const OcclusionOptions& opt) {
  const detector::ObjectModel& model3 = seq.object().model;
  const detector::ObjectModel model2 = twoDOnly(model3);
  detector::Detector det3(opt.detector), det2(opt.detector);
  det3.addObject(model3);
  det2.addObject(model2);
  ClassicPipeline classic(model3);
  servo::PoseReplay track3(det3, {}, servo::planarTrackerFactory({}, &det3));
  servo::PoseReplay track2(det2, {}, servo::planarTrackerFactory({}, &det2));
  const SetObject& obj = seq.object();
  // The texture's corners in the object frame (the texture plane), TL TR BR BL.
  const double w = obj.width_m, h = obj.height_m;
  const std::array<Eigen::Vector3d, 4> corners_o = {Eigen::Vector3d(-w / 2, -h / 2, 0), Eigen::Vector3d(w / 2, -h / 2, 0),
                                                    Eigen::Vector3d(w / 2, h / 2, 0), Eigen::Vector3d(-w / 2, h / 2, 0)};
  std::vector<OcclusionRow> rows;
  for (int i = 0; i < seq.frames(); ++i) {
    const OcclusionFrame of = seq.frame(i);
    const SetFrame& f = of.frame;
    OcclusionRow r;
    r.sequence = sequence_index;
    r.frame = i;
    r.covered = of.covered;
    if (opt.detection) {
      const detector::DetectionResult res = det3.detect(f.image, f.camera);
      if (const auto d = res.find(0)) {
        r.refgrasp = scoreOutcome(obj, f, d->H, d->cMo);
        r.refgrasp.inliers = d->inliers;
        r.refgrasp.correlation = d->correlation;
      } else if (res.ok && !res.stats.empty()) {
        r.miss = detector::missReasonName(res.stats[0].miss);
      }
      const detector::DetectionResult res2 = det2.detect(f.image, f.camera);
      if (const auto d = res2.find(0)) {
        r.refgrasp_2d = scoreOutcome(obj, f, d->H, std::nullopt);
        r.refgrasp_2d.inliers = d->inliers;
        r.refgrasp_2d.correlation = d->correlation;
      }
      const detector::Features ff = detector::DetectorInternals::extract(det3, f.image, f.camera);
      const ClassicResult c = classic.detect(ClassicFeatures{ff.keypoints, ff.descriptors}, f.camera);
      if (c.found) {
        r.classic = scoreOutcome(obj, f, c.H, c.cMo);
        r.classic.inliers = c.inliers;
      }
    }
    if (opt.tracking) {
      robot::MonoFrame mf;
      mf.image = f.image;
      mf.stamp = i / 30.0;
      mf.index = i;
      const servo::ObjectFrame a = track3.process(i, mf, f.camera).objects[0];
      if (a.confirmed && a.cMo) {
        std::array<Eigen::Vector2d, 4> c;
        for (int k = 0; k < 4; ++k) c[k] = f.camera.project(*a.cMo * corners_o[k]);
        r.tracked_3d = scoreCorners(f, c);
      }
      const servo::ObjectFrame b = track2.process(i, mf, f.camera).objects[0];
      if (b.confirmed && b.mode != servo::TrackMode::kLost) {
        const Eigen::Matrix3d H = b.mode == servo::TrackMode::kTrack && b.H ? *b.H : b.detection.H;
        r.tracked_2d = scoreOutcome(obj, f, H, std::nullopt);
      }
    }
    rows.push_back(r);
  }
  return rows;
}

OcclusionCount countOcclusion(const std::vector<OcclusionRow>& rows, MethodOutcome OcclusionRow::*what, int bin) {
  OcclusionCount c;
  for (const auto& r : rows) {
    if (bin >= 0 && occlusionBin(r.covered) != bin) continue;
    const MethodOutcome& m = r.*what;
    ++c.frames;
    c.reported += m.reported;
    c.found += m.found;
    c.wrong += m.reported && !m.found;
  }
  return c;
}

std::string formatOcclusionTable(const std::vector<OcclusionRow>& rows, const OcclusionOptions& opt) {
  std::ostringstream o;
  char buf[512];
  if (opt.detection) o << "Single-frame detection, reported / found (corners within max(5 px, 10 % of the diagonal)) / wrong:\n\n"
       "| cover | frames | refgrasp | refgrasp 2D-only | classic |\n|---|---|---|---|---|\n";
  const auto cell = [](const OcclusionCount& c) {
    return std::to_string(c.reported) + " / " + std::to_string(c.found) + " / **" + std::to_string(c.wrong) + "**";
  };
  for (int b = 0; opt.detection && b <= 3; ++b) {
    const int bin = b < 3 ? b : -1;
    const OcclusionCount r = countOcclusion(rows, &OcclusionRow::refgrasp, bin);
    if (r.frames == 0) continue;
    std::snprintf(buf, sizeof buf, "| %s | %d | %s | %s | %s |\n", occlusionBinName(bin).c_str(), r.frames,
                  cell(r).c_str(), cell(countOcclusion(rows, &OcclusionRow::refgrasp_2d, bin)).c_str(),
                  cell(countOcclusion(rows, &OcclusionRow::classic, bin)).c_str());
    o << buf;
  }
  if (!opt.tracking) return o.str();
  o << "\nTracking pipeline (servo::PoseReplay), tracked (confirmed report) / lost / wrong:\n\n"
       "| cover | frames | 3D (pose tracker) | 2D-only (homography tracker) |\n|---|---|---|---|\n";
  const auto tcell = [](const OcclusionCount& c) {
    return std::to_string(c.reported) + " / " + std::to_string(c.frames - c.reported) + " / **" +
           std::to_string(c.wrong) + "**";
  };
  for (int b = 0; b <= 3; ++b) {
    const int bin = b < 3 ? b : -1;
    const OcclusionCount t3 = countOcclusion(rows, &OcclusionRow::tracked_3d, bin);
    if (t3.frames == 0) continue;
    std::snprintf(buf, sizeof buf, "| %s | %d | %s | %s |\n", occlusionBinName(bin).c_str(), t3.frames,
                  tcell(t3).c_str(), tcell(countOcclusion(rows, &OcclusionRow::tracked_2d, bin)).c_str());
    o << buf;
  }
  return o.str();
}

}  // namespace refgrasp::eval
