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
#include "reference/box_views.h"
#include "reference/cylinder_reference.h"
#include "reference/make_reference.h"
#include "tool/tool.h"

using namespace refgrasp;
namespace fs = std::filesystem;

namespace {

const char* kDescription = R"(Makes an object definition (config/objects/*.yaml, docs/formats.md "Object definition"), in one
of four ways (docs/tools/make_reference.md):
  --image PHOTO --camera CAM --corners u1,v1,...,u4,v4 --size W,H
        a planar object: the corners TL, TR, BR, BL (photo px) of a rectangle of W x H metres on
        it (planar PnP); the pattern region is the rectangle;
  --image PHOTO --camera CAM --apriltag FAMILY --tag-size S
        a planar object: an AprilTag (36h11, 25h9, 16h5, circle21h7; S = side of its black
        square, metres) on its plane; the pattern region is --region u,v,u,v,... or the photo
        minus the tag. Object frame (both): origin at the centre of the rectangle (tag), x along
        its top edge, y along its left edge, z into the plane;
  --cylinder --image PHOTO --camera CAM --radius R --left-edge u1,v1,u2,v2 --right-edge u1,v1,u2,v2
             --label-top u,v --label-bottom u,v
        a can or bottle: two points on each silhouette edge and a point on the label's top and
        bottom borders (photo px); the visible part of the label is unrolled into --label-image
        (default OUTPUT with _label.png) and the definition gets its size on the surface;
  --views --box-size W,H,D --face NAME=FILE [--face NAME=FILE ...]
        a box: the planar definitions of its faces (front, back, left, right, top, bottom), each
        with its frame at the face's centre, joined into one several-view definition.
The photo modes also write a picture (--check, default OUTPUT with .png) to check the result.
Exit status: 0 written; 2 bad options or files, or input that defines no reference (corners not a
convex quadrilateral, a tag not found, sizes <= 0, edges that give no axis), with a one-line
error; 3 an output could not be written.)";

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
  if (n_exact ? v.size() != n_exact : (v.size() < n_min || v.size() % 2 != 0))
    throw std::invalid_argument(option + ": expected " +
                                (n_exact ? std::to_string(n_exact) + " numbers" : "pairs u,v of numbers"));
  return v;
}

Eigen::Vector2d pointOption(const std::string& text, const std::string& option) {
  const std::vector<double> v = numbers(text, option, 2, 2);
  return {v[0], v[1]};
}

std::array<Eigen::Vector2d, 2> edgeOption(const std::string& text, const std::string& option) {
  const std::vector<double> v = numbers(text, option, 4, 4);
  return {Eigen::Vector2d(v[0], v[1]), Eigen::Vector2d(v[2], v[3])};
}

// --face NAME=FILE, as given.
std::vector<reference::BoxFaceDefinition> faceOptions(const std::vector<std::string>& faces) {
  std::vector<reference::BoxFaceDefinition> out;
  for (const std::string& f : faces) {
    const size_t eq = f.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == f.size())
      throw std::invalid_argument("--face: '" + f + "' is not NAME=FILE (NAME: front, back, left, right, top, bottom)");
    out.push_back({f.substr(0, eq), f.substr(eq + 1)});
  }
  return out;
}

// --views: nothing but the face definitions is read.
int makeBoxDefinition(const std::string& output, const std::string& name, const std::string& box_size,
                      const std::vector<std::string>& face_options) {
  const std::vector<reference::BoxFaceDefinition> faces = faceOptions(face_options);
  tool::Paths paths;
  for (const auto& f : faces) paths.input("--face " + f.face, f.definition);
  paths.output("--output", output);
  paths.check();
  const std::vector<double> size = numbers(box_size, "--box-size", 3, 3);
  reference::writeBoxDefinition(output, name, {size[0], size[1], size[2]}, faces);
  std::cerr << "make_reference: " << output << " (a " << size[0] << " x " << size[1] << " x " << size[2]
            << " m box, " << faces.size() << " face" << (faces.size() > 1 ? "s" : "") << ")\n";
  return 0;
}

