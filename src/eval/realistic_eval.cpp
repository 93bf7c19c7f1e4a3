#include "eval/realistic_eval.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <map>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>

#include "core/geometry.h"
#include "detector/detector_internal.h"
#include "detector/homography.h"
#include "eval/classic.h"
#include "eval/eval_util.h"
#include "robot/sim/synthetic_scene.h"

namespace refgrasp::eval {

namespace {

constexpr double kDeg = M_PI / 180;

using detail::median;
using detail::mix;
using detail::timed;
using detail::uni;

int binOf(const std::vector<double>& edges, double x) {
  for (size_t i = 0; i + 1 < edges.size(); ++i)
    if (x < edges[i + 1]) return static_cast<int>(i);
  return static_cast<int>(edges.size()) - 2;
}

}  // namespace

std::vector<RealisticSetSpec> realisticSets(uint64_t seed, int frames) {
  std::vector<RealisticSetSpec> sets(3);
  sets[0].name = "photos";
  sets[0].textures = testing::photoTextures();
  sets[1].name = "procedural";
  sets[1].textures = testing::targetTextures();
  RealisticSetSpec& far = sets[2];
  far.name = "far_oblique";
  far.textures = testing::photoTextures();
  for (const auto& t : testing::targetTextures()) far.textures.push_back(t);
  far.width_m = 0.16;
  far.references_per_texture = 1;
  far.ref_min_tilt_rad = 40 * kDeg;
  far.ref_max_tilt_rad = 60 * kDeg;
  far.ref_min_width_px = 80;
  far.ref_max_width_px = 130;
  far.distance_edges_m = {0.5, 0.9, 1.3, 1.7, 2.1, 2.5};
  far.tilt_edges_rad = {40 * kDeg, 50 * kDeg, 60 * kDeg};
  for (size_t k = 0; k < sets.size(); ++k) {
    sets[k].frames = frames;
    sets[k].seed = mix(seed, k);
  }
  return sets;
}

RealisticSet::RealisticSet(RealisticSetSpec spec) : spec_(std::move(spec)) {
  std::mt19937_64 rng(mix(spec_.seed, 0xABCD));
  for (const auto& t : spec_.textures) {
    const cv::Mat tex = testing::loadMedia(t);
    for (int r = 0; r < spec_.references_per_texture; ++r) {
      SetObject o;
      o.texture = t;
      o.width_m = spec_.width_m;
      o.height_m = spec_.width_m * tex.rows / tex.cols;
      testing::ReferencePhotoSpec ps;
      // The first reference of a texture is the mildest tilt of the range, the others anywhere.
      ps.tilt_rad = r == 0 ? uni(rng, spec_.ref_min_tilt_rad, 0.5 * (spec_.ref_min_tilt_rad + spec_.ref_max_tilt_rad))
                           : uni(rng, spec_.ref_min_tilt_rad, spec_.ref_max_tilt_rad);
      ps.width_px = uni(rng, spec_.ref_min_width_px, spec_.ref_max_width_px);
      ps.look_strength = uni(rng, 0.2, 0.8);
      ps.seed = rng();
      o.photo = testing::photographReference(tex, o.width_m, o.height_m, ps);
      const std::string name = t.substr(t.find('/') + 1) + "#" + std::to_string(r);
      o.model = detector::makeObjectModel(name, o.photo.image, o.photo.camera, o.photo.cMo, o.photo.polygon_px);
      objects_.push_back(std::move(o));
    }
  }
}

SetFrame RealisticSet::frame(int i) const {
  std::mt19937_64 rng(mix(spec_.seed, 1000003ull + static_cast<uint64_t>(i)));
  const int D = static_cast<int>(spec_.distance_edges_m.size()) - 1;
  const int T = static_cast<int>(spec_.tilt_edges_rad.size()) - 1;
  const int n = static_cast<int>(objects_.size());
  SetFrame f;
  f.camera = testing::sceneCamera();
  f.distance_bin = i % D;
  f.tilt_bin = (i / D) % T;
  f.object = (i * 7 + i / (D * T)) % n;
  const SetObject& o = objects_[f.object];
  const cv::Mat tex = testing::loadMedia(o.texture);
  testing::RealisticSceneSpec s;
  s.cMo = testing::randomVisiblePoseIn(rng, f.camera, o.width_m, o.height_m, spec_.distance_edges_m[f.distance_bin],
                                       spec_.distance_edges_m[f.distance_bin + 1], spec_.tilt_edges_rad[f.tilt_bin],
                                       spec_.tilt_edges_rad[f.tilt_bin + 1]);
  const Eigen::Vector2d centre = f.camera.project(s.cMo.t);
  s.look = testing::randomCameraLook(rng, uni(rng, spec_.min_look, spec_.max_look), centre);
  if (uni(rng, 0, 1) < spec_.occlusion_probability) s.occlusion = uni(rng, 0.1, spec_.max_occlusion);
  s.seed = rng();
  s.exclude_from_background = {o.texture};
  const testing::RealisticScene sc = testing::renderRealisticScene(f.camera, tex, o.width_m, o.height_m, s);
  f.image = sc.image;
  f.cMo = sc.cMo;
  f.corners = sc.corners;
  f.distance_m = s.cMo.t.norm();
  f.tilt_rad = std::acos(std::min(1.0, std::abs(s.cMo.R.col(2).dot(s.cMo.t.normalized()))));
  f.size_px = std::sqrt(std::abs(signedArea(f.corners)));
  return f;
}

namespace {

// The object without its reference pose (2D-only): the same image, camera and pattern region.
}  // namespace

detector::ObjectModel twoDOnly(const detector::ObjectModel& m) {
  detector::ObjectModel out = detector::makeObjectModel(m.name, m.reference, m.camera, std::nullopt,
                                                        m.pattern_polygon_px, m.plane_normal_o, m.plane_offset_m, m.source);
  out.pattern_region_exact = m.pattern_region_exact;
  return out;
}

bool poseWithinTolerance(const Pose& cMo, const Pose& truth) {
  return rotationError(cMo, truth) < 2.0 * kDeg && translationError(cMo, truth) < 0.02 * truth.t.norm();
}

MethodOutcome scoreOutcome(const SetObject& obj, const SetFrame& f, const Eigen::Matrix3d& H,
                           const std::optional<Pose>& cMo) {
  std::array<Eigen::Vector2d, 4> corners;
  for (int k = 0; k < 4; ++k) corners[k] = detector::applyHomography(H, obj.photo.corners_px[k]);
  MethodOutcome m = scoreCorners(f, corners);
  if (cMo) {
    m.has_pose = true;
    m.rot_deg = rotationError(*cMo, f.cMo) / kDeg;
    m.rel_t = translationError(*cMo, f.cMo) / f.cMo.t.norm();
    m.pose_ok = m.found && poseWithinTolerance(*cMo, f.cMo);
  }
  return m;
}

MethodOutcome scoreCorners(const SetFrame& f, const std::array<Eigen::Vector2d, 4>& corners) {
  MethodOutcome m;
  m.reported = true;
  double err = 0;
  for (int k = 0; k < 4; ++k) err = std::max(err, (corners[k] - f.corners[k]).norm());
  if (!std::isfinite(err)) err = 1e9;
  m.corner_px = err;
  const double diag = 0.5 * ((f.corners[2] - f.corners[0]).norm() + (f.corners[3] - f.corners[1]).norm());
  m.found = err <= std::max(5.0, 0.1 * diag);
  return m;
}

std::vector<FrameOutcome> evaluateSet(const RealisticSet& set, const EvalOptions& opt, int first, int last,
                                      const std::function<void(int)>& progress) {
  const auto& objects = set.objects();
  std::vector<std::unique_ptr<detector::Detector>> dets(objects.size());
  std::vector<std::unique_ptr<ClassicPipeline>> classics(objects.size());
  std::vector<FrameOutcome> out;
  const int D = static_cast<int>(set.spec().distance_edges_m.size()) - 1;
  for (int i = first; i < last; ++i) {
    if (i % D < opt.min_distance_bin) continue;
    const SetFrame f = set.frame(i);
    const SetObject& o = objects[f.object];
    if (!dets[f.object]) {
      dets[f.object] = std::make_unique<detector::Detector>(opt.detector);
      const detector::ObjectModel model = opt.two_d ? twoDOnly(o.model) : o.model;
      dets[f.object]->addObject(model);
      classics[f.object] = std::make_unique<ClassicPipeline>(model);
    }
    FrameOutcome r;
    r.frame = i;
    r.object = f.object;
    r.distance_bin = f.distance_bin;
    r.tilt_bin = f.tilt_bin;
    r.distance_m = f.distance_m;
    r.tilt_rad = f.tilt_rad;
    r.size_px = f.size_px;
    detector::DetectionResult res;
    const double t_r = timed(opt.cpu_time, [&] { res = dets[f.object]->detect(f.image, f.camera); });
    if (const auto d = res.find(0)) {
      r.refgrasp = scoreOutcome(o, f, d->H, d->cMo);
      r.refgrasp.inliers = d->inliers;
      r.refgrasp.log10_nfa = d->log10_nfa;
      r.refgrasp.correlation = d->correlation;
    } else if (res.ok && !res.stats.empty()) {
      r.miss = detector::missReasonName(res.stats[0].miss);
    } else {
      r.miss = res.error;
    }
    r.refgrasp.ms = t_r;
    if (opt.time_sift)
      r.sift_ms = timed(opt.cpu_time, [&] { detector::DetectorInternals::extract(*dets[f.object], f.image, f.camera); });
    ClassicResult c;
    double t_c = 0;
    if (opt.classic_own_sift) {
      t_c = timed(opt.cpu_time, [&] { c = classics[f.object]->detect(f.image, f.camera); });
    } else {
      const detector::Features ff = detector::DetectorInternals::extract(*dets[f.object], f.image, f.camera);
      ClassicFeatures cf{ff.keypoints, ff.descriptors};
      t_c = timed(opt.cpu_time, [&] { c = classics[f.object]->detect(cf, f.camera); });
    }
    if (c.found) {
      r.classic = scoreOutcome(o, f, c.H, c.cMo);
      r.classic.inliers = c.inliers;
    }
    r.classic.ms = t_c;
    out.push_back(r);
    if (progress) progress(i);
  }
  return out;
}

Tally tally(const std::vector<FrameOutcome>& rows) {
  Tally t;
  std::vector<double> rr, rc, tr, tc, br, bc;
  for (const auto& r : rows) {
    ++t.n;
    t.found_r += r.refgrasp.found;
    t.found_c += r.classic.found;
    t.pose_r += r.refgrasp.pose_ok;
    t.pose_c += r.classic.pose_ok;
    t.wrong_r += r.refgrasp.reported && !r.refgrasp.found;
    t.wrong_c += r.classic.reported && !r.classic.found;
    if (r.refgrasp.found && r.refgrasp.has_pose) {
      rr.push_back(r.refgrasp.rot_deg);
      tr.push_back(100 * r.refgrasp.rel_t);
    }
    if (r.classic.found && r.classic.has_pose) {
      rc.push_back(r.classic.rot_deg);
      tc.push_back(100 * r.classic.rel_t);
    }
    if (r.refgrasp.found && r.classic.found && r.refgrasp.has_pose && r.classic.has_pose) {
      br.push_back(r.refgrasp.rot_deg);
      bc.push_back(r.classic.rot_deg);
    }
  }
  t.rot_med_r = median(rr);
  t.rot_med_c = median(rc);
  t.t_med_r = median(tr);
  t.t_med_c = median(tc);
  t.rot_both_r = median(br);
  t.rot_both_c = median(bc);
  return t;
}

namespace {

std::string row(const std::string& label, const Tally& t) {
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "| %s | %d | **%d** / %d | **%d** / %d | %d / %d | **%.2f** / %.2f | **%.2f** / %.2f | %.2f / %.2f |\n",
                label.c_str(), t.n, t.found_r, t.found_c, t.pose_r, t.pose_c, t.wrong_r, t.wrong_c, t.rot_med_r,
                t.rot_med_c, t.t_med_r, t.t_med_c, t.rot_both_r, t.rot_both_c);
  return buf;
}

const char* kHeader =
    "| found, pose ok, wrong, medians: refgrasp / classic | frames | found | pose ok (< 2 deg, < 2 %) | "
    "wrong (false positives) | rotation error median, deg | translation error median, % of distance | "
    "rotation median where both found |\n|---|---|---|---|---|---|---|---|\n";

std::string fmtRange(double a, double b, const char* unit, double scale) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%g-%g %s", std::round(a * scale * 100) / 100, std::round(b * scale * 100) / 100, unit);
  return buf;
}

