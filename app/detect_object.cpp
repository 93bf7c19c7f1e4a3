// detect_object: find planar objects (reference image + pose) in images; one JSON line per image.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/camera.h"
#include "core/error.h"
#include "detector/detector.h"

using namespace refgrasp;
using namespace refgrasp::detector;
using json = nlohmann::ordered_json;  // keys in the documented order

namespace {

const char* kDescription = R"(Finds planar textured objects in images (SIFT + local-geometric-consistency matching +
homography + 6-DOF pose) and prints one JSON object per line per input image (per object and
instance when there are several):
  {"image":"p.png","found":true,"homography":[9 numbers row-major, reference px -> image px],
   "corners":[[u,v] x4 (pattern corners TL,TR,BR,BL, image px)],"R":[9 row-major],"t":[x,y,z],
   "inliers":42,"time_ms":{"extract":..,"match":..,"pose":..,"total":..}}
R, t: the object frame in the camera frame (cMo, metres); absent for 2D-only objects (no
reference_pose). With --right/--stereo, R, t are the fused pose in the LEFT camera frame and
"eyes" says which eyes found the object. found:false lines carry no geometry. With several
objects or --max-instances > 1 every line has "object" (name) and "instance" (0 = best).
With lens distortion, homography maps undistorted reference px to undistorted image px.
Exit status: 0 when every image was read and processed; 1 when an image could not be read or
used (one-line error on stderr naming the file, other images are still processed); 2 for bad
options or object/camera files.)";

json poseJson(const Pose& P, json j) {
  j["R"] = json::array();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) j["R"].push_back(P.R(r, c));
  j["t"] = {P.t.x(), P.t.y(), P.t.z()};
  return j;
}

json detectionJson(const Detection& d, json j) {
  j["found"] = d.found;
  if (!d.found) return j;
  const Eigen::Matrix3d H = d.H / d.H(2, 2);
  j["homography"] = json::array();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) j["homography"].push_back(H(r, c));
  j["corners"] = json::array();
  for (const auto& c : d.corners) j["corners"].push_back({c.x(), c.y()});
  if (d.cMo) j = poseJson(*d.cMo, j);
  j["inliers"] = d.inliers;
  return j;
}

json timingJson(const DetectionTimings& t) {
  return {{"extract", t.extract}, {"match", t.match}, {"pose", t.pose}, {"total", t.total}};
}