int makeReference(int argc, char** argv) {
  CLI::App app(kDescription, "make_reference");
  std::string photo_file, camera_file, output, name, check, corners, size, family, region;
  std::string left_edge, right_edge, label_top, label_bottom, label_image, box_size;
  std::vector<std::string> faces;
  double tag_size = 0, radius = 0, max_incidence_deg = 65, pixels_per_metre = 0, snap_px = 4;
  int tag_id = -1;
  bool cylinder = false, views = false;
  auto* image = app.add_option("--image", photo_file, "the photo (the planar modes' reference image)");
  auto* camera = app.add_option("--camera", camera_file, "the photo's intrinsics (ROS yaml / ViSP xml)");
  app.add_option("--output", output, "object definition YAML to write")->required();
  app.add_option("--name", name, "object name (default: the output's file stem)");
  auto* chk = app.add_option("--check", check, "picture to write for checking (default: OUTPUT with .png)");
  auto* c = app.add_option("--corners", corners, "u1,v1,...,u4,v4: rectangle corners TL, TR, BR, BL (px)");
  auto* s = app.add_option("--size", size, "W,H: the rectangle's width and height (metres)");
  auto* a = app.add_option("--apriltag", family, "tag family (36h11, 25h9, 16h5, circle21h7)");
  auto* t = app.add_option("--tag-size", tag_size, "side of the tag's black square (metres)")
                ->check(tool::Finite(1e-4, 100));
  auto* ti = app.add_option("--tag-id", tag_id, "the tag to use when the photo shows several (-1: the only one)")
                 ->check(tool::Integer(-1, INT32_MAX));
  auto* rg = app.add_option("--region", region, "u,v,u,v,...: pattern region polygon (px; default: photo minus tag)");
  auto* cy = app.add_flag("--cylinder", cylinder, "a can or bottle: unroll its label (needs --radius, the edges, the borders)");
  auto* r = app.add_option("--radius", radius, "the radius of the surface the label is wrapped on (metres)");
  auto* le = app.add_option("--left-edge", left_edge, "u1,v1,u2,v2: two points on one silhouette edge (px)");
  auto* re = app.add_option("--right-edge", right_edge, "u1,v1,u2,v2: two points on the other silhouette edge (px)");
  auto* lt = app.add_option("--label-top", label_top, "u,v: a point on the label's top border (px)");
  auto* lb = app.add_option("--label-bottom", label_bottom, "u,v: a point on the label's bottom border (px)");
  auto* li = app.add_option("--label-image", label_image, "the unrolled label to write (default: OUTPUT with _label.png)");
  auto* mi = app.add_option("--max-incidence", max_incidence_deg,
                            "unroll where the surface is seen within this angle of its normal (degrees, 10-85)")
                 ->check(tool::Finite(10, 85));
  auto* pp = app.add_option("--pixels-per-metre", pixels_per_metre,
                            "label resolution on the surface (px/m; 0: the photo's at the can)")
                 ->check(tool::Finite(0, 1e6));
  auto* sn = app.add_option("--snap", snap_px,
                            "move each clicked edge to the straight photo edge within this many px (0: as clicked)")
                 ->check(tool::Finite(0, 20));
  auto* vw = app.add_flag("--views", views, "a box: join the faces' definitions (needs --box-size, --face)");
  auto* bs = app.add_option("--box-size", box_size, "W,H,D: the box's width, height, depth (metres)");
  auto* fc = app.add_option("--face", faces, "NAME=FILE: a face's planar definition (front, back, left, right, "
                                              "top, bottom), repeated");
  c->needs(s);
  s->needs(c);
  a->needs(t);
  t->needs(a);
  c->excludes(a);
  for (CLI::Option* o : {r, le, re, lt, lb}) {
    cy->needs(o);
    o->needs(cy);
  }
  for (CLI::Option* o : {li, mi, pp, sn}) o->needs(cy);
  for (CLI::Option* o : {c, a, ti, rg}) cy->excludes(o);
  for (CLI::Option* o : {bs, fc}) {
    vw->needs(o);
    o->needs(vw);
  }
  for (CLI::Option* o : {image, camera, chk, c, a, ti, rg, cy}) vw->excludes(o);
  tool::parse(app, argc, argv);
  if (name.empty()) name = fs::path(output).stem().string();
  if (views) return makeBoxDefinition(output, name, box_size, faces);
  if (photo_file.empty() || camera_file.empty()) {
    std::cerr << "make_reference: --image and --camera are required (except with --views)\n";
    return 2;
  }
  if (!cylinder && corners.empty() && family.empty()) {
    std::cerr << "make_reference: give --corners and --size, --apriltag and --tag-size, --cylinder and its points, "
                 "or --views\n";
    return 2;
  }
  if (check.empty()) check = fs::path(output).replace_extension(".png").string();
  if (label_image.empty()) label_image = (fs::path(output).parent_path() / (fs::path(output).stem().string() + "_label.png")).string();
  tool::Paths paths;
  paths.input("--image", photo_file);
  paths.input("--camera", camera_file);
  paths.output("--output", output);
  paths.output("--check", check);
  if (cylinder) paths.output("--label-image", label_image);
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
    if (cylinder) {
      reference::CylinderPoints pts;
      pts.left_edge = edgeOption(left_edge, "--left-edge");
      pts.right_edge = edgeOption(right_edge, "--right-edge");
      pts.label_top = pointOption(label_top, "--label-top");
      pts.label_bottom = pointOption(label_bottom, "--label-bottom");
      reference::CylinderOptions o;
      o.radius_m = radius;
      o.max_incidence_rad = max_incidence_deg * M_PI / 180;
      o.pixels_per_metre = pixels_per_metre;
      o.snap_px = snap_px;
      const reference::CylinderGeometry g = reference::cylinderGeometry(photo, pts, cam, o);
      const cv::Mat label = reference::unrollLabel(photo, cam, g);
      if (const fs::path dir = fs::path(label_image).parent_path(); !dir.empty()) tool::makeOutputDir(dir.string());
      tool::writeImage(label_image, label);
      reference::writeCylinderDefinition(output, name, label_image, g);
      tool::writeImage(check, reference::drawCylinder(photo, g, cam));
      std::cerr << "make_reference: " << output << " (label " << label_image << ", " << g.label.image_width << "x"
                << g.label.image_height << " px, " << g.label.width_m << " x " << g.label.height_m
                << " m, axis at " << g.axis_distance_m << " m, edges "
                << (g.snapped[0] ? "snapped" : "as clicked") << " / " << (g.snapped[1] ? "snapped" : "as clicked")
                << "); check " << check << "\n";
      return 0;
    }
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