const std::vector<double> kSizeEdges = {0, 40, 60, 80, 120, 200, 1e9};

std::vector<std::pair<std::string, std::vector<FrameOutcome>>> groups(const RealisticSetSpec& spec,
                                                                      const std::vector<FrameOutcome>& rows,
                                                                      int kind) {
  std::vector<std::pair<std::string, std::vector<FrameOutcome>>> g;
  if (kind == 0) {
    for (size_t b = 0; b + 1 < spec.distance_edges_m.size(); ++b)
      g.push_back({"distance " + fmtRange(spec.distance_edges_m[b], spec.distance_edges_m[b + 1], "m", 1), {}});
    for (const auto& r : rows) g[r.distance_bin].second.push_back(r);
  } else if (kind == 1) {
    for (size_t b = 0; b + 1 < spec.tilt_edges_rad.size(); ++b)
      g.push_back({"tilt " + fmtRange(spec.tilt_edges_rad[b], spec.tilt_edges_rad[b + 1], "deg", 1 / kDeg), {}});
    for (const auto& r : rows) g[r.tilt_bin].second.push_back(r);
  } else {
    for (size_t b = 0; b + 1 < kSizeEdges.size(); ++b)
      g.push_back({b + 2 == kSizeEdges.size() ? "size >= 200 px" : "size " + fmtRange(kSizeEdges[b], kSizeEdges[b + 1], "px", 1), {}});
    for (const auto& r : rows) g[binOf(kSizeEdges, r.size_px)].second.push_back(r);
  }
  return g;
}

}  // namespace

