#include "detector/detector_config.h"

#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <type_traits>

#include "core/error.h"
#include "core/yaml.h"

namespace refgrasp::detector {
namespace {

// Every field of DetectorOptions, by its name in the file. O = (const) DetectorOptions.
template <class O, class Visit>
void visitFields(O& o, Visit&& v) {
  v("sift.max_features", o.sift.max_features);
  v("sift.octave_layers", o.sift.octave_layers);
  v("sift.contrast_threshold", o.sift.contrast_threshold);
  v("sift.edge_threshold", o.sift.edge_threshold);
  v("sift.sigma", o.sift.sigma);
  v("sift.upsample", o.sift.upsample);
  v("sift.implementation", o.sift.implementation);
  v("sift.threads", o.sift.threads);
  v("match.matcher", o.match.matcher);
  v("match.global_ratio", o.match.global_ratio);
  v("match.local_ratio", o.match.local_ratio);
  v("match.search_radius_factor", o.match.search_radius_factor);
  v("match.orientation_tolerance_rad", o.match.orientation_tolerance_rad);
  v("match.scale_tolerance", o.match.scale_tolerance);
  v("match.max_hypotheses", o.match.max_hypotheses);
  v("match.max_reference_features", o.match.max_reference_features);
  v("match.min_inliers", o.match.min_inliers);
  v("match.ransac_reproj_px", o.match.ransac_reproj_px);
  v("match.max_instances", o.match.max_instances);
  v("match.max_descriptor_distance", o.match.max_descriptor_distance);
  v("match.min_inlier_spread", o.match.min_inlier_spread);
  v("match.affine_below_px", o.match.affine_below_px);
  v("match.cylinder_views", o.match.cylinder_views);
  v("match.plane_views", o.match.plane_views);
  v("match.weak_regions", o.match.weak_regions);
  v("match.weak_contrast_threshold", o.match.weak_contrast_threshold);
  v("match.max_log10_nfa", o.match.max_log10_nfa);
  v("match.seed", o.match.seed);
  v("pose", o.pose);
  v("pose_options.paper_lm_iterations", o.pose_options.paper_lm_iterations);
  v("pose_options.refined_lm_iterations", o.pose_options.refined_lm_iterations);
  v("pose_options.huber_px", o.pose_options.huber_px);
  v("pose_options.keypoint_sigma_per_size", o.pose_options.keypoint_sigma_per_size);
  v("pose_options.min_corner_depth_m", o.pose_options.min_corner_depth_m);
  v("dense.enabled", o.dense.enabled);
  v("dense.max_iterations", o.dense.max_iterations);
  v("dense.epsilon", o.dense.epsilon);
  v("dense.max_template_px", o.dense.max_template_px);
  v("dense.max_corner_shift_px", o.dense.max_corner_shift_px);
  v("dense.min_correlation", o.dense.min_correlation);
  v("dense.gauss_filter_size", o.dense.gauss_filter_size);
  v("dense.normalize_sigma_px", o.dense.normalize_sigma_px);
  v("dense.raw_trusted_correlation", o.dense.raw_trusted_correlation);
  v("dense.normalized_min_correlation", o.dense.normalized_min_correlation);
  v("dense.max_2d_coarsening", o.dense.max_2d_coarsening);
  v("dense.pose_grid", o.dense.pose_grid);
  v("dense.robust", o.dense.robust);
  v("dense.robust_block_px", o.dense.robust_block_px);
  v("dense.robust_min_residual", o.dense.robust_min_residual);
  v("dense.robust_min_kept", o.dense.robust_min_kept);
  v("sanity.min_distance_m", o.sanity.min_distance_m);
  v("sanity.max_distance_m", o.sanity.max_distance_m);
  v("sanity.min_area_px2", o.sanity.min_area_px2);
  v("sanity.max_area_fraction", o.sanity.max_area_fraction);
  v("sanity.max_pose_gap_px", o.sanity.max_pose_gap_px);
  v("verify.enabled", o.verify.enabled);
  v("verify.min_correlation", o.verify.min_correlation);
  v("verify.compare_px", o.verify.compare_px);
  v("verify.strong_correlation", o.verify.strong_correlation);
  v("verify.min_strong_cells", o.verify.min_strong_cells);
  v("verify.periodic_min_strong_cells", o.verify.periodic_min_strong_cells);
  v("verify.realign", o.verify.realign);
  v("verify.realign_trusted_correlation", o.verify.realign_trusted_correlation);
  v("verify.realign_verified_correlation", o.verify.realign_verified_correlation);
  v("verify.realign_verified_gain", o.verify.realign_verified_gain);
  v("verify.realign_verified_cells", o.verify.realign_verified_cells);
  v("verify.realign_min_in_view", o.verify.realign_min_in_view);
  v("verify.period_rematch", o.verify.period_rematch);
  v("verify.spare_candidate", o.verify.spare_candidate);
  v("verify.period_ambiguity_margin", o.verify.period_ambiguity_margin);
  v("verify.period_ambiguity_cells", o.verify.period_ambiguity_cells);
  v("verify.period_switch_correlation", o.verify.period_switch_correlation);
  v("verify.max_feature_pose_rms_px", o.verify.max_feature_pose_rms_px);
  v("verify.second_pass_needs_dense", o.verify.second_pass_needs_dense);
  v("multiview.max_gap_m", o.multiview.max_gap_m);
  v("multiview.max_gap_fraction", o.multiview.max_gap_fraction);
  v("multiview.max_rotation_gap_rad", o.multiview.max_rotation_gap_rad);
}

// check() names fields "<Options>.<field>"; the file names them "<section>.<field>".
const std::map<std::string, std::string> kSectionOf = {
    {"SiftOptions", "sift"},          {"MatchOptions", "match"},
    {"PoseOptions", "pose_options"},  {"DenseRefineOptions", "dense"},
    {"SanityOptions", "sanity"},      {"VerifyOptions", "verify"},
    {"MultiViewOptions", "multiview"}};

const char* name(MatcherType m) { return m == MatcherType::kRatio ? "ratio" : "paper"; }
const char* name(SiftImplementation i) { return i == SiftImplementation::kOpenCV ? "opencv" : "fast"; }

}  // namespace

DetectorOptions loadDetectorOptions(const std::string& path) {
  const YamlFile f(path);
  DetectorOptions opt;
  // Known fields, per section ("" = top level).
  std::map<std::string, std::set<std::string>> known;
  visitFields(opt, [&](const std::string& field, auto&) {
    const size_t dot = field.find('.');
    if (dot == std::string::npos) {
      known[""].insert(field);
    } else {
      known[""].insert(field.substr(0, dot));
      known[field.substr(0, dot)].insert(field.substr(dot + 1));
    }
  });
  f.onlyKeys(f.root(), "", known[""]);
  for (const auto& [section, keys] : known)
    if (!section.empty() && f.has(f.root(), section)) f.onlyKeys(f.get(f.root(), section), section, keys);

  visitFields(opt, [&](const std::string& field, auto& value) {
    using T = std::decay_t<decltype(value)>;
    const YAML::Node node = f.get(f.root(), field);
    if (!node.IsDefined()) return;  // not in the file: the default
    if (node.IsNull()) f.fail(field, "no value");
    if constexpr (std::is_same_v<T, bool>) {
      value = f.boolean(f.root(), field, value);
    } else if constexpr (std::is_same_v<T, int>) {
      value = f.integer(f.root(), field);
    } else if constexpr (std::is_same_v<T, uint64_t>) {
      const double v = f.number(f.root(), field);
      if (v < 0 || v != std::floor(v) || v > 9007199254740992.0)
        f.fail(field, "expected an integer in [0, 2^53]");
      value = static_cast<uint64_t>(v);
    } else if constexpr (std::is_same_v<T, double>) {
      value = f.number(f.root(), field);
    } else if constexpr (std::is_same_v<T, MatcherType>) {
      const std::string s = f.string(f.root(), field);
      if (s != "paper" && s != "ratio") f.fail(field, "expected paper or ratio, got '" + s + "'");
      value = s == "ratio" ? MatcherType::kRatio : MatcherType::kPaper;
    } else if constexpr (std::is_same_v<T, SiftImplementation>) {
      const std::string s = f.string(f.root(), field);
      if (s != "fast" && s != "opencv") f.fail(field, "expected fast or opencv, got '" + s + "'");
      value = s == "opencv" ? SiftImplementation::kOpenCV : SiftImplementation::kFast;
    } else {
      static_assert(std::is_same_v<T, PoseMethod>);
      const std::string s = f.string(f.root(), field);
      if (s != "paper" && s != "refined") f.fail(field, "expected paper or refined, got '" + s + "'");
      value = s == "paper" ? PoseMethod::kPaper : PoseMethod::kRefined;
    }
  });

  // Counts that set loop lengths or allocations: a typo of a few zeros must not hang a frame.
  static const std::map<std::string, double> kMaxima = {
      {"sift.threads", 256},
      {"match.max_hypotheses", 100000},
      {"match.max_instances", 100},
      {"pose_options.paper_lm_iterations", 10000},
      {"pose_options.refined_lm_iterations", 10000},
      {"dense.max_iterations", 10000},
      {"dense.max_template_px", 1 << 24},
      {"dense.gauss_filter_size", 99},
      {"dense.pose_grid", 64}};
  for (const auto& [field, max] : kMaxima)
    if (f.has(f.root(), field) && f.number(f.root(), field) > max)
      f.fail(field, "must be at most " + std::to_string(static_cast<long long>(max)));

  try {
    opt.check();
  } catch (const std::invalid_argument& e) {
    // "<Options>.<field>: <problem>" -> "<file>: <section>.<field>: <problem>"
    const std::string what = e.what();
    const size_t dot = what.find('.'), colon = what.find(": ");
    if (dot != std::string::npos && colon != std::string::npos && dot < colon &&
        kSectionOf.count(what.substr(0, dot)))
      f.fail(kSectionOf.at(what.substr(0, dot)) + what.substr(dot, colon - dot), what.substr(colon + 2));
    throw ConfigError(path, what);
  }
  return opt;
}

std::vector<std::pair<std::string, std::string>> detectorOptionValues(const DetectorOptions& opt) {
  std::vector<std::pair<std::string, std::string>> out;
  visitFields(opt, [&](const std::string& field, const auto& value) {
    using T = std::decay_t<decltype(value)>;
    char buf[64];
    if constexpr (std::is_same_v<T, bool>) {
      out.emplace_back(field, value ? "true" : "false");
    } else if constexpr (std::is_same_v<T, int> || std::is_same_v<T, uint64_t>) {
      out.emplace_back(field, std::to_string(value));
    } else if constexpr (std::is_same_v<T, double>) {
      std::snprintf(buf, sizeof buf, "%.17g", value);
      out.emplace_back(field, buf);
    } else if constexpr (std::is_same_v<T, MatcherType> || std::is_same_v<T, SiftImplementation>) {
      out.emplace_back(field, name(value));
    } else {
      out.emplace_back(field, poseMethodName(value));
    }
  });
  return out;
}

}  // namespace refgrasp::detector
