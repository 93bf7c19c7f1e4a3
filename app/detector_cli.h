#pragma once
// The detector options every app takes on its command line: --detector-config FILE (every field,
// config/detector.yaml), then --matcher and --pose override the file when given.
#include <CLI/CLI.hpp>
#include <string>

#include "detector/detector.h"
#include "detector/detector_config.h"

namespace refgrasp {

class DetectorCli {
 public:
  /// Registers the options on `app` (before CLI11_PARSE).
  void add(CLI::App& app) {
    app.add_option("--detector-config", config_file_,
                   "detector options YAML (config/detector.yaml lists every field); the options "
                   "below override it");
    matcher_opt_ =
        app.add_option("--matcher", matcher_, "paper (local geometric consistency) or ratio (baseline)")
            ->check(CLI::IsMember({"paper", "ratio"}));
    pose_opt_ = app.add_option("--pose", pose_, "paper (eq. 7 + LM on 4 corners) or refined (IPPE + robust LM)")
                    ->check(CLI::IsMember({"paper", "refined"}));
  }
  /// The file's options (or the defaults) with the overrides given. Throws ConfigError.
  detector::DetectorOptions options() const {
    detector::DetectorOptions opt;
    if (!config_file_.empty()) opt = detector::loadDetectorOptions(config_file_);
    if (matcher_opt_->count())
      opt.match.matcher = matcher_ == "ratio" ? detector::MatcherType::kRatio : detector::MatcherType::kPaper;
    if (pose_opt_->count())
      opt.pose = pose_ == "paper" ? detector::PoseMethod::kPaper : detector::PoseMethod::kRefined;
    return opt;
  }

 private:
  std::string config_file_, matcher_, pose_;
  CLI::Option* matcher_opt_ = nullptr;
  CLI::Option* pose_opt_ = nullptr;
};

}  // namespace refgrasp
