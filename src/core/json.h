#pragma once
// JSON for the value types every tool writes (detect_object lines, search logs, recordings): one
// encoding of a pose, so every reader parses the same thing. Keys keep their insertion order
// (nlohmann::ordered_json): documented field orders are part of the contract.
#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <string>

#include "core/pose.h"

namespace refgrasp {

using Json = nlohmann::ordered_json;

enum class PoseJsonForm {
  kMatrix,          ///< "R": 9 numbers, row-major; "t": [x, y, z], metres
  kRotationVector,  ///< "t": [x, y, z], metres; "rotation_vector": axis * angle, radians
};

/// Writes the pose aMb's fields into *j; keys already there keep their place, new ones go last.
void putPose(Json* j, const Pose& aMb, PoseJsonForm form = PoseJsonForm::kMatrix);
/// The pose alone, e.g. {"R":[...],"t":[...]}.
Json poseJson(const Pose& aMb, PoseJsonForm form = PoseJsonForm::kMatrix);
/// Reads either form from the object j ("R" is preferred when both are there). R must be a
/// rotation (orthonormal to 1e-6, det +1). Throws ConfigError("<source>", "<field>", "<problem>").
Pose poseFromJson(const Json& j, const std::string& source = "json");

/// A 3x3 matrix as 9 numbers, row-major.
Json matrixJson(const Eigen::Matrix3d& M);
/// Throws ConfigError(source, field, ...) unless j is 9 finite numbers.
Eigen::Matrix3d matrixFromJson(const Json& j, const std::string& source, const std::string& field);

}  // namespace refgrasp
