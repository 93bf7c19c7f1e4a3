#include "detector/multiview.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

namespace refgrasp::detector {

namespace {

// A reference feature's point in the view's frame, and whether it faces a camera at cMv. A
// cylinder's points lie on its surface when its pose is the cylinder's own (refined method); with
// the paper's method the view is its flat label, like a planar view.
std::optional<Eigen::Vector3d> viewPoint(const ObjectModel& view, const Eigen::Vector2d& ref_px, const Pose& cMv,
                                         bool on_cylinder) {
  if (on_cylinder) {
    if (!view.cylinder->facesCamera(ref_px.x(), ref_px.y(), cMv)) return std::nullopt;
    return view.cylinder->point(ref_px);
  }
  return view.target->backProject(ref_px);
}

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
  if (!(std::isfinite(guided_radius_px) && guided_radius_px > 0 && guided_radius_px <= 100))
    bad("guided_radius_px", "must be in (0, 100]");
}

ViewCorrespondences viewCorrespondences(const RegisteredObject& view, const Pose& oMv, const Pose& cMv,
                                        const Features& scene, const GridIndex& grid, const Intrinsics& camera,
                                        const MultiViewOptions& opt, const DetectorOptions& detector) {
  ViewCorrespondences out;
  const ObjectModel& model = view.model;
  const bool on_cylinder = model.isCylinder() && detector.pose == PoseMethod::kRefined;
  if (!on_cylinder && !(model.target && model.reference_cMo && planeFacesCamera(model, cMv))) return out;
  const double max_descriptor_distance = detector.match.max_descriptor_distance;
  const double sigma_per_size = detector.pose_options.keypoint_sigma_per_size;
  const Features& ref = view.index.features;
  const Eigen::Matrix3d K = camera.K();
  // Per scene feature: the reference feature it is paired with and their descriptor distance.
  std::vector<int> pair_of(static_cast<size_t>(scene.size()), -1);
  std::vector<float> distance_of(static_cast<size_t>(scene.size()), std::numeric_limits<float>::max());
  std::vector<std::optional<Eigen::Vector3d>> points(static_cast<size_t>(ref.size()));
  std::vector<int> near;
  for (int i = 0; i < ref.size(); ++i) {
    const cv::Point2f& p = ref.keypoints[static_cast<size_t>(i)].pt;
    points[static_cast<size_t>(i)] = viewPoint(model, Eigen::Vector2d(p.x, p.y), cMv, on_cylinder);
    if (!points[static_cast<size_t>(i)]) continue;
    const Eigen::Vector3d Xc = cMv * *points[static_cast<size_t>(i)];
    if (!(Xc.z() > 1e-6)) continue;
    grid.radiusSearch(projectPinhole(K, Xc), opt.guided_radius_px, &near);
    int best = -1;
    float best_distance = static_cast<float>(max_descriptor_distance);
    for (int s : near) {
      const float d = static_cast<float>(cv::norm(ref.descriptors.row(i), scene.descriptors.row(s), cv::NORM_L2));
      if (d <= best_distance) {
        best = s;
        best_distance = d;
      }
    }
    if (best < 0 || !(best_distance < distance_of[static_cast<size_t>(best)])) continue;
    pair_of[static_cast<size_t>(best)] = i;
    distance_of[static_cast<size_t>(best)] = best_distance;
  }
  for (int s = 0; s < scene.size(); ++s) {
    const int i = pair_of[static_cast<size_t>(s)];
    if (i < 0) continue;
    const cv::KeyPoint& k = scene.keypoints[static_cast<size_t>(s)];
    out.points_o.push_back(oMv * *points[static_cast<size_t>(i)]);
    out.points_px.emplace_back(k.pt.x, k.pt.y);
    out.sigma_px.push_back(sigma_per_size > 0 ? std::max(0.1, sigma_per_size * k.size) : 1.0);
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
