#include "servo/target_estimator.h"

#include <cmath>
#include <stdexcept>

#include "core/error.h"
#include "servo/surface_model.h"

namespace refgrasp::servo {

const char* toString(TargetStatus s) {
  switch (s) {
    case TargetStatus::kNone: return "none";
    case TargetStatus::kLost: return "lost";
    case TargetStatus::kUnconfirmed: return "unconfirmed";
    case TargetStatus::kConfirmed: return "confirmed";
  }
  return "?";
}

void OracleOptions::check() const {
  refgrasp::check(std::isfinite(border_px) && border_px >= 0, "OracleOptions.border_px",
                  "must be >= 0");
  refgrasp::check(std::isfinite(min_side_px) && min_side_px > 0, "OracleOptions.min_side_px",
                  "must be > 0");
  refgrasp::check(std::isfinite(max_view_angle_rad) && max_view_angle_rad > 0 &&
                      max_view_angle_rad < M_PI / 2,
                  "OracleOptions.max_view_angle_rad", "must be in (0, pi/2)");
}

OracleEstimator::OracleEstimator(const detector::ObjectModel& object, const OracleOptions& o)
    : name_(object.name), opt_(o) {
  opt_.check();
  quads_o_ = patternQuads(object);
  if (!object.hasPose() || quads_o_.empty())
    throw std::invalid_argument("OracleEstimator: object '" + object.name +
                                "' has no reference pose (2D only)");
}

bool OracleEstimator::visible(const Pose& cMo, const Intrinsics& cam,
                              std::array<Eigen::Vector2d, 4>* corners) const {
  // Several views: the one seen most squarely.
  const std::array<Eigen::Vector3d, 4> corners_o = *facingQuad(quads_o_, cMo);
  const Eigen::Vector3d normal_o =
      (corners_o[1] - corners_o[0]).cross(corners_o[3] - corners_o[0]).normalized();
  std::array<Eigen::Vector2d, 4> px;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < 4; ++i) {
    const Eigen::Vector3d c = cMo * corners_o[i];
    if (c.z() < 0.05) return false;
    px[i] = cam.project(c);
    centre += 0.25 * c;
    if (!px[i].allFinite() || px[i].x() < opt_.border_px || px[i].y() < opt_.border_px ||
        px[i].x() > cam.width - 1 - opt_.border_px || px[i].y() > cam.height - 1 - opt_.border_px)
      return false;
  }
  // The pattern is seen from its front (the planar convention: z_o points away from a viewer of
  // the texture, along the line of sight) and not too obliquely.
  const Eigen::Vector3d n = cMo.R * normal_o;
  const double cos_view = n.dot(centre.normalized());
  if (cos_view < std::cos(opt_.max_view_angle_rad)) return false;
  for (size_t i = 0; i < 4; ++i)
    if ((px[i] - px[(i + 1) % 4]).norm() < opt_.min_side_px) return false;
  if (corners) *corners = px;
  return true;
}

TargetObservation OracleEstimator::observe(const robot::StereoFrame& frame, const StereoRig& rig,
                                           const std::optional<Pose>&) {
  TargetObservation o;
  o.status = TargetStatus::kLost;
  o.source = "truth";
  for (const robot::ObjectTruth& t : frame.truth) {
    if (t.object != name_) continue;
    std::array<Eigen::Vector2d, 4> corners;
    if (!visible(t.cMo, rig.left, &corners)) return o;
    o.status = TargetStatus::kConfirmed;
    o.cMo = t.cMo;
    o.corners = corners;
    return o;
  }
  o.error = "frame " + std::to_string(frame.index) + " carries no ground truth for '" + name_ + "'";
  return o;
}

}  // namespace refgrasp::servo
