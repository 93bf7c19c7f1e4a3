#pragma once
// Writing object definition YAML (the pieces every make_reference mode shares): numbers, quoted
// strings and paths as the detector's loader reads them, and the file opened, finished and read
// back by that loader.
#include <Eigen/Core>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <string>

#include "core/camera.h"
#include "core/pose.h"

namespace refgrasp::reference::detail {

[[noreturn]] void refuse(const std::string& what);  ///< throws std::invalid_argument(what)

/// "<what>: ... is outside the WxH image" unless p is finite and within the image's pixel area.
void checkInImage(const Eigen::Vector2d& p, const Intrinsics& camera, const std::string& what);

std::string yamlNumber(double v);                 ///< %.10g
std::string yamlQuoted(const std::string& s);     ///< a YAML double-quoted scalar, one line
/// `path` relative to the folder `dir` (absolute when there is no relative form).
std::string relativeTo(const std::string& path, const std::filesystem::path& dir);
/// "{translation: [x, y, z], rotation_vector: [a, b, c]}" (metres, radians).
std::string yamlPose(const Pose& pose);

/// Opens the YAML for writing (its folder created); OutputError when it cannot.
std::ofstream openDefinition(const std::string& yaml_path);
/// Flushes and closes it (OutputError on a failed write), then reads it back with the detector's
/// loader, so that a file the detector would refuse is an error here.
void finishDefinition(std::ofstream& out, const std::string& yaml_path);

/// A BGR copy of the photo to draw a check picture on, and the line thickness for its size.
cv::Mat checkCanvas(const cv::Mat& photo);
int checkThickness(const cv::Mat& canvas);

}  // namespace refgrasp::reference::detail
