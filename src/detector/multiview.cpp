#include "detector/multiview.h"

#include <algorithm>
#include <cmath>
#include <optional>

namespace refgrasp::detector {

namespace {

// A view's pose, as points: its reprojection RMS may be ~0 (a dense alignment's grid fits
// exactly), but no alignment is better than a tenth of a pixel.
constexpr double kMinSigmaPx = 0.1;

// A planar view faces the camera at cMv when the camera centre lies on the side of the pattern
// plane that the reference camera saw it from.
bool planeFacesCamera(const ObjectModel& view, const Pose& cMv) {
  const auto side = [&](const Pose& cMo) {
    return view.plane_normal_o.dot(cMo.inverse().t) - view.plane_offset_m;
  };
  return side(*view.reference_cMo) * side(cMv) > 0;
}

// The members of one fused instance: indices into the instances, best (most inliers) first.
struct Group {
  std::vector<int> members;
  bool holds(const std::vector<ViewInstance>& all, int view) const {
    return std::any_of(members.begin(), members.end(), [&](int m) { return all[m].view == view; });
  }
};

}  // namespace

void MultiViewOptions::check() const {
  auto bad = [](const char* field, const char* problem) {
    throw std::invalid_argument(std::string("MultiViewOptions.") + field + ": " + problem);
  };
  if (!(std::isfinite(max_gap_m) && max_gap_m >= 0)) bad("max_gap_m", "must be >= 0");
  if (!(std::isfinite(max_gap_fraction) && max_gap_fraction >= 0 && max_gap_fraction <= 1))
    bad("max_gap_fraction", "must be in [0, 1]");
  if (!(std::isfinite(max_rotation_gap_rad) && max_rotation_gap_rad >= 0 && max_rotation_gap_rad <= M_PI))
    bad("max_rotation_gap_rad", "must be in [0, pi]");
}

ViewCorrespondences viewCorrespondences(const RegisteredObject& view, const Pose& oMv, const Detection& instance,
                                        const Intrinsics& camera, const DetectorOptions& detector) {
  ViewCorrespondences out;
  const ObjectModel& model = view.model;
  if (!instance.cMo) return out;
  const Pose& cMv = *instance.cMo;
  const bool on_cylinder = model.isCylinder() && detector.pose == PoseMethod::kRefined;
  if (!on_cylinder && !(model.target && model.reference_cMo && planeFacesCamera(model, cMv))) return out;
  const Eigen::Matrix3d K = camera.K();
  const double sigma = std::max(kMinSigmaPx, instance.pose_rms_px);
  const int n = detector.dense.pose_grid;
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      const double a = (c + 0.5) / n, b = (r + 0.5) / n;  // cell centres across the pattern
      std::optional<Eigen::Vector3d> X;
      if (on_cylinder) {
        const Eigen::Vector2d uv(a * model.cylinder->image_width - 0.5, b * model.cylinder->image_height - 0.5);
        if (model.cylinder->facesCamera(uv.x(), uv.y(), cMv)) X = model.cylinder->point(uv);
      } else {
        const auto& q = model.target->corners_o;  // TL, TR, BR, BL
        X = (1 - b) * ((1 - a) * q[0] + a * q[1]) + b * ((1 - a) * q[3] + a * q[2]);
      }
      if (!X) continue;
      const Eigen::Vector3d Xc = cMv * *X;
      if (!(Xc.z() > 1e-6)) continue;
      out.points_o.push_back(oMv * *X);
      out.points_px.push_back(projectPinhole(K, Xc));
      out.sigma_px.push_back(sigma);
    }
  }
  return out;
}

bool posesAgree(const Pose& a, const Pose& b, const MultiViewOptions& opt) {
  const double distance = std::min(a.t.norm(), b.t.norm());
  return (a.t - b.t).norm() <= opt.max_gap_m + opt.max_gap_fraction * distance &&
         rotationError(a, b) <= opt.max_rotation_gap_rad;
}

std::vector<Detection> fuseViews(std::vector<ViewInstance> instances, const std::vector<std::string>& names,
                                 const Eigen::Matrix3d& K, const PoseOptions& pose_options,
                                 const MultiViewOptions& opt) {
  std::stable_sort(instances.begin(), instances.end(), [](const ViewInstance& a, const ViewInstance& b) {
    return a.detection.inliers > b.detection.inliers;
  });
  std::vector<Group> groups;
  for (int i = 0; i < static_cast<int>(instances.size()); ++i) {
    auto joins = [&](const Group& g) {
      return !g.holds(instances, instances[i].view) && posesAgree(instances[g.members[0]].cMo, instances[i].cMo, opt);
    };
    const auto g = std::find_if(groups.begin(), groups.end(), joins);
    if (g != groups.end()) g->members.push_back(i);
    else groups.push_back({{i}});
  }

  std::vector<Detection> out;
  for (const Group& g : groups) {
    const ViewInstance& seed = instances[g.members[0]];
    Detection d = seed.detection;  // H, corners and scores of the member with the most inliers
    d.found = true;
    d.cMo = seed.cMo;
    d.view = names[static_cast<size_t>(seed.view)];
    d.views.clear();
    d.inliers = 0;
    ViewCorrespondences all;
    for (int m : g.members) {
      const ViewInstance& v = instances[m];
      d.views.push_back(names[static_cast<size_t>(v.view)]);
      d.inliers += v.detection.inliers;
      all.points_o.insert(all.points_o.end(), v.pairs.points_o.begin(), v.pairs.points_o.end());
      all.points_px.insert(all.points_px.end(), v.pairs.points_px.begin(), v.pairs.points_px.end());
      all.sigma_px.insert(all.sigma_px.end(), v.pairs.sigma_px.begin(), v.pairs.sigma_px.end());
    }
    // Two views or more: the joint pose over every member's pairs (at least 6 to fix 6 DOF), kept
    // when it stays with the seed (a joint fit pulled away by bad pairs is not an improvement).
    if (g.members.size() >= 2 && all.size() >= 6) {
      const PoseResult joint = refinePoseLM(all.points_o, all.points_px, K, seed.cMo,
                                            pose_options.refined_lm_iterations, pose_options.huber_px, all.sigma_px);
      if (joint.ok && joint.cMo.isFinite() && posesAgree(joint.cMo, seed.cMo, opt)) {
        d.cMo = joint.cMo;
        d.pose_rms_px = joint.rms_px;
      }
    }
    d.instance = static_cast<int>(out.size());
    out.push_back(std::move(d));
  }
  return out;
}

}  // namespace refgrasp::detector
