#pragma once
// Detector options from a YAML file, so every tool tunes the detector the same way. The shipped
// config/detector.yaml holds every field with its default and documents it; a file may give any
// subset (sections sift, match, pose_options, dense, sanity and the scalar pose), the rest keeps
// the defaults of DetectorOptions{}.
#include <string>
#include <utility>
#include <vector>

#include "detector/detector.h"

namespace refgrasp::detector {

/// Throws ConfigError "<file>: <field>: <problem>" (field as in the file, e.g.
/// "match.min_inliers") on a missing or invalid file, an unknown field (typos), a wrong type, a
/// non-finite number or a value DetectorOptions::check() refuses.
DetectorOptions loadDetectorOptions(const std::string& path);

/// Every option as (field, value) in file order, e.g. {"match.min_inliers", "12"}; numbers
/// printed exactly (round trip). For logs and for comparing option sets.
std::vector<std::pair<std::string, std::string>> detectorOptionValues(const DetectorOptions& opt);

}  // namespace refgrasp::detector
