#include "detector/detector.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <new>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "detector/checks.h"
#include "detector/cylinder_detection.h"
#include "detector/detector_internal.h"
#include "detector/homography.h"
#include "detector/multiview.h"
#include "detector/registered_object.h"
#include "detector/search_region.h"

namespace refgrasp::detector {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
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
    if (p.H && (!p.H->allFinite() || std::abs(p.H->determinant()) < 1e-12))
      return field + "H: must be finite and invertible";
    if (!(std::isfinite(p.max_scale) && p.max_scale >= 0)) return field + "max_scale: must be >= 0";
    if (p.roi.width < 0 || p.roi.height < 0) return field + "roi: negative size";
    if (!(std::isfinite(p.roi_margin) && p.roi_margin >= 0)) return field + "roi_margin: must be >= 0";
    if (!(std::isfinite(p.scale_margin) && p.scale_margin >= 1))
      return field + "scale_margin: must be >= 1";
  }
  return "";
}

// A validated frame (8-bit gray, BGR or BGRA) as gray; gray frames are not copied.
cv::Mat toGray(const cv::Mat& image) {
  cv::Mat gray = image;
  if (image.channels() == 3) cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  if (image.channels() == 4) cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  return gray;
}

// what() of an exception on one line (OpenCV's end with a newline).
std::string oneLine(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  while (!s.empty() && s.back() == ' ') s.pop_back();
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

// SIFT on a validated gray frame (or a region of it), keypoints undistorted; the frame is kept
// in Features::image for the dense alignment and the verification.
Features extractFeatures(const cv::Mat& gray, const Intrinsics& camera, const SiftOptions& sift,
                         const ExtractRegion& region) {
  Features f = extractSiftUnchecked(gray, sift, region);
  undistortKeypoints(&f.keypoints, camera);
  if (gray.type() == CV_8UC1) f.image = gray;
  return f;
}

// The features of one region of a frame, shared by every object searching that region.
struct Extraction {
  Search search;
  Features features;
  GridIndex grid;
};

// The extraction serving `s` (made when no earlier one asks for the same features): its index
// in *extractions, -1 when nothing is searched.
int extractionFor(const Search& s, const cv::Mat& gray, const Intrinsics& camera, const SiftOptions& sift,
                  std::vector<Extraction>* extractions) {
  if (!s.searched || s.roi.area() <= 0) return -1;
  for (size_t k = 0; k < extractions->size(); ++k)
    if ((*extractions)[k].search.sameExtraction(s)) return static_cast<int>(k);
  Features f = extractFeatures(gray, camera, sift, s.region);
  GridIndex grid(f.keypoints, f.image_size);
  extractions->push_back({s, std::move(f), std::move(grid)});
  return static_cast<int>(extractions->size()) - 1;
}

// One object's verdicts in a frame: its found instances, in order, and why the others failed.
struct ObjectTally {
  int found = 0, pose_failures = 0, sanity_failures = 0, verify_failures = 0;
  SanityStatus rejected = SanityStatus::kOk;  ///< reported on the not-found entry

  void add(Verdict v, ObjectStats* st, DetectionResult* res) {
    switch (v.outcome) {
      case CheckOutcome::kOk:
        v.detection.found = true;
        v.detection.instance = found++;
        res->detections.push_back(v.detection);
        break;
      case CheckOutcome::kPoseFailed:
        rejected = SanityStatus::kNotFinite;
        ++pose_failures;
        break;
      case CheckOutcome::kPoseDisagrees:
        if (found == 0) rejected = SanityStatus::kPoseDisagrees;
        if (sanity_failures++ == 0) st->sanity = SanityStatus::kPoseDisagrees;
        break;
      case CheckOutcome::kSanity:
        if (found == 0) rejected = v.detection.sanity;
        if (sanity_failures++ == 0) st->sanity = v.detection.sanity;
        break;
      case CheckOutcome::kNotVerified:
        ++verify_failures;
        break;
    }
  }

  // Why nothing was accepted: the furthest stage a candidate reached.
  MissReason miss(bool searched, const MatchResult& m, int scene_features, int reference_features) const {
    if (!searched) return MissReason::kNotSearched;
    if (verify_failures > 0) return MissReason::kNotVerified;
    if (sanity_failures > 0) return MissReason::kSanity;
    if (pose_failures > 0) return MissReason::kPoseFailed;
    return matcherMiss(m, scene_features, reference_features);
  }
};

void addRejects(const MatchRejects& a, MatchRejects* sum) {
  sum->too_few_local_matches += a.too_few_local_matches;
  sum->too_few_inliers += a.too_few_inliers;
  sum->not_significant += a.not_significant;
  sum->implausible_homography += a.implausible_homography;
  sum->narrow_inlier_spread += a.narrow_inlier_spread;
}

// The spare candidate (verify.spare_candidate): the matcher's search ends once it has
// max_instances candidates, and when every one of them failed the checks (on a facade, a
// consensus one window off that the pose check refuses) it is asked for one more, checked the
// same way. Returns the time spent matching (ms).
double checkSpareCandidate(const CandidateContext& ctx, const MatchResult& m, ObjectStats* st, ObjectTally* tally,
                           DetectionResult* res) {
  const auto t = Clock::now();
  MatchOptions more = ctx.opt.match;
  ++more.max_instances;
  const MatchResult spare = matchObjectUnchecked(ctx.object.index, ctx.scene, *ctx.grid, more);
  const double ms = msSince(t);
  for (const MatchCandidate& c : spare.instances) {
    const bool tried = std::any_of(m.instances.begin(), m.instances.end(),
                                   [&](const MatchCandidate& o) { return o.H == c.H; });
    if (!tried) tally->add(verifyCandidate(ctx, c), st, res);
  }
  return ms;
}

// Smallest side of a weak region's extraction (px): a far pattern's box is a few px wide.
constexpr double kMinWeakRegionPx = 48;

// Weak evidence looked at again (MatchOptions::weak_regions): the boxes of the strongest weak
// hypotheses of both passes (m.weak), each extracted again at the lower contrast threshold,
// matched with the object's own and view-synthesised features, and checked like the frame's.
// Adds to the stats and the tally; returns the time spent (ms, extraction included).
double lookAgainAtWeakRegions(const CandidateContext& ctx, MatchResult& m, const Search& search, ObjectStats* st,
                              ObjectTally* tally, DetectionResult* res) {
  const auto t = Clock::now();
  const DetectorOptions& opt = ctx.opt;
  std::stable_sort(m.weak.begin(), m.weak.end(),
                   [](const WeakRegion& a, const WeakRegion& b) { return a.local_matches > b.local_matches; });
  SiftOptions sift = opt.sift;
  sift.contrast_threshold = opt.match.weak_contrast_threshold;
  const cv::Mat& gray = ctx.scene.image;
  const cv::Rect frame = search.roi.area() > 0 ? search.roi : cv::Rect(0, 0, gray.cols, gray.rows);
  // The views' index holds the own features too: one match over both.
  const RegisteredObject* obj = ctx.object.with_views ? ctx.object.with_views.get() : &ctx.object;
  std::vector<cv::Rect> looked;
  for (const WeakRegion& w : m.weak) {
    if (static_cast<int>(looked.size()) >= opt.match.weak_regions) break;
    // The box is in undistorted px (the keypoints'); the extraction reads the real image.
    const Eigen::Vector2d cd =
        distortPixel(ctx.camera, Eigen::Vector2d(w.box.x + w.box.width / 2, w.box.y + w.box.height / 2));
    if (!cd.allFinite()) continue;
    const cv::Point c(static_cast<int>(std::lround(cd.x())), static_cast<int>(std::lround(cd.y())));
    if (std::any_of(looked.begin(), looked.end(), [&](const cv::Rect& r) { return r.contains(c); })) continue;
    // At least kMinWeakRegionPx on a side: a box of a few px has no keypoints of its own.
    const double side = std::max(w.box.width, kMinWeakRegionPx);
    const cv::Rect box = cv::Rect(static_cast<int>(std::floor(c.x - side / 2)), static_cast<int>(std::floor(c.y - side / 2)),
                                  static_cast<int>(std::ceil(side)), static_cast<int>(std::ceil(side))) & frame;
    if (box.area() <= 0) continue;
    looked.push_back(box);
    ExtractRegion region = search.region;
    region.roi = box;
    region.inner_margin_px = 0;
    region.downsample = 1;
    // Keypoints up to half the box (3/4 of the pattern's predicted diagonal): larger ones are not
    // the pattern's, and their context would make the crop most of the frame.
    region.max_size_px = std::min(region.max_size_px, 0.5 * side);
    region.min_size_px = std::min(region.min_size_px, region.max_size_px);
    const Features f = extractFeatures(gray, ctx.camera, sift, region);
    const GridIndex grid(f.keypoints, f.image_size);
    ++st->weak_regions;
    const MatchResult mw = matchRegistered(*obj, f, grid, opt.match);
    st->hypotheses_evaluated += mw.hypotheses_evaluated;
    st->candidates += static_cast<int>(mw.instances.size());
    addRejects(mw.rejected, &st->rejected);
    const CandidateContext wctx{*obj, ctx.id, opt, f, &grid, ctx.camera, true};
    for (const MatchCandidate& matched : mw.instances) tally->add(verifyCandidate(wctx, matched), st, res);
    if (tally->found > 0) break;
  }
  m.rejected = st->rejected;
  return msSince(t);
}

// Matching and the verification stage for one object; appends its detections (or its not-found
// entry) and stats to *res and adds the time spent to res->time_ms.
void detectObject(const RegisteredObject& obj, int id, const DetectorOptions& opt, const Search& search,
                  const Extraction* extraction, const Intrinsics& camera, DetectionResult* res) {
  const Features no_features;
  const Features& scene = extraction ? extraction->features : no_features;
  ObjectStats st;
  st.object = id;
  st.roi = search.roi;
  st.min_keypoint_px = search.region.min_size_px;
  st.max_keypoint_px = search.region.max_size_px;
  st.downsample = search.region.downsample;
  st.scene_features = scene.size();

  auto t = Clock::now();
  MatchResult m;
  if (extraction) m = matchRegistered(obj, scene, extraction->grid, opt.match);
  res->time_ms.match += msSince(t);
  st.global_matches = m.global_matches;
  st.hypotheses_evaluated = m.hypotheses_evaluated;
  st.candidates = static_cast<int>(m.instances.size());
  st.rejected = m.rejected;

  t = Clock::now();
  // A region extracted at 1/downsample of the resolution: the dense alignment, which gives the
  // result its precision, may use a template downsample^2 larger (what the extraction saved), so
  // that it is no coarser against the pattern in the scene than without the downsampling.
  std::optional<DetectorOptions> finer;
  if (search.region.downsample > 1) {
    finer = opt;
    const double d2 = search.region.downsample * search.region.downsample;
    finer->dense.max_template_px = static_cast<int>(std::min(1e9, opt.dense.max_template_px * d2));
  }
  const CandidateContext ctx{obj, id, finer ? *finer : opt, scene, extraction ? &extraction->grid : nullptr, camera};
  ObjectTally tally;
  for (const MatchCandidate& matched : m.instances) tally.add(verifyCandidate(ctx, matched), &st, res);
  double spare_ms = 0;  // the spare candidate's matching: match time, not pose time
  if (tally.found == 0 && extraction && opt.verify.enabled && opt.verify.spare_candidate && !m.instances.empty() &&
      static_cast<int>(m.instances.size()) >= opt.match.max_instances) {
    spare_ms = checkSpareCandidate(ctx, m, &st, &tally, res);
    res->time_ms.match += spare_ms;
  }
  if (tally.found == 0 && extraction && obj.with_views) {
    // Nothing from the reference's own features: the object again with its view-synthesised
    // features (RegisteredObject::with_views), checked the same way.
    const auto tv = Clock::now();
    const MatchResult mv = matchRegistered(*obj.with_views, scene, extraction->grid, opt.match);
    double views_ms = msSince(tv);
    st.views_matched = true;
    st.global_matches = std::max(st.global_matches, mv.global_matches);
    st.hypotheses_evaluated += mv.hypotheses_evaluated;
    st.candidates += static_cast<int>(mv.instances.size());
    addRejects(mv.rejected, &st.rejected);
    m.global_matches = st.global_matches;
    m.rejected = st.rejected;
    m.weak.insert(m.weak.end(), mv.weak.begin(), mv.weak.end());
    const CandidateContext vctx{*obj.with_views, id, ctx.opt, scene, &extraction->grid, camera, true};
    for (const MatchCandidate& matched : mv.instances) tally.add(verifyCandidate(vctx, matched), &st, res);
    if (tally.found == 0 && opt.verify.enabled && opt.verify.spare_candidate && !mv.instances.empty() &&
        static_cast<int>(mv.instances.size()) >= opt.match.max_instances)
      views_ms += checkSpareCandidate(vctx, mv, &st, &tally, res);
    res->time_ms.match += views_ms;
    spare_ms += views_ms;
  }
  if (tally.found == 0 && extraction && opt.match.weak_regions > 0 && !extraction->features.image.empty()) {
    const double weak_ms = lookAgainAtWeakRegions(ctx, m, search, &st, &tally, res);
    res->time_ms.match += weak_ms;
    spare_ms += weak_ms;
  }
  if (tally.found == 0) {
    res->detections.emplace_back();
    res->detections.back().object = id;
    res->detections.back().sanity = tally.rejected;
    st.miss = tally.miss(search.searched, m, scene.size(), obj.index.features.size());
  }
  res->stats.push_back(st);
  res->time_ms.pose += msSince(t) - spare_ms;
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
  multiview.check();
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
  const std::string where = object.source.empty() ? object.name : object.source;
  auto checkReference = [](const ObjectModel& m, const std::string& at, const std::string& field) {
    if (m.reference.empty() || m.reference.type() != CV_8UC1)
      throw ConfigError(at, field, "expected a non-empty 8-bit grayscale image");
  };
  std::vector<RegisteredObject> views;
  if (object.isMultiView()) {
    for (size_t k = 0; k < object.views.size(); ++k) {
      const std::string field = "views[" + std::to_string(k) + "].definition";
      const ObjectModel* view = object.views[k].model.get();
      if (!view || view->isMultiView() || !(view->has3d() || view->isCylinder()))
        throw ConfigError(where, field, "a view needs metric geometry (planar with reference_pose, or cylinder)");
      checkReference(*view, where, field);
      views.push_back(registerObject(*view, opt_));
    }
    RegisteredObject model_only;  // its views are matched, never the object itself
    model_only.model = object;
    objects_.push_back(std::move(model_only));
  } else {
    checkReference(object, where, "reference_image");
    objects_.push_back(registerObject(object, opt_));
  }
  views_.push_back(std::move(views));
  return static_cast<int>(objects_.size()) - 1;
}

namespace {

// One object, or one view of a several-view object, as searched in a frame.
struct Searched {
  const RegisteredObject* obj;
  Search search;
  int extraction;  ///< index into the frame's extractions, -1: nothing extracted
};

// A several-view object: each view matched and checked as an object of its own (into a result
// of its own), its instances fused (multiview.h); appends the object's instances (or its
// not-found entry) and stats to *res and the time spent to res->time_ms. The stats are those of
// the view giving the best instance's H, or when none was found, of the view that got furthest
// (MissReason order).
void detectSeveralViews(const ObjectModel& model, int id, const DetectorOptions& opt,
                        const std::vector<Searched>& views, const std::vector<Extraction>& extractions,
                        const Intrinsics& camera, DetectionResult* res) {
  std::vector<ViewInstance> instances;
  std::vector<std::string> names;
  std::vector<DetectionResult> per_view(views.size());
  for (size_t k = 0; k < views.size(); ++k) {
    names.push_back(model.views[k].name);
    const Extraction* x = views[k].extraction >= 0 ? &extractions[static_cast<size_t>(views[k].extraction)] : nullptr;
    DetectionResult& r = per_view[k];
    detectObject(*views[k].obj, id, opt, views[k].search, x, camera, &r);
    res->time_ms.match += r.time_ms.match;
    res->time_ms.pose += r.time_ms.pose;
    const auto t = Clock::now();
    for (const Detection& d : r.detections) {
      if (!d.found || !d.cMo) continue;
      ViewInstance v{static_cast<int>(k), d, *d.cMo * model.views[k].oMv.inverse(), {}};
      v.pairs = viewCorrespondences(*views[k].obj, model.views[k].oMv, d, camera, opt);
      instances.push_back(std::move(v));
    }
    res->time_ms.pose += msSince(t);
  }
  const auto t = Clock::now();
  std::vector<Detection> fused = fuseViews(std::move(instances), names, camera.K(), opt.pose_options, opt.multiview);
  if (static_cast<int>(fused.size()) > opt.match.max_instances) fused.resize(static_cast<size_t>(opt.match.max_instances));
  res->time_ms.pose += msSince(t);

  size_t shown = 0;  // the view whose stats (and not-found entry) stand for the object's
  if (!fused.empty()) {
    shown = static_cast<size_t>(std::find(names.begin(), names.end(), fused[0].view) - names.begin());
  } else {
    for (size_t k = 1; k < views.size(); ++k)
      if (per_view[k].stats[0].miss > per_view[shown].stats[0].miss) shown = k;
    Detection missing;
    missing.object = id;
    missing.sanity = per_view[shown].detections[0].sanity;
    fused.push_back(missing);
  }
  res->detections.insert(res->detections.end(), fused.begin(), fused.end());
  res->stats.push_back(per_view[shown].stats[0]);
}

}  // namespace

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
      res = detectGray(toGray(image), camera, query);
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
  DetectionResult res;
  std::vector<const ObjectPrior*> prior_of(objectCount(), nullptr);
  for (const ObjectPrior& p : query.priors) prior_of[p.object] = &p;

  // What is searched: each object, or each view of a several-view object (its prior moved to
  // the view: cMv = cMo * oMv).
  std::vector<std::vector<Searched>> searched(objectCount());
  const auto t = Clock::now();
  std::vector<Extraction> extractions;
  auto add = [&](int id, const RegisteredObject& obj, const ObjectPrior* prior) {
    Search s = searchFor(obj, prior, query, camera);
    const int x = extractionFor(s, gray, camera, opt_.sift, &extractions);
    searched[id].push_back({&obj, std::move(s), x});
  };
  for (int id = 0; id < objectCount(); ++id) {
    const std::vector<ObjectView>& views = objects_[id].model.views;
    if (views.empty()) add(id, objects_[id], prior_of[id]);
    for (size_t k = 0; k < views.size(); ++k) {
      std::optional<ObjectPrior> view_prior;
      if (prior_of[id]) view_prior = *prior_of[id];
      if (view_prior && view_prior->cMo) view_prior->cMo = *view_prior->cMo * views[k].oMv;
      // Views are extracted at full resolution: the fused pose of the two-view box of the real
      // clip (ctest BoxVideo) lost precision with downsampled views (docs/results.md "Detection
      // with a prior region at 1280x720").
      if (view_prior) view_prior->max_scale = 0;
      add(id, views_[id][k], view_prior ? &*view_prior : nullptr);
    }
  }
  for (const Extraction& x : extractions) res.scene_features += x.features.size();
  res.time_ms.extract = msSince(t);

  for (int id = 0; id < objectCount(); ++id) {
    if (objects_[id].model.views.empty()) {
      const Searched& s = searched[id][0];
      detectObject(*s.obj, id, opt_, s.search, s.extraction >= 0 ? &extractions[s.extraction] : nullptr, camera, &res);
    } else {
      detectSeveralViews(objects_[id].model, id, opt_, searched[id], extractions, camera, &res);
    }
  }
  return res;
}

