// detect_object: find planar objects (reference image + pose) in images; one JSON line per image.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>

#include "core/camera.h"
#include "core/error.h"
#include "core/image_io.h"
#include "detector/detection_json.h"
#include "detector/detector.h"
#include "detector/detector_config.h"
#include "detector_cli.h"
#include "tool/tool.h"

using namespace refgrasp;
using namespace refgrasp::detector;

namespace {

const char* kDescription = R"(Finds planar textured objects in images (SIFT + local-geometric-consistency matching +
homography + 6-DOF pose) and prints one JSON object per line per input image (per object and
instance when there are several):
  {"image":"p.png","found":true,"homography":[9 numbers row-major, reference px -> image px],
   "corners":[[u,v] x4 (pattern corners TL,TR,BR,BL, image px)],"R":[9 row-major],"t":[x,y,z],
   "inliers":42,"time_ms":{"extract":..,"match":..,"pose":..,"total":..}}
R, t: the object frame in the camera frame (cMo, metres); absent for 2D-only objects (no
reference_pose). A several-view object (a box's faces) adds "views" (the views fused into
the instance, most inliers first) and "view" (the one whose homography and corners are given);
R, t are then its own frame's, jointly over every view seen. With --right/--stereo, R, t are the fused pose in the LEFT camera frame and
"eyes" says which eyes found the object. found:false lines carry no geometry. With several
objects or --max-instances > 1 every line has "object" (name) and "instance" (0 = best).
With lens distortion, homography maps undistorted reference px to undistorted image px.
Detector options: --detector-config FILE (every field: config/detector.yaml); the options below
override the file. Images and options may come in any order.
Exit status: 0 when every image was read and processed; 1 when an image could not be read or
used (one-line error on stderr naming the file, other images are still processed); 2 for bad
options or object/camera/detector-config files; 3 when stdout could not be written.
Images larger than $REFGRASP_MAX_IMAGE_PIXELS pixels (default 2^25) are refused from their header.)";

// Reads an image as 8-bit gray; prints "<file>: cannot read image: <problem>" when it cannot.
cv::Mat readGray(const std::string& path) {
  ImageRead r = readImage(path, ImageMode::kGray);
  if (!r.ok()) std::cerr << oneLine(path, 1000) << ": cannot read image: " << r.problem << "\n";
  return r.image;
}

int detectObject(int argc, char** argv) {
  CLI::App app(kDescription, "detect_object");
  std::vector<std::string> object_files, images, rights;
  std::string camera_file, rig_file;
  DetectorCli detector_cli;
  DetectorOptions cli;  // values of the tuning options below; only those given are applied
  // Repeatable options take exactly one value each, so the images after them stay positionals.
  app.add_option("--object", object_files, "object definition YAML (repeat for several objects)")
      ->required()
      ->expected(1)
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  app.add_option("--camera", camera_file,
                 "intrinsics of the images (ROS yaml or ViSP xml); default: the first object's "
                 "reference camera (a several-view object's: its first view's), or an ideal pinhole "
                 "for 2D-only objects");
  detector_cli.add(app);
  app.add_option("--right", rights, "right stereo image, one per IMAGE in order (repeat; needs --stereo)")
      ->expected(1)
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  app.add_option("--stereo", rig_file, "stereo rig YAML (left/right cameras, right_in_left)");
  CLI::Option* o_instances =
      app.add_option("--max-instances", cli.match.max_instances, "instances reported per object")
          ->check(tool::Integer(1, 100));
  CLI::Option* o_ratio = app.add_option("--ratio", cli.match.global_ratio, "global descriptor ratio test")
                             ->check(tool::Finite(0.1, 1.0));
  CLI::Option* o_features =
      app.add_option("--max-features", cli.sift.max_features, "scene SIFT features kept (0 = all)")
          ->check(tool::Integer(0, INT32_MAX));
  CLI::Option* o_inliers = app.add_option("--min-inliers", cli.match.min_inliers, "homography inliers needed")
                               ->check(tool::Integer(4, 100000));
  app.add_option("IMAGE", images, "scene image(s) (left images with --stereo)")->required();
  tool::parse(app, argc, argv);

  const bool stereo = !rig_file.empty();
  if (stereo != !rights.empty() || (stereo && rights.size() != images.size()))
    throw std::invalid_argument("--stereo needs one --right image per IMAGE (and vice versa)");
  if (stereo && !camera_file.empty())
    throw std::invalid_argument("--camera and --stereo are exclusive (the rig holds the cameras)");

  std::unique_ptr<Detector> detector;
  std::vector<std::string> names;
  std::optional<Intrinsics> camera;
  StereoRig rig;
  DetectorOptions opt = detector_cli.options();
  if (o_instances->count()) opt.match.max_instances = cli.match.max_instances;
  if (o_ratio->count()) opt.match.global_ratio = cli.match.global_ratio;
  if (o_features->count()) opt.sift.max_features = cli.sift.max_features;
  if (o_inliers->count()) opt.match.min_inliers = cli.match.min_inliers;
  detector = std::make_unique<Detector>(opt);
  for (const auto& f : object_files) {
    const ObjectModel m = loadObjectDefinition(f);
    if (!camera && m.camera) camera = m.camera;
    if (!camera && m.isMultiView()) camera = m.views[0].model->camera;
    names.push_back(m.name);
    detector->addObject(m);
  }
  if (!camera_file.empty()) camera = loadCameraFile(camera_file);
  if (stereo) rig = loadStereoRig(rig_file);
  const bool tagged = names.size() > 1 || opt.match.max_instances > 1;

  int status = 0;
  for (size_t i = 0; i < images.size(); ++i) {
    const cv::Mat left = readGray(images[i]);
    if (left.empty()) {
      status = 1;
      continue;
    }
    Json base = {{"image", images[i]}};
    std::vector<Json> lines;
    if (stereo) {
      const cv::Mat right = readGray(rights[i]);
      if (right.empty()) {
        status = 1;
        continue;
      }
      const StereoDetectionResult r = detector->detectStereo(left, right, rig, {0, static_cast<int64_t>(i)});
      if (!r.ok) {
        std::cerr << (r.left.ok ? rights[i] : images[i]) << ": " << r.error << "\n";
        status = 1;
        continue;
      }
      base["right"] = rights[i];
      lines = stereoDetectionLines(r, base, names, tagged);
    } else {
      const Intrinsics cam = camera ? *camera
                                    : Intrinsics::pinhole(left.cols, left.rows,
                                                          std::max(left.cols, left.rows),
                                                          (left.cols - 1) / 2.0, (left.rows - 1) / 2.0);
      const DetectionResult r = detector->detect(left, cam, {0, static_cast<int64_t>(i)});
      if (!r.ok) {
        std::cerr << images[i] << ": " << r.error << "\n";
        status = 1;
        continue;
      }
      lines = detectionLines(r, base, names, tagged);
    }
    for (const Json& j : lines) std::cout << j.dump() << "\n";
  }
  return status;
}

}  // namespace

int main(int argc, char** argv) { return tool::run("detect_object", argc, argv, detectObject); }