std::string formatTables(const RealisticSetSpec& spec, const std::vector<FrameOutcome>& rows) {
  std::ostringstream o;
  o << "Set " << spec.name << " (" << rows.size() << " frames, seed " << spec.seed << ")\n\n" << kHeader;
  for (int kind = 0; kind < 3; ++kind)
    for (const auto& [label, rs] : groups(spec, rows, kind))
      if (!rs.empty()) o << row(label, tally(rs));
  o << row("all", tally(rows));
  std::vector<double> tr, tc, ratio, sift, rs;
  for (const auto& r : rows) {
    tr.push_back(r.refgrasp.ms);
    tc.push_back(r.classic.ms);
    if (r.classic.ms > 0) ratio.push_back(r.refgrasp.ms / r.classic.ms);
    if (r.sift_ms > 0) {
      sift.push_back(r.sift_ms);
      rs.push_back(r.refgrasp.ms / r.sift_ms);
    }
  }
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "\nTime per frame (median): refgrasp %.1f ms, classic %.1f ms, refgrasp / classic %.3f "
                "(median of per-frame ratios)",
                median(tr), median(tc), median(ratio));
  o << buf;
  if (!sift.empty()) {
    std::snprintf(buf, sizeof buf, "; SIFT extraction alone %.1f ms, refgrasp / SIFT %.3f", median(sift), median(rs));
    o << buf;
  }
  o << "\n";
  // The corners (the only figure of 2D-only objects, EvalOptions::two_d).
  std::vector<double> cr, cc;
  int within_r = 0, within_c = 0;
  for (const auto& r : rows) {
    within_r += r.refgrasp.found && r.refgrasp.corner_px <= 3;
    within_c += r.classic.found && r.classic.corner_px <= 3;
    if (r.refgrasp.found && r.classic.found) {
      cr.push_back(r.refgrasp.corner_px);
      cc.push_back(r.classic.corner_px);
    }
  }
  std::snprintf(buf, sizeof buf,
                "Corners: worst corner within 3 px refgrasp %d, classic %d; median worst-corner error over the %zu "
                "frames both found: refgrasp %.2f px, classic %.2f px\n",
                within_r, within_c, cr.size(), median(cr), median(cc));
  o << buf;
  return o.str();
}