PoseAlignment Detector::alignPose(const cv::Mat& image, const Intrinsics& camera, int object,
                                 const Pose& cMo, const DenseRefineOptions* dense) const {
  PoseAlignment out;
  try {
    if (object < 0 || object >= objectCount() || !cMo.isFinite()) return out;
    const RegisteredObject& obj = objects_[static_cast<size_t>(object)];
    if (!obj.model.target || !obj.dense_usable || !validateImage(image, camera).empty()) return out;
    const cv::Mat gray = toGray(image);
    // The homography cMo predicts: undistorted reference px -> undistorted scene px.
    std::vector<Eigen::Vector2d> ref(4), und(4);
    for (int i = 0; i < 4; ++i) {
      const Eigen::Vector3d Xc = cMo * obj.model.target->corners_o[i];
      if (!(Xc.z() > 1e-6)) return out;
      ref[i] = obj.corners_und_px[i];
      und[i] = projectPinhole(camera.K(), Xc);
    }
    const Eigen::Matrix3d H = fitHomographyLeastSquares(ref, und);
    if (!H.allFinite()) return out;
    const DenseRefineResult dr = refineDense(obj, H, gray, camera, dense ? *dense : opt_.dense);
    out.correlation = dr.correlation;
    out.corner_shift_px = dr.corner_shift_px;
    out.used_fraction = 1 - dr.masked_fraction;
    if (!dr.ok) return out;
    const PoseResult p = poseFromDenseH(obj, opt_, dr.H, camera, &cMo);
    if (!p.ok || !p.cMo.isFinite()) return out;
    out.ok = true;
    out.cMo = p.cMo;
  } catch (...) {  // OpenCV, out of memory: not aligned
    out.ok = false;
  }
  return out;
}

HomographyAlignment Detector::alignHomography(const cv::Mat& image, const Intrinsics& camera, int object,
                                              const Eigen::Matrix3d& H, const DenseRefineOptions* dense) const {
  HomographyAlignment out;
  out.H = H;
  try {
    if (object < 0 || object >= objectCount() || !H.allFinite()) return out;
    const RegisteredObject& obj = objects_[static_cast<size_t>(object)];
    if (obj.model.isMultiView() || obj.cylinder_model || !obj.dense_usable || obj.pyramid.empty() ||
        !validateImage(image, camera).empty())
      return out;
    const DenseRefineResult dr = refineDense(obj, H, toGray(image), camera, dense ? *dense : opt_.dense);
    out.correlation = dr.correlation;
    out.corner_shift_px = dr.corner_shift_px;
    out.used_fraction = 1 - dr.masked_fraction;
    if (!dr.ok || !dr.H.allFinite()) return out;
    out.H = dr.H;
    for (int i = 0; i < 4; ++i) out.corners[i] = distortPixel(camera, applyHomography(dr.H, obj.corners_und_px[i]));
    out.ok = true;
  } catch (...) {  // OpenCV, out of memory: not aligned
    out.ok = false;
    out.H = H;
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
