#include "detector/detection_json.h"

namespace refgrasp::detector {

Json detectionJson(const Detection& d, Json j) {
  j["found"] = d.found;
  if (!d.found) return j;
  j["homography"] = matrixJson(d.H / d.H(2, 2));
  j["corners"] = Json::array();
  for (const auto& c : d.corners) j["corners"].push_back({c.x(), c.y()});
  if (d.cMo) putPose(&j, *d.cMo);
  j["inliers"] = d.inliers;
  if (!d.views.empty()) {
    j["views"] = d.views;
    j["view"] = d.view;
  }
  return j;
}

Json timingsJson(const DetectionTimings& t) {
  return {{"extract", t.extract}, {"match", t.match}, {"pose", t.pose}, {"total", t.total}};
}

std::vector<Json> detectionLines(const DetectionResult& r, const Json& base,
                                 const std::vector<std::string>& names, bool tagged) {
  std::vector<Json> lines;
  for (const Detection& d : r.detections) {
    Json j = detectionJson(d, base);
    if (tagged) {
      j["object"] = names.at(d.object);
      j["instance"] = d.instance;
    }
    j["time_ms"] = timingsJson(r.time_ms);
    lines.push_back(std::move(j));
  }
  return lines;
}

std::vector<Json> stereoDetectionLines(const StereoDetectionResult& r, const Json& base,
                                       const std::vector<std::string>& names, bool tagged) {
  DetectionTimings t = r.left.time_ms;
  t.extract += r.right.time_ms.extract;
  t.match += r.right.time_ms.match;
  t.pose += r.right.time_ms.pose;
  t.total += r.right.time_ms.total;
  std::vector<Json> lines;
  for (const StereoDetection& s : r.objects) {
    Json j = detectionJson(s.left.found ? s.left : s.right, base);
    j["found"] = s.fused.eyes != EyesUsed::kNone;
    j["eyes"] = eyesUsedName(s.fused.eyes);
    if (s.fused.lMo) putPose(&j, *s.fused.lMo);
    if (tagged) {
      j["object"] = names.at(s.object);
      j["instance"] = 0;
    }
    j["time_ms"] = timingsJson(t);
    lines.push_back(std::move(j));
  }
  return lines;
}

}  // namespace refgrasp::detector