std::vector<std::string> binsWhereRefgraspLoses(const RealisticSetSpec& spec, const std::vector<FrameOutcome>& rows) {
  std::vector<std::string> out;
  for (int kind = 0; kind < 2; ++kind)
    for (const auto& [label, rs] : groups(spec, rows, kind)) {
      const Tally t = tally(rs);
      if (t.found_r < t.found_c)
        out.push_back(spec.name + " " + label + ": found " + std::to_string(t.found_r) + " < " + std::to_string(t.found_c));
      if (t.pose_r < t.pose_c)
        out.push_back(spec.name + " " + label + ": pose ok " + std::to_string(t.pose_r) + " < " + std::to_string(t.pose_c));
    }
  return out;
}

namespace {

// A pattern's sibling: another texture carrying one piece (6-15 % of the area) of the pattern,
// as two products of one brand share a logo or a word.
cv::Mat sibling(const cv::Mat& pattern, const cv::Mat& base, std::mt19937_64& rng) {
  cv::Mat out;
  cv::resize(base, out, pattern.size(), 0, 0, cv::INTER_AREA);
  const double frac = uni(rng, 0.06, 0.15), aspect = uni(rng, 0.6, 1.6);
  const int w = std::min(pattern.cols - 2, static_cast<int>(std::sqrt(frac * pattern.total() * aspect)));
  const int h = std::min(pattern.rows - 2, static_cast<int>(frac * pattern.total() / std::max(1, w)));
  const cv::Rect src(static_cast<int>(uni(rng, 0, pattern.cols - w)), static_cast<int>(uni(rng, 0, pattern.rows - h)), w, h);
  const cv::Rect dst(static_cast<int>(uni(rng, 0, pattern.cols - w)), static_cast<int>(uni(rng, 0, pattern.rows - h)), w, h);
  pattern(src).copyTo(out(dst));
  return out;
}

}  // namespace

