#include "core/json.h"

#include <Eigen/Geometry>
#include <cmath>
#include <vector>

#include "core/error.h"

namespace refgrasp {
namespace {

Json vec3(const Eigen::Vector3d& v) { return Json::array({v.x(), v.y(), v.z()}); }

std::vector<double> numbers(const Json& j, size_t n, const std::string& source, const std::string& field) {
  if (!j.is_array() || j.size() != n)
    throw ConfigError(source, field, "expected " + std::to_string(n) + " numbers");
  std::vector<double> v;
  for (const Json& x : j) {
    if (!x.is_number()) throw ConfigError(source, field, "expected " + std::to_string(n) + " numbers");
    v.push_back(x.get<double>());
    if (!std::isfinite(v.back())) throw ConfigError(source, field, "must be finite");
  }
  return v;
}

}  // namespace

Json matrixJson(const Eigen::Matrix3d& M) {
  Json a = Json::array();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) a.push_back(M(r, c));
  return a;
}

Eigen::Matrix3d matrixFromJson(const Json& j, const std::string& source, const std::string& field) {
  const std::vector<double> v = numbers(j, 9, source, field);
  Eigen::Matrix3d M;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) M(r, c) = v[3 * r + c];
  return M;
}

void putPose(Json* j, const Pose& p, PoseJsonForm form) {
  if (form == PoseJsonForm::kMatrix) {
    (*j)["R"] = matrixJson(p.R);
    (*j)["t"] = vec3(p.t);
  } else {
    (*j)["t"] = vec3(p.t);
    (*j)["rotation_vector"] = vec3(p.rotationVector());
  }
}

Json poseJson(const Pose& p, PoseJsonForm form) {
  Json j = Json::object();
  putPose(&j, p, form);
  return j;
}

Pose poseFromJson(const Json& j, const std::string& source) {
  if (!j.is_object()) throw ConfigError(source, "expected an object with R (or rotation_vector) and t");
  if (!j.contains("t")) throw ConfigError(source, "t", "missing");
  const std::vector<double> t = numbers(j["t"], 3, source, "t");
  const Eigen::Vector3d tv(t[0], t[1], t[2]);
  if (j.contains("R")) {
    const Eigen::Matrix3d R = matrixFromJson(j["R"], source, "R");
    if ((R * R.transpose() - Eigen::Matrix3d::Identity()).norm() > 1e-6 || R.determinant() < 0)
      throw ConfigError(source, "R", "not a rotation matrix");
    return Pose(R, tv);
  }
  if (!j.contains("rotation_vector")) throw ConfigError(source, "R", "missing (or rotation_vector)");
  const std::vector<double> r = numbers(j["rotation_vector"], 3, source, "rotation_vector");
  return Pose::fromRotationVector(Eigen::Vector3d(r[0], r[1], r[2]), tv);
}

}  // namespace refgrasp
