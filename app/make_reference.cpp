// make_reference: an object definition (reference image + 6-DOF reference pose) from one photo.
#include <CLI/CLI.hpp>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "core/camera.h"
#include "core/error.h"
#include "core/image_io.h"
#include "reference/make_reference.h"
#include "tool/tool.h"

using namespace refgrasp;
namespace fs = std::filesystem;

namespace {

const char* kDescription = R"(Makes an object definition (config/objects/*.yaml, docs/formats.md "Object definition") from one
photo of a planar object and the photo's camera file, with the 6-DOF reference pose from either
  --corners u1,v1,...,u4,v4 --size W,H   the corners TL, TR, BR, BL (photo px) of a rectangle of
                                         W x H metres on the object (planar PnP); the pattern
                                         region is the rectangle;
  --apriltag FAMILY --tag-size S         an AprilTag (36h11, 25h9, 16h5, circle21h7; S = side of its
                                         black square, metres) on the object's plane; the pattern
                                         region is --region u,v,u,v,... or the photo minus the tag.
Object frame: origin at the centre of the rectangle (tag), x along its top edge, y along its left
edge, z into the plane. Also writes a picture (--check, default OUTPUT with .png) with the pattern
region, the rectangle/tag and the object axes (x red, y green, z blue) to check the result.
Exit status: 0 written; 2 bad options or files, or input that defines no reference (corners not a
convex quadrilateral, a tag not found, sizes <= 0), with a one-line error; 3 an output could not
be written.)";

std::vector<double> numbers(const std::string& text, const std::string& option, size_t n_min,
                            size_t n_exact = 0) {
  std::vector<double> v;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) {
    try {
      size_t used = 0;
      v.push_back(std::stod(item, &used));
      if (used != item.size() || !std::isfinite(v.back())) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      throw std::invalid_argument(option + ": '" + item + "' is not a finite number");
    }
  }
  if ((n_exact && v.size() != n_exact) || v.size() < n_min || v.size() % 2 != 0)
    throw std::invalid_argument(option + ": expected " +
                                (n_exact ? std::to_string(n_exact) + " numbers" : "pairs u,v of numbers"));
  return v;
}

int makeReference(int argc, char** argv) {
  CLI::App app(kDescription, "make_reference");
  std::string photo_file, camera_file, output, name, check, corners, size, family, region;
  double tag_size = 0;
  int tag_id = -1;
  app.add_option("--image", photo_file, "the photo (the reference image)")->required();
  app.add_option("--camera", camera_file, "the photo's intrinsics (ROS yaml / ViSP xml)")->required();
  app.add_option("--output", output, "object definition YAML to write")->required();
  app.add_option("--name", name, "object name (default: the output's file stem)");
  app.add_option("--check", check, "picture to write for checking (default: OUTPUT with .png)");
  auto* c = app.add_option("--corners", corners, "u1,v1,...,u4,v4: rectangle corners TL, TR, BR, BL (px)");
  auto* s = app.add_option("--size", size, "W,H: the rectangle's width and height (metres)");
  auto* a = app.add_option("--apriltag", family, "tag family (36h11, 25h9, 16h5, circle21h7)");
  auto* t = app.add_option("--tag-size", tag_size, "side of the tag's black square (metres)")
                ->check(tool::Finite(1e-4, 100));
  app.add_option("--tag-id", tag_id, "the tag to use when the photo shows several (-1: the only one)")
      ->check(tool::Integer(-1, INT32_MAX));
  app.add_option("--region", region, "u,v,u,v,...: pattern region polygon (px; default: photo minus tag)");
  c->needs(s);
  s->needs(c);
  a->needs(t);
  t->needs(a);
  c->excludes(a);
  tool::parse(app, argc, argv);
  if (corners.empty() && family.empty()) {
    std::cerr << "make_reference: give --corners and --size, or --apriltag and --tag-size\n";
    return 2;
  }
  if (name.empty()) name = fs::path(output).stem().string();
  if (check.empty()) check = fs::path(output).replace_extension(".png").string();
  tool::Paths paths;
  paths.input("--image", photo_file);
  paths.input("--camera", camera_file);
  paths.output("--output", output);
  paths.output("--check", check);
  paths.check();
  try {
    const Intrinsics cam = loadCameraFile(camera_file);
    const ImageRead read = readImage(photo_file, ImageMode::kColor);
    if (!read.ok()) throw ConfigError(photo_file, "cannot read image: " + read.problem);
    const cv::Mat& photo = read.image;
    if (photo.cols != cam.width || photo.rows != cam.height)
      throw ConfigError(camera_file, "image size " + std::to_string(cam.width) + "x" +
                                         std::to_string(cam.height) + " differs from the photo's " +
                                         std::to_string(photo.cols) + "x" + std::to_string(photo.rows));
    reference::Reference ref;
    if (!corners.empty()) {
      const std::vector<double> v = numbers(corners, "--corners", 8, 8);
      const std::vector<double> wh = numbers(size, "--size", 2, 2);
      std::array<Eigen::Vector2d, 4> px;
      for (size_t i = 0; i < 4; ++i) px[i] = {v[2 * i], v[2 * i + 1]};
      ref = reference::fromCorners(px, wh[0], wh[1], cam);
    } else {
      reference::TagOptions o;
      o.family = family;
      o.tag_size_m = tag_size;
      o.id = tag_id;
      if (!region.empty()) {
        const std::vector<double> v = numbers(region, "--region", 6);
        for (size_t i = 0; i + 1 < v.size(); i += 2) o.region_px.emplace_back(v[i], v[i + 1]);
      }
      ref = reference::fromTag(photo, cam, o);
    }
    reference::writeObjectDefinition(output, name, photo_file, camera_file, ref);
    tool::writeImage(check, reference::drawReference(photo, ref, cam));
    std::cerr << "make_reference: " << output << " (" << ref.method << ", object at "
              << ref.cMo.t.norm() << " m, corner RMS " << ref.rms_px << " px); check " << check << "\n";
  } catch (const OutputError&) {
    throw;  // exit 3
  } catch (const std::exception& e) {
    std::cerr << "make_reference: " << e.what() << "\n";
    return 2;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return tool::run("make_reference", argc, argv, makeReference); }
