#include "grasp/grasp_map.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace refgrasp::grasp_app {

namespace {

// BGR colours of the map.
const cv::Scalar kOutside(45, 45, 45), kFloor(226, 226, 226), kGrid(205, 205, 205), kWalls(95, 95, 95),
    kTable(140, 185, 215), kTableEdge(70, 110, 140), kItem(200, 130, 70), kTarget(40, 40, 225),
    kTargetEdge(0, 230, 255), kPath(20, 150, 20), kLookFill(0, 190, 255), kLookEdge(0, 120, 200),
    kRobot(190, 160, 120), kRobotEdge(60, 40, 20);

Eigen::Vector2d rotate(double theta, const Eigen::Vector2d& p) {
  const double c = std::cos(theta), s = std::sin(theta);
  return {c * p.x() - s * p.y(), s * p.x() + c * p.y()};
}

std::vector<Eigen::Vector2d> hull(const std::vector<Eigen::Vector2d>& pts) {
  std::vector<cv::Point2f> in, out;
  for (const auto& p : pts) in.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  cv::convexHull(in, out);
  std::vector<Eigen::Vector2d> h;
  for (const auto& q : out) h.emplace_back(q.x, q.y);
  return h;
}

// Blends `over` into img where mask is set: img = alpha over + (1 - alpha) img.
void blendMasked(cv::Mat& img, const cv::Mat& over, const cv::Mat& mask, double alpha) {
  cv::Mat mixed;
  cv::addWeighted(over, alpha, img, 1 - alpha, 0, mixed);
  mixed.copyTo(img, mask);
}

}  // namespace

std::vector<std::vector<Eigen::Vector2d>> footprints(const sim::SimObject& o) {
  std::vector<std::vector<Eigen::Vector2d>> out;
  for (const sim::Solid& sd : o.solids) {
    const Pose wMs = o.wMo * sd.oMs;
    std::vector<Eigen::Vector2d> pts;
    if (sd.cylinder) {
      // Both end discs (axis z_s, radius half_m.x, half height half_m.z), 24 points each.
      for (const double z : {-sd.half_m.z(), sd.half_m.z()})
        for (int k = 0; k < 24; ++k) {
          const double a = 2 * M_PI * k / 24;
          pts.push_back((wMs * Eigen::Vector3d(sd.half_m.x() * std::cos(a), sd.half_m.x() * std::sin(a), z)).head<2>());
        }
    } else {
      for (int i = 0; i < 8; ++i)
        pts.push_back((wMs * Eigen::Vector3d((i & 1) ? sd.half_m.x() : -sd.half_m.x(),
                                             (i & 2) ? sd.half_m.y() : -sd.half_m.y(),
                                             (i & 4) ? sd.half_m.z() : -sd.half_m.z()))
                          .head<2>());
    }
    out.push_back(hull(pts));
  }
  return out;
}

TopDownMap::TopDownMap(const sim::World& world, const robot::PlanarPose& odom_in_world, cv::Size size)
    : odom_in_world_(odom_in_world), size_(size) {
  // The area shown: the floor, else every object's footprint with 1 m around it.
  Eigen::Vector2d lo(1e30, 1e30), hi(-1e30, -1e30);
  for (const sim::SimObject& o : world.objects)
    if (o.kind == sim::ObjectKind::kFloor && !o.faces.empty()) {
      const Eigen::Vector2d half(o.faces.front().width_m / 2, o.faces.front().height_m / 2);
      lo = lo.cwiseMin(o.wMo.t.head<2>() - half);
      hi = hi.cwiseMax(o.wMo.t.head<2>() + half);
    }
  if (lo.x() > hi.x()) {
    for (const sim::SimObject& o : world.objects)
      for (const auto& fp : footprints(o))
        for (const auto& p : fp) {
          lo = lo.cwiseMin(p - Eigen::Vector2d(1, 1));
          hi = hi.cwiseMax(p + Eigen::Vector2d(1, 1));
        }
  }
  if (lo.x() > hi.x()) lo = Eigen::Vector2d(-3, -3), hi = Eigen::Vector2d(3, 3);  // an empty world
  const Eigen::Vector2d extent = hi - lo + Eigen::Vector2d(0.6, 0.6);
  scale_ = std::min(size.width / extent.x(), size.height / extent.y());
  centre_w_ = 0.5 * (lo + hi);

  fixed_ = cv::Mat(size, CV_8UC3, kOutside);
  const std::vector<Eigen::Vector2d> floor_rect = {lo, {hi.x(), lo.y()}, hi, {lo.x(), hi.y()}};
  cv::fillConvexPoly(fixed_, polygon(floor_rect), kFloor, cv::LINE_AA);
  for (double x = std::ceil(lo.x()); x <= hi.x(); x += 1)
    cv::line(fixed_, pixel({x, lo.y()}), pixel({x, hi.y()}), kGrid, 1);
  for (double y = std::ceil(lo.y()); y <= hi.y(); y += 1)
    cv::line(fixed_, pixel({lo.x(), y}), pixel({hi.x(), y}), kGrid, 1);
  for (const sim::SimObject& o : world.objects) {
    if (o.kind != sim::ObjectKind::kWalls && o.kind != sim::ObjectKind::kTable) continue;
    for (const auto& fp : footprints(o)) {
      const std::vector<cv::Point> poly = polygon(fp);
      cv::fillConvexPoly(fixed_, poly, o.kind == sim::ObjectKind::kWalls ? kWalls : kTable, cv::LINE_AA);
      if (o.kind == sim::ObjectKind::kTable) cv::polylines(fixed_, poly, true, kTableEdge, 1, cv::LINE_AA);
    }
  }
}