ClutterFrame clutterFrame(const std::vector<SetObject>& objects, uint64_t seed, int i) {
  std::vector<std::string> registered;
  for (const auto& o : objects) registered.push_back(o.texture);
  // Bases for siblings: media textures that are no registered pattern.
  std::vector<std::string> bases = {"hard/low_texture.png", "boxes/box_side_a.png", "boxes/box_side_b.png",
                                    "boxes/box_top.png", "backgrounds/wall.png", "clutter/clutter_05.png"};
  for (const auto& p : testing::photoTextures())
    if (std::find(registered.begin(), registered.end(), p) == registered.end()) bases.push_back(p);
  for (const auto& p : testing::targetTextures())
    if (std::find(registered.begin(), registered.end(), p) == registered.end()) bases.push_back(p);
  ClutterFrame out;
  out.camera = testing::sceneCamera();
  std::mt19937_64 rng(mix(seed, static_cast<uint64_t>(i)));
  std::vector<sim::TexturedPlane> planes;
  const int n = std::uniform_int_distribution<int>(1, 3)(rng);
  for (int k = 0; k < n; ++k) {
    const SetObject& o = objects[std::uniform_int_distribution<size_t>(0, objects.size() - 1)(rng)];
    const cv::Mat base = testing::loadMedia(bases[std::uniform_int_distribution<size_t>(0, bases.size() - 1)(rng)]);
    sim::TexturedPlane p;
    p.texture = sibling(testing::loadMedia(o.texture), base, rng);
    p.width_m = o.width_m;
    p.height_m = o.height_m;
    p.cMp = testing::randomVisiblePose(rng, out.camera, p.width_m, p.height_m, 0.35, 1.6, 55 * kDeg);
    planes.push_back(p);
  }
  testing::RealisticSceneSpec s;
  s.look = testing::randomCameraLook(rng, uni(rng, 0.3, 1.0), Eigen::Vector2d(uni(rng, 0, 640), uni(rng, 0, 480)));
  s.seed = rng();
  s.exclude_from_background = registered;
  out.image = testing::renderRealisticScene(out.camera, cv::Mat(), 0, 0, s, planes).image;
  return out;
}

ClutterReport evaluateClutter(const std::vector<SetObject>& objects, const detector::DetectorOptions& opt,
                              int frames, uint64_t seed, bool run_classic) {
  ClutterReport rep;
  rep.frames = frames;
  detector::Detector det(opt);
  std::vector<std::unique_ptr<ClassicPipeline>> classics;
  for (const auto& o : objects) {
    det.addObject(o.model);
    if (run_classic) classics.push_back(std::make_unique<ClassicPipeline>(o.model));
  }
  for (int i = 0; i < frames; ++i) {
    const ClutterFrame sc = clutterFrame(objects, seed, i);
    const detector::DetectionResult r = det.detect(sc.image, sc.camera);
    for (const auto& d : r.detections)
      if (d.found) {
        ++rep.detections;
        rep.details.push_back("frame " + std::to_string(i) + ": " + objects[d.object].model.name + " with " +
                              std::to_string(d.inliers) + " inliers");
      }
    if (run_classic) {
      const ClassicFeatures cf = classicSift(sc.image);
      for (const auto& c : classics) rep.classic_detections += c->detect(cf, sc.camera).found;
    }
  }
  return rep;
}

}  // namespace refgrasp::eval
