#pragma once
// A several-view object definition (docs/formats.md "Object definition", detector/object.h) of a
// box, from one planar definition per photographed face and the box's dimensions.
//
// The box's object frame is the simulator's box convention (robot/sim/scenario.h): origin at the
// front face's centre, x along the front texture's columns, y along its rows (down on an upright
// box), z into the box; the box spans x in [-W/2, W/2], y in [-H/2, H/2], z in [0, D] for a size
// (W, H, D) metres. Each face's own frame (the frame of its planar definition) must sit at that
// face's centre with z into the box, its texture rows running
//   front, back, left, right: along +y (down);   top, bottom: along +z (from the front to the back);
// and x = y cross z. That is the frame make_reference --corners gives when the four corners are
// the face's own corners, TL, TR, BR, BL in that orientation, and --size its two sides; it is the
// frame of sim::boxFaces' faces for the rows above.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/pose.h"

namespace refgrasp::reference {

/// The face names, in the order they are written: front, back, left, right, top, bottom.
const std::vector<std::string>& boxFaceNames();

/// oMv: the frame of face `face` in the box's object frame (metres, radians). Throws
/// std::invalid_argument "--face: unknown face '...'" for another name.
Pose boxFacePose(const std::string& face, const Eigen::Vector3d& size_m);
/// The face's width (along its x) and height (along its y), metres.
Eigen::Vector2d boxFaceSize(const std::string& face, const Eigen::Vector3d& size_m);

struct BoxFaceDefinition {
  std::string face;        ///< front, back, left, right, top or bottom
  std::string definition;  ///< path of the face's planar definition (with reference_pose)
};

/// Checks the faces (each known, at most once, a planar definition with a reference pose whose
/// pattern lies on its z = 0 plane within the face's rectangle, 2 % + 2 mm slack), writes the
/// several-view definition (definition paths relative to it, faces in boxFaceNames() order) and
/// reads it back with the detector's loader. Throws std::invalid_argument "--box-size: ...",
/// "--face NAME=FILE: ..." (one line) for bad input, ConfigError / OutputError from the files.
void writeBoxDefinition(const std::string& yaml_path, const std::string& name, const Eigen::Vector3d& size_m,
                        const std::vector<BoxFaceDefinition>& faces);

}  // namespace refgrasp::reference