cv::Point2d TopDownMap::pixel(const Eigen::Vector2d& p) const {
  return {(size_.width - 1) / 2.0 + (p.x() - centre_w_.x()) * scale_,
          (size_.height - 1) / 2.0 - (p.y() - centre_w_.y()) * scale_};
}

Eigen::Vector2d TopDownMap::odomToWorld(const Eigen::Vector2d& p) const {
  return rotate(odom_in_world_.theta_rad, p) + Eigen::Vector2d(odom_in_world_.x_m, odom_in_world_.y_m);
}

std::vector<cv::Point> TopDownMap::polygon(const std::vector<Eigen::Vector2d>& pts) const {
  std::vector<cv::Point> out;
  for (const auto& p : pts) {
    const cv::Point2d q = pixel(p);
    out.emplace_back(cvRound(q.x), cvRound(q.y));
  }
  return out;
}

cv::Vec3b TopDownMap::heatColour(double fraction) {
  static const cv::Mat lut = [] {
    cv::Mat ramp(1, 256, CV_8U), colours;
    for (int i = 0; i < 256; ++i) ramp.at<uchar>(0, i) = static_cast<uchar>(i);
    cv::applyColorMap(ramp, colours, cv::COLORMAP_INFERNO);
    return colours;
  }();
  const int i = static_cast<int>(std::lround(255 * std::clamp(fraction, 0.0, 1.0)));
  return lut.at<cv::Vec3b>(0, i);
}

double TopDownMap::heatAlpha(double fraction) {
  return kHeatAlpha * (0.15 + 0.85 * std::clamp(fraction, 0.0, 1.0));
}

void TopDownMap::drawBelief(cv::Mat& img, const servo::SearchBelief& b) const {
  if (b.cols <= 0 || b.rows <= 0 || b.p.size() != static_cast<size_t>(b.cols) * static_cast<size_t>(b.rows)) return;
  const float top = *std::max_element(b.p.begin(), b.p.end());
  if (!(top > 0)) return;
  // Each cell's colour and opacity into an overlay, then one blend: img = a over + (1 - a) img.
  cv::Mat over(img.size(), CV_8UC3, cv::Scalar(0, 0, 0)), alpha(img.size(), CV_32F, cv::Scalar(0));
  for (int r = 0; r < b.rows; ++r)
    for (int c = 0; c < b.cols; ++c) {
      const float p = b.p[static_cast<size_t>(r) * static_cast<size_t>(b.cols) + static_cast<size_t>(c)];
      if (!(p > 0)) continue;
      const Eigen::Vector2d c0 = b.origin + Eigen::Vector2d(c * b.cell_m, r * b.cell_m);
      const std::vector<Eigen::Vector2d> cell = {odomToWorld(c0), odomToWorld(c0 + Eigen::Vector2d(b.cell_m, 0)),
                                                 odomToWorld(c0 + Eigen::Vector2d(b.cell_m, b.cell_m)),
                                                 odomToWorld(c0 + Eigen::Vector2d(0, b.cell_m))};
      const std::vector<cv::Point> poly = polygon(cell);
      const cv::Vec3b colour = heatColour(p / top);
      cv::fillConvexPoly(over, poly, cv::Scalar(colour[0], colour[1], colour[2]));
      cv::fillConvexPoly(alpha, poly, cv::Scalar(heatAlpha(p / top)));
    }
  for (int y = 0; y < img.rows; ++y) {
    cv::Vec3b* d = img.ptr<cv::Vec3b>(y);
    const cv::Vec3b* o = over.ptr<cv::Vec3b>(y);
    const float* a = alpha.ptr<float>(y);
    for (int x = 0; x < img.cols; ++x)
      if (a[x] > 0)
        for (int i = 0; i < 3; ++i) d[x][i] = cv::saturate_cast<uchar>(a[x] * o[x][i] + (1 - a[x]) * d[x][i]);
  }
}

