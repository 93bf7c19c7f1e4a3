#pragma once
// Detections as JSON: the documented detect_object line (docs/formats.md "detect_object's JSON
// line"), for every tool that writes detections. Field order: the caller's `base` fields (e.g.
// "image", "right"), "found", then when found "homography" (9 numbers row-major, undistorted
// reference px -> undistorted image px, H(2,2) = 1), "corners" ([u, v] x 4, TL TR BR BL, image px),
// "R" and "t" (cMo, core/json.h; only with a pose), "inliers"; for a several-view object then
// "views" (the names of the views fused into the instance, most inliers first) and "view" (the
// one whose homography and corners these are); stereo lines then "eyes"; tagged
// lines "object" (name) and "instance"; last "time_ms" {"extract","match","pose","total"}.
#include <string>
#include <vector>

#include "core/json.h"
#include "detector/detector.h"

namespace refgrasp::detector {

/// base + "found" and, when found, the geometry and "inliers".
Json detectionJson(const Detection& d, Json base = Json::object());
/// {"extract": ms, "match": ms, "pose": ms, "total": ms}
Json timingsJson(const DetectionTimings& t);

/// The lines of one image: per object in id order, one per found instance or one found:false.
/// names[id] is written as "object" (with "instance") when tagged.
std::vector<Json> detectionLines(const DetectionResult& r, const Json& base,
                                 const std::vector<std::string>& names, bool tagged);
/// The lines of one stereo pair: per object, the geometry of the eye that found it (left first),
/// "found" when any eye did, R and t the fused pose in the left camera frame, "eyes"; time_ms
/// summed over both eyes.
std::vector<Json> stereoDetectionLines(const StereoDetectionResult& r, const Json& base,
                                       const std::vector<std::string>& names, bool tagged);

}  // namespace refgrasp::detector
