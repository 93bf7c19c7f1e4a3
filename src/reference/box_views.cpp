#include "reference/box_views.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/error.h"
#include "detector/object.h"
#include "reference/definition_text.h"

namespace refgrasp::reference {

using detail::refuse;
using detail::yamlNumber;

namespace {

struct FaceAxes {
  const char* name;
  Eigen::Vector3d outward;  ///< the face's outward normal, box frame
  Eigen::Vector3d rows;     ///< the direction of its texture rows, box frame
};

const FaceAxes kFaces[] = {
    {"front", -Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitY()},
    {"back", Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitY()},
    {"left", -Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY()},
    {"right", Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY()},
    {"top", -Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ()},
    {"bottom", Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ()},
};

const FaceAxes& axesOf(const std::string& face) {
  for (const FaceAxes& f : kFaces)
    if (face == f.name) return f;
  refuse("--face: unknown face '" + face + "' (front, back, left, right, top, bottom)");
}

std::string sizeText(const Eigen::Vector2d& s) { return yamlNumber(s.x()) + " x " + yamlNumber(s.y()) + " m"; }

// The face's definition must be planar with a reference pose, its pattern within the face.
void checkFace(const BoxFaceDefinition& f, const Eigen::Vector3d& size) {
  const std::string what = "--face " + f.face + "=" + f.definition;
  const detector::ObjectModel m = detector::loadObjectDefinition(f.definition);
  if (m.isMultiView() || m.isCylinder() || !m.has3d())
    refuse(what + ": not a planar definition with reference_pose (make one with --corners)");
  if (!m.pattern_region_exact) return;  // the region only bounds the pattern: nothing to compare
  const Eigen::Vector2d half = 0.5 * boxFaceSize(f.face, size);
  const double slack = 0.002;
  for (const Eigen::Vector3d& X : m.target->corners_o)
    if (std::abs(X.x()) > 1.02 * half.x() + slack || std::abs(X.y()) > 1.02 * half.y() + slack ||
        std::abs(X.z()) > slack)
      refuse(what + ": its pattern reaches (" + yamlNumber(X.x()) + ", " + yamlNumber(X.y()) + ", " +
             yamlNumber(X.z()) + ") m in its frame, off the box's " + f.face + " face (" +
             sizeText(2 * half) + ", centred): check --box-size and the face's frame");
}

}  // namespace

const std::vector<std::string>& boxFaceNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const FaceAxes& f : kFaces) n.push_back(f.name);
    return n;
  }();
  return names;
}

Pose boxFacePose(const std::string& face, const Eigen::Vector3d& size) {
  const FaceAxes& f = axesOf(face);
  const Eigen::Vector3d z = -f.outward, y = f.rows, x = y.cross(z);
  Eigen::Matrix3d R;
  R << x, y, z;
  const Eigen::Vector3d centre(0, 0, size.z() / 2);
  return Pose(R, centre + 0.5 * std::abs(f.outward.dot(size)) * f.outward);
}

Eigen::Vector2d boxFaceSize(const std::string& face, const Eigen::Vector3d& size) {
  const Pose p = boxFacePose(face, size);
  return Eigen::Vector2d(std::abs(p.R.col(0).dot(size)), std::abs(p.R.col(1).dot(size)));
}

void writeBoxDefinition(const std::string& yaml_path, const std::string& name, const Eigen::Vector3d& size,
                        const std::vector<BoxFaceDefinition>& faces) {
  if (!(size.allFinite() && size.minCoeff() > 0)) refuse("--box-size: W,H,D must be positive (metres)");
  if (faces.empty()) refuse("--face: give at least one face (--face front=FRONT.yaml)");
  std::vector<BoxFaceDefinition> ordered;
  for (const std::string& face : boxFaceNames())
    for (const BoxFaceDefinition& f : faces)
      if (f.face == face) {
        if (!ordered.empty() && ordered.back().face == face) refuse("--face: " + face + " is given twice");
        ordered.push_back(f);
      }
  for (const BoxFaceDefinition& f : faces) axesOf(f.face);  // an unknown name
  for (const BoxFaceDefinition& f : ordered) checkFace(f, size);
  const std::filesystem::path dir = std::filesystem::path(yaml_path).parent_path();
  std::ofstream out = detail::openDefinition(yaml_path);
  out << "# Object definition (docs/formats.md \"Object definition\") made by make_reference --views: a box of\n"
      << "# " << yamlNumber(size.x()) << " x " << yamlNumber(size.y()) << " x " << yamlNumber(size.z())
      << " m (W x H x D). Object frame: origin at the front face's centre, x along its columns,\n"
      << "# y along its rows, z into the box; each view's frame at its face's centre (docs/tools/make_reference.md).\n"
      << "name: " << detail::yamlQuoted(name) << "\n"
      << "views:\n";
  for (const BoxFaceDefinition& f : ordered)
    out << "  - definition: " << detail::yamlQuoted(detail::relativeTo(f.definition, dir)) << "   # " << f.face
        << " face, " << sizeText(boxFaceSize(f.face, size)) << "\n"
        << "    oMv: " << detail::yamlPose(boxFacePose(f.face, size)) << "\n";
  detail::finishDefinition(out, yaml_path);
}

}  // namespace refgrasp::reference