void TopDownMap::drawLooks(cv::Mat& img, const std::vector<servo::SearchLook>& looks) const {
  if (looks.empty()) return;
  cv::Mat over = img.clone(), mask(img.size(), CV_8U, cv::Scalar(0));
  std::vector<std::vector<cv::Point>> wedges;
  for (const servo::SearchLook& l : looks) {
    // The wedge: the camera's floor position and an arc at range_m across the field of view,
    // turned from the odometry frame into the world.
    std::vector<Eigen::Vector2d> pts = {odomToWorld(l.camera_w)};
    constexpr int kArc = 16;
    for (int k = 0; k <= kArc; ++k) {
      const double a = l.bearing_rad - l.half_fov_rad + 2 * l.half_fov_rad * k / kArc;
      pts.push_back(odomToWorld(l.camera_w + l.range_m * Eigen::Vector2d(std::cos(a), std::sin(a))));
    }
    wedges.push_back(polygon(pts));
    cv::fillPoly(over, std::vector<std::vector<cv::Point>>{wedges.back()}, kLookFill);
    cv::fillPoly(mask, std::vector<std::vector<cv::Point>>{wedges.back()}, cv::Scalar(255));
  }
  blendMasked(img, over, mask, 0.2);
  for (size_t i = 0; i < wedges.size(); ++i)
    cv::polylines(img, wedges[i], true, kLookEdge, i + 1 == wedges.size() ? 2 : 1, cv::LINE_AA);
  const servo::SearchLook& last = looks.back();
  const cv::Point2d at = pixel(odomToWorld(last.camera_w));
  cv::putText(img, "look " + std::to_string(last.index), cv::Point(cvRound(at.x) + 6, cvRound(at.y) - 6),
              cv::FONT_HERSHEY_SIMPLEX, 0.45, kLookEdge, 1, cv::LINE_AA);
}

cv::Mat TopDownMap::draw(const sim::World& world, const MapFrame& f) const {
  cv::Mat img = fixed_.clone();
  if (f.belief) drawBelief(img, *f.belief);
  for (const sim::SimObject& o : world.objects) {
    if (o.kind != sim::ObjectKind::kItem) continue;
    for (const auto& fp : footprints(o)) {
      const std::vector<cv::Point> poly = polygon(fp);
      cv::fillConvexPoly(img, poly, o.is_target ? kTarget : kItem, cv::LINE_AA);
      if (o.is_target) cv::polylines(img, poly, true, kTargetEdge, 2, cv::LINE_AA);
    }
    if (o.is_target) {
      // A ring round it: a target a few centimetres deep is a few pixels on the map.
      const cv::Point2d at = pixel(o.wMo.t.head<2>());
      cv::circle(img, cv::Point(cvRound(at.x), cvRound(at.y)), 10, kTargetEdge, 2, cv::LINE_AA);
      cv::putText(img, "target", cv::Point(cvRound(at.x) + 14, cvRound(at.y) + 4), cv::FONT_HERSHEY_SIMPLEX, 0.45,
                  kTarget, 1, cv::LINE_AA);
    }
  }
  drawLooks(img, f.looks);
  if (f.path_w.size() >= 2) cv::polylines(img, polygon(f.path_w), false, kPath, 2, cv::LINE_AA);
  const cv::Point2d c = pixel({f.base_w.x_m, f.base_w.y_m});
  const cv::Point centre(cvRound(c.x), cvRound(c.y));
  const int radius = std::max(3, static_cast<int>(std::lround(f.base_radius_m * scale_)));
  cv::circle(img, centre, radius, kRobot, cv::FILLED, cv::LINE_AA);
  cv::circle(img, centre, radius, kRobotEdge, 1, cv::LINE_AA);
  const cv::Point2d nose = pixel(Eigen::Vector2d(f.base_w.x_m, f.base_w.y_m) +
                                 1.6 * f.base_radius_m * Eigen::Vector2d(std::cos(f.base_w.theta_rad),
                                                                         std::sin(f.base_w.theta_rad)));
  cv::line(img, centre, cv::Point(cvRound(nose.x), cvRound(nose.y)), kRobotEdge, 2, cv::LINE_AA);
  // Scale bar: 1 m.
  const int bar = static_cast<int>(std::lround(scale_));
  cv::line(img, {10, size_.height - 12}, {10 + bar, size_.height - 12}, cv::Scalar(255, 255, 255), 3);
  cv::putText(img, "1 m", {14 + bar, size_.height - 8}, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(255, 255, 255), 1,
              cv::LINE_AA);
  const char* label = "map: path, looks, belief";
  cv::putText(img, label, {8, 20}, cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
  cv::putText(img, label, {8, 20}, cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  return img;
}

}  // namespace refgrasp::grasp_app
