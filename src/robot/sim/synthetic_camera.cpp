#include "robot/sim/synthetic_camera.h"

#include <cmath>
#include <exception>
#include <limits>
#include <thread>

#include "core/error.h"

namespace refgrasp::sim {

std::vector<TexturedPlane> worldPlanes(const World& world, const Pose& wMc) {
  const Pose cMw = wMc.inverse();
  std::vector<TexturedPlane> planes;
  for (const SimObject& o : world.objects) {
    const Pose cMo = cMw * o.wMo;
    for (const TexturedPlane& f : o.faces) planes.push_back({f.texture, f.width_m, f.height_m, cMo * f.cMp});
  }
  return planes;
}

std::vector<TexturedCylinder> worldCylinders(const World& world, const Pose& wMc) {
  const Pose cMw = wMc.inverse();
  std::vector<TexturedCylinder> cylinders;
  for (const SimObject& o : world.objects) {
    const Pose cMo = cMw * o.wMo;
    for (TexturedCylinder c : o.cylinders) {
      c.cMo = cMo * c.cMo;
      cylinders.push_back(std::move(c));
    }
  }
  return cylinders;
}

cv::Mat renderWorld(const Intrinsics& cam, const World& world, const Pose& wMc, const RenderOptions& opt) {
  return renderView(cam, worldPlanes(world, wMc), worldCylinders(world, wMc), world.background, opt);
}

namespace {

// cMo of every object; render and poses share it so that their poses are the same bits.
void objectPoses(const World& world, const Pose& wMc, std::vector<Pose>* cMo) {
  const Pose cMw = wMc.inverse();
  cMo->clear();
  for (const SimObject& o : world.objects) cMo->push_back(cMw * o.wMo);
}

}  // namespace

SyntheticStereoCamera::SyntheticStereoCamera(const StereoRig& rig, const Degradation& deg,
                                             uint64_t seed, double exposure_s,
                                             const RenderOptions& render)
    : rig_(rig), deg_(deg), exposure_s_(exposure_s), render_(render), rng_(seed) {
  rig_.left.check();
  rig_.right.check();
  deg_.check();
  render_.check();
  refgrasp::check(std::isfinite(exposure_s) && exposure_s >= 0, "SyntheticStereoCamera.exposure_s",
                  "must be finite and >= 0");
}

cv::Mat SyntheticStereoCamera::renderEye(const Intrinsics& cam, const World& world, const Pose& wMc,
                                         const Twist& cVc, std::mt19937_64& rng,
                                         std::vector<Pose>* cMo) const {
  objectPoses(world, wMc, cMo);
  // Depth for the blur: the nearest object centre in front of the camera and inside the view.
  double depth = std::numeric_limits<double>::infinity();
  for (const Pose& o : *cMo) {
    const Eigen::Vector3d X = o.t;
    if (X.z() <= render_.near_m) continue;
    const Eigen::Vector2d p = cam.project(X);
    if (p.x() >= 0 && p.y() >= 0 && p.x() < cam.width && p.y() < cam.height) depth = std::min(depth, X.z());
  }
  if (!std::isfinite(depth)) depth = 2.0;

  cv::Mat img = renderWorld(cam, world, wMc, render_);

  // Image velocity at the principal point (x = y = 0 of the point-feature interaction matrix):
  // xdot = -vx/Z - wy, ydot = -vy/Z + wx.
  const double du = cam.fx * (-cVc.v.x() / depth - cVc.w.y()) * exposure_s_;
  const double dv = cam.fy * (-cVc.v.y() / depth + cVc.w.x()) * exposure_s_;
  const double bu = du + deg_.motion_blur_px * std::cos(deg_.motion_blur_angle_rad);
  const double bv = dv + deg_.motion_blur_px * std::sin(deg_.motion_blur_angle_rad);
  Degradation d = deg_;
  d.motion_blur_px = std::min(std::hypot(bu, bv), kMaxMotionBlurPx);  // a near object, a fast turn
  d.motion_blur_angle_rad = std::atan2(bv, bu);
  degrade(img, d, rng);
  return img;
}

SyntheticFrame SyntheticStereoCamera::render(const World& world, const Pose& wMl, const Twist& lVl,
                                             Seconds stamp) {
  SyntheticFrame f;
  f.stamp = stamp;
  // The right eye moves with the rig: w_r = rRl w_l, v_r = rRl (v_l + w_l x l_t_r).
  const Pose& lMr = rig_.lMr;
  Twist rVr;
  rVr.w = lMr.R.transpose() * lVl.w;
  rVr.v = lMr.R.transpose() * (lVl.v + lVl.w.cross(lMr.t));
  // One noise stream per eye, drawn in a fixed order: the eyes can render concurrently and the
  // images stay bit-identical for a given seed.
  std::mt19937_64 rng_left(rng_()), rng_right(rng_());
  std::exception_ptr right_error;  // rethrown here: an exception must not escape the thread
  std::thread right([&] {
    try {
      f.right = renderEye(rig_.right, world, wMl * lMr, rVr, rng_right, &f.right_cMo);
    } catch (...) {
      right_error = std::current_exception();
    }
  });
  try {
    f.left = renderEye(rig_.left, world, wMl, lVl, rng_left, &f.left_cMo);
  } catch (...) {
    right.join();
    throw;
  }
  right.join();
  if (right_error) std::rethrow_exception(right_error);
  return f;
}

SyntheticFrame SyntheticStereoCamera::poses(const World& world, const Pose& wMl, Seconds stamp) {
  SyntheticFrame f;
  f.stamp = stamp;
  rng_();  // the two eyes' noise seeds, as render() draws them
  rng_();
  objectPoses(world, wMl * rig_.lMr, &f.right_cMo);
  objectPoses(world, wMl, &f.left_cMo);
  return f;
}

}  // namespace refgrasp::sim