// Reads an image as 8-bit gray; empty Mat when it cannot be read.
cv::Mat readGray(const std::string& path) {
  try {
    return cv::imread(path, cv::IMREAD_GRAYSCALE);
  } catch (const cv::Exception&) {
    return cv::Mat();
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app(kDescription, "detect_object");
  std::vector<std::string> object_files, images, rights;
  std::string camera_file, rig_file, matcher = "paper", pose_method = poseMethodName(DetectorOptions{}.pose);
  DetectorOptions opt;
  app.add_option("--object", object_files, "object definition YAML (repeat for several objects)")
      ->required()
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  app.add_option("--camera", camera_file,
                 "intrinsics of the images (ROS yaml or ViSP xml); default: the first object's "
                 "reference camera, or an ideal pinhole for 2D-only objects");
  app.add_option("--matcher", matcher, "paper (local geometric consistency) or ratio (baseline)")
      ->check(CLI::IsMember({"paper", "ratio"}));
  app.add_option("--pose", pose_method, "paper (eq. 7 + LM on 4 corners) or refined (IPPE + robust LM)")
      ->check(CLI::IsMember({"paper", "refined"}));
  app.add_option("--right", rights, "right stereo image, one per IMAGE in order (repeat; needs --stereo)")
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  app.add_option("--stereo", rig_file, "stereo rig YAML (left/right cameras, right_in_left)");
  app.add_option("--max-instances", opt.match.max_instances, "instances reported per object")
      ->check(CLI::Range(1, 100));
  app.add_option("--ratio", opt.match.global_ratio, "global descriptor ratio test")
      ->check(CLI::Range(0.1, 1.0));
  app.add_option("--max-features", opt.sift.max_features, "scene SIFT features kept (0 = all)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--min-inliers", opt.match.min_inliers, "homography inliers needed")
      ->check(CLI::Range(4, 100000));
  app.add_option("IMAGE", images, "scene image(s) (left images with --stereo)")->required();
  CLI11_PARSE(app, argc, argv);

  opt.match.matcher = matcher == "ratio" ? MatcherType::kRatio : MatcherType::kPaper;
  opt.pose = pose_method == "paper" ? PoseMethod::kPaper : PoseMethod::kRefined;
  const bool stereo = !rig_file.empty();
  if (stereo != !rights.empty() || (stereo && rights.size() != images.size())) {
    std::cerr << "detect_object: --stereo needs one --right image per IMAGE (and vice versa)\n";
    return 2;
  }
  if (stereo && !camera_file.empty()) {
    std::cerr << "detect_object: --camera and --stereo are exclusive (the rig holds the cameras)\n";
    return 2;
  }

  std::unique_ptr<Detector> detector;
  std::vector<std::string> names;
  std::optional<Intrinsics> camera;
  StereoRig rig;
  try {
    detector = std::make_unique<Detector>(opt);
    for (const auto& f : object_files) {
      const ObjectModel m = loadObjectDefinition(f);
      if (!camera && m.camera) camera = m.camera;
      names.push_back(m.name);
      detector->addObject(m);
    }
    if (!camera_file.empty()) camera = loadCameraFile(camera_file);
    if (stereo) rig = loadStereoRig(rig_file);
  } catch (const std::exception& e) {
    std::cerr << "detect_object: " << e.what() << "\n";
    return 2;
  }
  const bool tagged = names.size() > 1 || opt.match.max_instances > 1;

  int status = 0;
  for (size_t i = 0; i < images.size(); ++i) {
    const cv::Mat left = readGray(images[i]);
    if (left.empty()) {
      std::cerr << images[i] << ": cannot read image (missing, unreadable or corrupt)\n";
      status = 1;
      continue;
    }
    json base = {{"image", images[i]}};
    if (stereo) {
      const cv::Mat right = readGray(rights[i]);
      if (right.empty()) {
        std::cerr << rights[i] << ": cannot read image (missing, unreadable or corrupt)\n";
        status = 1;
        continue;
      }
      const StereoDetectionResult r = detector->detectStereo(left, right, rig);
      if (!r.ok) {
        std::cerr << (r.left.ok ? rights[i] : images[i]) << ": " << r.error << "\n";
        status = 1;
        continue;
      }
      DetectionTimings t = r.left.time_ms;
      t.extract += r.right.time_ms.extract;
      t.match += r.right.time_ms.match;
      t.pose += r.right.time_ms.pose;
      t.total += r.right.time_ms.total;
      base["right"] = rights[i];
      for (const StereoDetection& s : r.objects) {
        const Detection& eye = s.left.found ? s.left : s.right;
        json j = detectionJson(eye, base);
        j["found"] = s.fused.eyes != EyesUsed::kNone;
        j["eyes"] = eyesUsedName(s.fused.eyes);
        if (s.fused.lMo) j = poseJson(*s.fused.lMo, j);
        if (tagged) {
          j["object"] = names[s.object];
          j["instance"] = 0;
        }
        j["time_ms"] = timingJson(t);
        std::cout << j.dump() << "\n";
      }
      continue;
    }
    const Intrinsics cam = camera ? *camera
                                  : Intrinsics::pinhole(left.cols, left.rows,
                                                        std::max(left.cols, left.rows),
                                                        (left.cols - 1) / 2.0, (left.rows - 1) / 2.0);
    const DetectionResult r = detector->detect(left, cam);
    if (!r.ok) {
      std::cerr << images[i] << ": " << r.error << "\n";
      status = 1;
      continue;
    }
    for (const Detection& d : r.detections) {
      json j = detectionJson(d, base);
      if (tagged) {
        j["object"] = names[d.object];
        j["instance"] = d.instance;
      }
      j["time_ms"] = timingJson(r.time_ms);
      std::cout << j.dump() << "\n";
    }
  }
  return status;
}
