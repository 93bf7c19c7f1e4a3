#include "eval/ablation.h"

#include <atomic>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "detector/object.h"
#include "eval/eval_util.h"
#include "eval/pairs_eval.h"
#include "eval/realistic_eval.h"

namespace refgrasp::eval {

using detail::median;
using detail::timed;

std::vector<AblationVariant> verificationAblation() {
  using O = detector::DetectorOptions;
  return {
      {"all checks", "(defaults)", [](O*) {}},
      {"no photometric verification", "verify.enabled: false", [](O* o) { o->verify.enabled = false; }},
      {"no correlation floor", "verify.min_correlation: -1", [](O* o) { o->verify.min_correlation = -1; }},
      {"no strong-cell rule", "verify.min_strong_cells: 0", [](O* o) { o->verify.min_strong_cells = 0; }},
      {"no periodic strong-cell rule", "verify.periodic_min_strong_cells: 3",
       [](O* o) { o->verify.periodic_min_strong_cells = o->verify.min_strong_cells; }},
      {"no re-alignment (and what comes with it)", "verify.realign: false", [](O* o) { o->verify.realign = false; }},
      {"no trusted wide alignment", "verify.realign_trusted_correlation: 1",
       [](O* o) { o->verify.realign_trusted_correlation = 1; }},
      {"no verified wide alignment", "verify.realign_verified_correlation: 1.01",
       [](O* o) { o->verify.realign_verified_correlation = 1.01; }},
      {"re-alignment of close-ups too", "verify.realign_min_in_view: 0",
       [](O* o) { o->verify.realign_min_in_view = 0; }},
      {"no period re-match", "verify.period_rematch: false", [](O* o) { o->verify.period_rematch = false; }},
      {"no period ambiguity test", "verify.period_ambiguity_cells: 10",
       [](O* o) { o->verify.period_ambiguity_cells = 10; }},
      {"no feature-pose RMS bound", "verify.max_feature_pose_rms_px: 1000",
       [](O* o) { o->verify.max_feature_pose_rms_px = 1000; }},
      {"no pose-gap check", "sanity.max_pose_gap_px: 1e9", [](O* o) { o->sanity.max_pose_gap_px = 1e9; }},
      {"no spare candidate", "verify.spare_candidate: false", [](O* o) { o->verify.spare_candidate = false; }},
      {"no sanity limits", "sanity: distance 0-1e9 m, area 0-1e9 x frame",
       [](O* o) {
         o->sanity.min_distance_m = 0;
         o->sanity.max_distance_m = 1e9;
         o->sanity.min_area_px2 = 0;
         o->sanity.max_area_fraction = 1e9;
       }},
      {"2D: dense alignment at any coarsening", "dense.max_2d_coarsening: 1e9",
       [](O* o) { o->dense.max_2d_coarsening = 1e9; }},
      {"no view-synthesised reference features", "match.plane_views: false",
       [](O* o) { o->match.plane_views = false; }},
      {"no weak regions looked at again", "match.weak_regions: 0", [](O* o) { o->match.weak_regions = 0; }},
      {"second pass placed by its features too (2D-only, periodic)", "verify.second_pass_needs_dense: false",
       [](O* o) { o->verify.second_pass_needs_dense = false; }},
  };
}

void AblationData::check() const {
  if (seeds.empty() && pair_seeds == 0 && clutter_frames == 0)
    throw std::invalid_argument("AblationData: no data (no seeds, pairs or clutter)");
  if (frames_per_set < 1) throw std::invalid_argument("AblationData.frames_per_set: must be >= 1");
  if (pair_seeds < 0) throw std::invalid_argument("AblationData.pair_seeds: must be >= 0");
  if (clutter_frames < 0) throw std::invalid_argument("AblationData.clutter_frames: must be >= 0");
  if (clutter_frames > 0 && seeds.empty())
    throw std::invalid_argument("AblationData.clutter_frames: needs a realistic seed (its objects)");
}

namespace {

// One variant on one frame or pair.
struct ItemOutcome {
  bool reported = false, found = false, pose_ok = false, within = false, wrong = false;
  int false_detections = 0;  // clutter
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  double ms = 0, checks_ms = 0;
};

enum class ItemKind { k3d, kPair, kClutter };

// A frame or pair to evaluate with every variant.
struct Item {
  ItemKind kind = ItemKind::k3d;
  int set = 0, frame = 0;  // realistic: set index, frame; pairs: index into the pair list; clutter: frame
};

struct PairSpec {
  std::string texture;
  PairFamily family;
  int level;
  uint64_t seed;
};

// Detectors of one worker thread, per variant and registered object.
struct WorkerDetectors {
  std::map<std::tuple<int, int, int, bool>, std::unique_ptr<detector::Detector>> per_object;  // variant, set, object, 2d
  std::map<int, std::unique_ptr<detector::Detector>> clutter;                                // variant
};

ItemOutcome runRealistic(const detector::Detector& det, const RealisticSet& set, const SetFrame& f, bool two_d) {
  ItemOutcome o;
  detector::DetectionResult res;
  o.ms = timed(true, [&] { res = det.detect(f.image, f.camera); });
  o.checks_ms = res.time_ms.pose;
  if (const auto d = res.find(0)) {
    const MethodOutcome m = scoreOutcome(set.objects()[f.object], f, d->H, two_d ? std::nullopt : d->cMo);
    o.reported = true;
    o.found = m.found;
    o.pose_ok = !two_d && m.pose_ok;
    o.within = m.found && m.corner_px <= 3;
    o.wrong = !m.found;
    o.H = d->H;
  }
  return o;
}

// Everything the items refer to: the sets of every seed, the pairs, the clutter objects.
struct AblationWork {
  std::vector<std::unique_ptr<RealisticSet>> sets;
  std::vector<SetObject> clutter_objects;
  std::vector<PairSpec> pairs;
  std::vector<Item> items;
};

AblationWork prepareWork(const AblationData& data) {
  AblationWork w;
  for (const uint64_t seed : data.seeds)
    for (const RealisticSetSpec& spec : realisticSets(seed, data.frames_per_set))
      w.sets.push_back(std::make_unique<RealisticSet>(spec));
  for (size_t s = 0; s < std::min<size_t>(w.sets.size(), 3); ++s)
    if (w.sets[s]->spec().name != "far_oblique")
      for (const SetObject& o : w.sets[s]->objects()) w.clutter_objects.push_back(o);
  const std::vector<std::string> textures = pairTextures();
  for (int k = 0; k < data.pair_seeds; ++k)
    for (int f = 0; f < kPairFamilies; ++f)
      for (int l = 0; l < kPairLevels; ++l)
        for (size_t t = 0; t < textures.size(); ++t)
          w.pairs.push_back({textures[t], static_cast<PairFamily>(f), l,
                             pairSeed(data.pair_first_seed + static_cast<uint64_t>(k), static_cast<int>(t))});
  for (size_t s = 0; s < w.sets.size(); ++s)
    for (int i = 0; i < w.sets[s]->frames(); ++i) w.items.push_back({ItemKind::k3d, static_cast<int>(s), i});
  for (size_t p = 0; p < w.pairs.size(); ++p) w.items.push_back({ItemKind::kPair, 0, static_cast<int>(p)});
  for (int i = 0; i < data.clutter_frames; ++i) w.items.push_back({ItemKind::kClutter, 0, i});
  return w;
}

// Item k with every variant (its realistic frame also 2D-only into *out2d when data.two_d).
void evaluateItem(const AblationWork& w, size_t k, const std::vector<detector::DetectorOptions>& options,
                  const AblationData& data, WorkerDetectors* dets, std::vector<ItemOutcome>* out,
                  std::vector<ItemOutcome>* out2d) {
  const Item& it = w.items[k];
  const size_t n = options.size();
  out->assign(n, ItemOutcome{});
  if (it.kind == ItemKind::k3d) {
    const RealisticSet& set = *w.sets[static_cast<size_t>(it.set)];
    const SetFrame f = set.frame(it.frame);
    for (int pass = 0; pass < (data.two_d ? 2 : 1); ++pass) {
      const bool two_d = pass == 1;
      std::vector<ItemOutcome>& dst = two_d ? *out2d : *out;
      dst.resize(n);
      // Variants in an order rotated per frame: each is first (cache-cold) equally often.
      for (size_t r = 0; r < n; ++r) {
        const size_t v = (r + k) % n;
        auto& det = dets->per_object[{static_cast<int>(v), it.set, f.object, two_d}];
        if (!det) {
          det = std::make_unique<detector::Detector>(options[v]);
          const detector::ObjectModel& m = set.objects()[f.object].model;
          det->addObject(two_d ? twoDOnly(m) : m);
        }
        dst[v] = runRealistic(*det, set, f, two_d);
      }
    }
  } else if (it.kind == ItemKind::kPair) {
    const PairSpec& ps = w.pairs[static_cast<size_t>(it.frame)];
    const ViewPair p = makeViewPair(ps.texture, ps.family, ps.level, ps.seed);
    const detector::ObjectModel model = detector::makeObjectModel(ps.texture, p.reference, std::nullopt, std::nullopt);
    for (size_t v = 0; v < n; ++v) {
      detector::Detector det(options[v]);
      det.addObject(model);
      const detector::DetectionResult res = det.detect(p.scene, p.camera);
      if (const auto d = res.find(0)) {
        const double err = worstCornerError(p, d->H);
        (*out)[v].reported = true;
        (*out)[v].within = err <= 3;
        (*out)[v].found = err <= 30;
        (*out)[v].wrong = err > 30;
        (*out)[v].H = d->H;
      }
    }
  } else {
    const ClutterFrame c = clutterFrame(w.clutter_objects, data.seeds.front(), it.frame);
    for (size_t v = 0; v < n; ++v) {
      auto& det = dets->clutter[static_cast<int>(v)];
      if (!det) {
        det = std::make_unique<detector::Detector>(options[v]);
        for (const SetObject& o : w.clutter_objects) det->addObject(o.model);
      }
      const detector::DetectionResult res = det->detect(c.image, c.camera);
      for (const auto& d : res.detections) (*out)[v].false_detections += d.found;
      (*out)[v].reported = (*out)[v].false_detections > 0;
    }
  }
}

bool outcomeDiffers(const ItemOutcome& a, const ItemOutcome& b) {
  return a.reported != b.reported || a.found != b.found || a.pose_ok != b.pose_ok || a.within != b.within ||
         a.wrong != b.wrong || a.false_detections != b.false_detections;
}

bool reportMoved(const ItemOutcome& a, const ItemOutcome& b) {
  return a.reported && b.reported && (a.H - b.H).cwiseAbs().maxCoeff() > 1e-9 * std::max(1.0, b.H.cwiseAbs().maxCoeff());
}

// The counts per variant; "changed" and "moved" against variant 0.
std::vector<AblationCounts> tallyAblation(const std::vector<Item>& items,
                                          const std::vector<std::vector<ItemOutcome>>& results,
                                          const std::vector<std::vector<ItemOutcome>>& results2d, size_t variants) {
  std::vector<AblationCounts> counts(variants);
  std::vector<std::vector<double>> ms(variants);
  std::vector<double> checks_ms(variants, 0);
  for (size_t k = 0; k < items.size(); ++k)
    for (size_t v = 0; v < variants; ++v) {
      AblationCounts& c = counts[v];
      const ItemOutcome& o = results[k][v];
      c.changed += outcomeDiffers(o, results[k][0]);
      c.moved += reportMoved(o, results[k][0]);
      if (items[k].kind == ItemKind::k3d) {
        ++c.frames_3d;
        c.found_3d += o.found;
        c.pose_ok_3d += o.pose_ok;
        c.wrong_3d += o.wrong;
        ms[v].push_back(o.ms);
        checks_ms[v] += o.checks_ms;
        if (!results2d[k].empty()) {
          const ItemOutcome& o2 = results2d[k][v];
          ++c.frames_2d;
          c.found_2d += o2.found;
          c.within_3px_2d += o2.within;
          c.wrong_2d += o2.wrong;
          c.changed += outcomeDiffers(o2, results2d[k][0]);
          c.moved += reportMoved(o2, results2d[k][0]);
        }
      } else if (items[k].kind == ItemKind::kPair) {
        ++c.pairs;
        c.pairs_within_3px += o.within;
        c.pairs_wrong += o.wrong;
      } else if (items[k].kind == ItemKind::kClutter) {
        ++c.clutter_frames;
        c.clutter_false += o.false_detections;
      }
    }
  for (size_t v = 0; v < variants; ++v) {
    counts[v].median_ms = ms[v].empty() ? 0 : median(ms[v]);
    counts[v].mean_checks_ms = ms[v].empty() ? 0 : checks_ms[v] / static_cast<double>(ms[v].size());
  }
  return counts;
}

}  // namespace

std::vector<AblationCounts> runAblation(const std::vector<AblationVariant>& variants, const AblationData& data,
                                        int threads, const std::function<void(int, int)>& progress) {
  data.check();
  if (variants.empty()) throw std::invalid_argument("runAblation: no variants");
  if (threads < 1) throw std::invalid_argument("runAblation: threads must be >= 1");
  std::vector<detector::DetectorOptions> options(variants.size());
  for (size_t v = 0; v < variants.size(); ++v) {
    variants[v].apply(&options[v]);
    options[v].sift.threads = 1;
    options[v].check();
  }
  const AblationWork w = prepareWork(data);
  // results[item][variant]; a realistic frame's 2D-only run goes to results2d.
  std::vector<std::vector<ItemOutcome>> results(w.items.size()), results2d(w.items.size());
  std::atomic<size_t> next{0};
  std::atomic<int> done{0};
  std::mutex progress_mu;
  auto work = [&] {
    WorkerDetectors dets;
    int current_set = -1;
    for (size_t k = next++; k < w.items.size(); k = next++) {
      const Item& it = w.items[k];
      if (it.kind == ItemKind::k3d && it.set != current_set) {  // a new set: the last one's detectors go
        dets.per_object.clear();
        current_set = it.set;
      }
      evaluateItem(w, k, options, data, &dets, &results[k], &results2d[k]);
      const int n = ++done;
      if (progress) {
        std::lock_guard<std::mutex> lock(progress_mu);
        progress(n, static_cast<int>(w.items.size()));
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) pool.emplace_back(work);
  for (auto& t : pool) t.join();
  return tallyAblation(w.items, results, results2d, variants.size());
}

std::string formatAblation(const std::vector<AblationVariant>& variants, const std::vector<AblationCounts>& counts) {
  std::string s =
      "| rule switched off | option | 3D found | 3D pose ok | 3D wrong | 2D found | 2D within 3 px | 2D wrong | "
      "pairs within 3 px | pairs wrong | clutter false | outcomes changed | reports moved | ms / frame | checks ms "
      "/ frame |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  if (counts.empty()) return s;
  const AblationCounts& b = counts[0];
  char buf[512];
  auto cell = [&](int value, int base, bool first) {
    if (first || value == base) return std::to_string(value);
    return std::to_string(value) + " (" + (value > base ? "+" : "") + std::to_string(value - base) + ")";
  };
  for (size_t v = 0; v < counts.size(); ++v) {
    const AblationCounts& c = counts[v];
    const bool first = v == 0;
    std::snprintf(buf, sizeof buf, "| %s | `%s` | %s | %s | %s | %s | %s | %s | %s | %s | %s | %d | %d | %.1f | %.2f |\n",
                  variants[v].name.c_str(), variants[v].off.c_str(), cell(c.found_3d, b.found_3d, first).c_str(),
                  cell(c.pose_ok_3d, b.pose_ok_3d, first).c_str(), cell(c.wrong_3d, b.wrong_3d, first).c_str(),
                  cell(c.found_2d, b.found_2d, first).c_str(), cell(c.within_3px_2d, b.within_3px_2d, first).c_str(),
                  cell(c.wrong_2d, b.wrong_2d, first).c_str(),
                  cell(c.pairs_within_3px, b.pairs_within_3px, first).c_str(),
                  cell(c.pairs_wrong, b.pairs_wrong, first).c_str(), cell(c.clutter_false, b.clutter_false, first).c_str(),
                  c.changed, c.moved, c.median_ms, c.mean_checks_ms);
    s += buf;
  }
  char tail[256];
  std::snprintf(tail, sizeof tail,
                "\n%d realistic frames (3D and 2D-only each), %d photo pairs, %d clutter frames.\n", b.frames_3d,
                b.pairs, b.clutter_frames);
  return s + tail;
}

}  // namespace refgrasp::eval
