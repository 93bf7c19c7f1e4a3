#include "reference/cylinder_reference.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "core/error.h"
#include "detector/draw.h"
#include "reference/definition_text.h"

namespace refgrasp::reference {

using detail::refuse;
using detail::yamlNumber;

namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr int kMinLabelPx = 16;      // a smaller unrolled label has too few features to detect
constexpr int kMaxLabelPx = 16384;   // per side
constexpr double kMaxLabelPixels = 1 << 25;   // the project's image limit (core/image_io.h)
constexpr double kMaxSamples = 1 << 26;       // label pixels x sub-samples: the sampling maps' size
constexpr int kMaxSupersampling = 8; // label pixels covering more photo pixels are box-averaged over 8 x 8
constexpr size_t kMaxPeaks = 4;      // edge candidates per sample of a silhouette edge

// Unit viewing ray (camera frame) of a distorted photo pixel.
Eigen::Vector3d rayOf(const Intrinsics& cam, const Eigen::Vector2d& px) {
  const Eigen::Vector2d n = cam.undistortToNormalized(px);
  return Eigen::Vector3d(n.x(), n.y(), 1).normalized();
}

std::string point(const Eigen::Vector2d& p) { return "(" + yamlNumber(p.x()) + ", " + yamlNumber(p.y()) + ")"; }

// The plane through the camera centre and an edge's two points (unit normal).
Eigen::Vector3d edgePlane(const std::array<Eigen::Vector2d, 2>& edge, const Intrinsics& cam, double min_px,
                          const std::string& option) {
  if ((edge[0] - edge[1]).norm() < min_px)
    refuse(option + ": its two points are less than " + yamlNumber(min_px) + " px apart");
  const Eigen::Vector3d n = rayOf(cam, edge[0]).cross(rayOf(cam, edge[1]));
  return n.normalized();
}

double bilinear(const cv::Mat& img, const Eigen::Vector2d& p) {
  const double x = std::clamp(p.x(), 0.0, img.cols - 1.001), y = std::clamp(p.y(), 0.0, img.rows - 1.001);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const double fx = x - x0, fy = y - y0;
  const auto at = [&](int r, int c) { return static_cast<double>(img.at<float>(r, c)); };
  return (1 - fy) * ((1 - fx) * at(y0, x0) + fx * at(y0, x0 + 1)) + fy * ((1 - fx) * at(y0 + 1, x0) + fx * at(y0 + 1, x0 + 1));
}

// Snaps a clicked silhouette edge to the photo. Every 2 px along the clicked segment, the
// intensity steps across it within +-search_px (photo smoothed with sigma 0.5 px; the 4 largest
// local maxima of the step that reach a fifth of the largest, parabolic sub-pixel peaks): where
// the background is as bright as the can, the silhouette is a weaker step than the label's
// texture beside it, but still a step. Lines through two candidates (undistorted, where the
// silhouette is straight) score per quarter of the segment, each sample 1 - (d / 0.5 px)^2 for
// its nearest candidate within 0.5 px (MSAC), and a line scores its weakest quarter: the
// silhouette runs along the whole segment, the label's own edges are short or curved, and a line
// that follows the silhouette over half the segment and something else over the rest loses.
// Among the lines scoring at least 70 % of the best, the outermost (`outward`: away from the
// other edge) wins: a band along the silhouette (a highlight, the label's texture averaged at a
// grazing angle) makes a second straight edge just inside it, as long as the can. The line is
// refitted to its candidates and the plane fitted (least squares) to their rays. Keeps `plane`
// when fewer than a third of the samples (or 8) support any line: no clear edge near the clicks.
bool snapEdge(const cv::Mat& smooth, const std::array<Eigen::Vector2d, 2>& edge, const Eigen::Vector2d& outward,
              const Intrinsics& cam, double search_px, Eigen::Vector3d& plane) {
  const Eigen::Vector2d along = (edge[1] - edge[0]).normalized(), across(-along.y(), along.x());
  const double length = (edge[1] - edge[0]).norm();
  const int n = std::min(200, static_cast<int>(length / 2));
  std::vector<std::vector<Eigen::Vector2d>> found(n + 1);  // per sample: candidates, undistorted px
  std::vector<std::pair<int, Eigen::Vector2d>> all;        // (sample, candidate)
  for (int k = 0; k <= n; ++k) {
    const Eigen::Vector2d q = edge[0] + (length * k / std::max(n, 1)) * along;
    std::vector<double> g;
    for (double s = -search_px - 0.5; s <= search_px + 0.5 + 1e-9; s += 0.5)
      g.push_back(std::abs(bilinear(smooth, q + (s + 0.25) * across) - bilinear(smooth, q + (s - 0.25) * across)));
    const double top = *std::max_element(g.begin(), g.end());
    std::vector<size_t> peaks;
    for (size_t i = 1; i + 1 < g.size(); ++i)
      if (g[i] >= 2 && g[i] >= 0.2 * top && g[i] >= g[i - 1] && g[i] > g[i + 1]) peaks.push_back(i);
    std::sort(peaks.begin(), peaks.end(), [&](size_t a, size_t b) { return g[a] > g[b]; });
    peaks.resize(std::min<size_t>(peaks.size(), kMaxPeaks));
    for (const size_t i : peaks) {
      const double den = g[i - 1] - 2 * g[i] + g[i + 1];
      const double s = -search_px - 0.5 + 0.5 * i + (den < 0 ? 0.25 * (g[i - 1] - g[i + 1]) / den : 0);
      found[k].push_back(cam.undistortPixel(q + s * across));
      all.emplace_back(k, found[k].back());
    }
  }
  // The line through `a` with unit normal `nrm`: its MSAC score, its support and (on) the
  // nearest candidate of each sample that supports it.
  const double tol = 0.5;
  struct Support {
    double score = 0;   // the least of the four quarters' scores
    int count = 0;
  };
  const auto support = [&](const Eigen::Vector2d& a, const Eigen::Vector2d& nrm, std::vector<Eigen::Vector2d>* on) {
    Support sup;
    std::array<double, 4> quarter{0, 0, 0, 0};
    for (size_t k = 0; k < found.size(); ++k) {
      const Eigen::Vector2d* best = nullptr;
      double best_d = tol;
      for (const Eigen::Vector2d& c : found[k])
        if (const double d = std::abs(nrm.dot(c - a)); d < best_d) {
          best_d = d;
          best = &c;
        }
      if (!best) continue;
      quarter[std::min<size_t>(3, 4 * k / found.size())] += 1 - (best_d / tol) * (best_d / tol);
      ++sup.count;
      if (on) on->push_back(*best);
    }
    sup.score = *std::min_element(quarter.begin(), quarter.end());
    return sup;
  };
  struct Line {
    Support sup;
    Eigen::Vector2d a, nrm;
  };
  std::vector<Line> lines;
  Support best;
  for (size_t i = 0; i < all.size(); ++i)
    for (size_t j = i + 1; j < all.size(); ++j) {
      if (std::abs(all[j].first - all[i].first) < (n + 1) / 4) continue;  // short baselines tilt too easily
      const Eigen::Vector2d d = all[j].second - all[i].second;
      const Eigen::Vector2d nrm = Eigen::Vector2d(-d.y(), d.x()).normalized();
      const Support sup = support(all[i].second, nrm, nullptr);
      if (sup.score > best.score || (sup.score == best.score && sup.count > best.count)) best = sup;
      if (sup.score > 0) lines.push_back({sup, all[i].second, nrm});
    }
  if (3 * best.count < n + 1 || best.count < 8) return false;
  // The outermost of the lines near the best, measured along `outward` at the segment's middle.
  const Eigen::Vector2d mid = cam.undistortPixel(0.5 * (edge[0] + edge[1]));
  double outermost = -1e9;
  Eigen::Vector2d line_a, line_n;
  for (const Line& l : lines) {
    const double den = l.nrm.dot(outward);
    if (l.sup.score < 0.7 * best.score || std::abs(den) < 0.5) continue;
    if (const double offset = l.nrm.dot(l.a - mid) / den; offset > outermost) {
      outermost = offset;
      line_a = l.a;
      line_n = l.nrm;
    }
  }
  std::vector<Eigen::Vector2d> on;
  for (int round = 0; round < 3; ++round) {  // refit on the line's own candidates until it settles
    on.clear();
    support(line_a, line_n, &on);
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const Eigen::Vector2d& u : on) mean += u;
    mean /= static_cast<double>(on.size());
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (const Eigen::Vector2d& u : on) cov += (u - mean) * (u - mean).transpose();
    line_a = mean;
    line_n = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(cov).eigenvectors().col(0);
  }
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector2d& u : on) {
    const Eigen::Vector3d r = Eigen::Vector3d((u.x() - cam.cx) / cam.fx, (u.y() - cam.cy) / cam.fy, 1).normalized();
    scatter += r * r.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(scatter);
  plane = es.eigenvectors().col(0);  // the smallest spread: the plane's normal
  return true;
}

// Orients the tangent plane `n` (of edge `name`) so that the other edge's points lie on its
// positive side, the can's; refuses edges on one line or crossing between their points.
void orientTowards(Eigen::Vector3d& n, const std::string& name, const std::array<Eigen::Vector2d, 2>& other,
                   const std::string& other_name, const Intrinsics& cam, double px_angle) {
  const double s0 = n.dot(rayOf(cam, other[0])), s1 = n.dot(rayOf(cam, other[1]));
  if (std::max(std::abs(s0), std::abs(s1)) < 2 * px_angle)
    refuse(other_name + ": lies on the line of " + name + ": the edges do not determine an axis");
  if (s0 * s1 <= 0)
    refuse(name + ", " + other_name + ": the edges cross between their points: they are not the two sides of one can");
  if (s0 < 0) n = -n;
}

// Axial coordinate (along `a`, from the axis point X0 nearest the camera) where the ray of a
// border point meets the cylinder's near side; a ray that just misses it (a click on the
// silhouette's blurred edge) is taken at its closest approach.
double axialCoordinate(const Eigen::Vector2d& px, const std::string& option, const Intrinsics& cam,
                       const Eigen::Vector3d& X0, const Eigen::Vector3d& a, double r) {
  const Eigen::Vector3d ray = rayOf(cam, px);
  const Eigen::Vector3d perp = ray - ray.dot(a) * a;  // ray component across the axis
  const double A = perp.squaredNorm(), b = perp.dot(X0), C = X0.squaredNorm() - r * r;
  if (A < 1e-12) refuse(option + ": " + point(px) + " looks along the can's axis");
  const double disc = b * b - A * C;
  double t = b / A;  // closest approach
  if (disc >= 0) {
    t = (b - std::sqrt(disc)) / A;
  } else if (std::sqrt(C + r * r - b * b / A) > 1.05 * r) {
    refuse(option + ": " + point(px) + " is not on the can (outside its silhouette)");
  }
  return t * ray.dot(a);
}

// Half the unrolled angle: where the angle between the surface normal and the ray to a camera at
// distance d from the axis reaches max_incidence, in the plane through the camera perpendicular
// to the axis. In the triangle axis-camera-point the angle at the camera is asin(r sin(inc) / d)
// (law of sines), and the angle at the axis is inc minus that.
double halfAngle(double d, double r, double max_incidence) {
  return max_incidence - std::asin(r * std::sin(max_incidence) / d);
}

}  // namespace

void CylinderOptions::check() const {
  if (!(std::isfinite(radius_m) && radius_m > 0)) refuse("--radius: must be a positive number of metres");
  if (!(std::isfinite(max_incidence_rad) && max_incidence_rad >= 10 * kDeg && max_incidence_rad <= 85 * kDeg))
    refuse("--max-incidence: must be in [10, 85] degrees");
  if (!(std::isfinite(pixels_per_metre) && pixels_per_metre >= 0))
    refuse("--pixels-per-metre: must be >= 0 (0: the photo's resolution)");
  if (!(std::isfinite(snap_px) && snap_px >= 0 && snap_px <= 20)) refuse("--snap: must be in [0, 20] px");
}

CylinderGeometry cylinderGeometry(const cv::Mat& photo, const CylinderPoints& p, const Intrinsics& cam,
                                  const CylinderOptions& o) {
  o.check();
  detail::checkInImage(p.left_edge[0], cam, "--left-edge");
  detail::checkInImage(p.left_edge[1], cam, "--left-edge");
  detail::checkInImage(p.right_edge[0], cam, "--right-edge");
  detail::checkInImage(p.right_edge[1], cam, "--right-edge");
  detail::checkInImage(p.label_top, cam, "--label-top");
  detail::checkInImage(p.label_bottom, cam, "--label-bottom");
  const double f = 0.5 * (cam.fx + cam.fy), px_angle = 1 / f, r = o.radius_m;

  // The tangent planes, both oriented towards the can: n1.X = r and n2.X = r on the axis.
  Eigen::Vector3d n1 = edgePlane(p.left_edge, cam, kMinLabelPx / 2.0, "--left-edge");
  Eigen::Vector3d n2 = edgePlane(p.right_edge, cam, kMinLabelPx / 2.0, "--right-edge");
  orientTowards(n1, "--left-edge", p.right_edge, "--right-edge", cam, px_angle);
  orientTowards(n2, "--right-edge", p.left_edge, "--left-edge", cam, px_angle);
  CylinderGeometry g;
  if (o.snap_px > 0) {
    cv::Mat gray = photo, smooth;
    if (photo.channels() == 3) cv::cvtColor(photo, gray, cv::COLOR_BGR2GRAY);
    gray.convertTo(smooth, CV_32F);
    cv::GaussianBlur(smooth, smooth, cv::Size(0, 0), 0.5);
    const auto snap = [&](const std::array<Eigen::Vector2d, 2>& edge, const std::array<Eigen::Vector2d, 2>& other,
                          Eigen::Vector3d& n) {
      const Eigen::Vector3d clicked = n;
      const Eigen::Vector2d along = (edge[1] - edge[0]).normalized();
      Eigen::Vector2d outward(-along.y(), along.x());
      if (outward.dot(edge[0] + edge[1] - other[0] - other[1]) < 0) outward = -outward;
      const bool ok = snapEdge(smooth, edge, outward, cam, o.snap_px, n);
      if (n.dot(clicked) < 0) n = -n;  // the clicked orientation: towards the can
      return ok;
    };
    g.snapped = {snap(p.left_edge, p.right_edge, n1), snap(p.right_edge, p.left_edge, n2)};
  }
  for (int i = 0; i < 2; ++i) {  // the clicked points moved onto the planes used
    const Eigen::Vector3d& n = i == 0 ? n1 : n2;
    const auto& edge = i == 0 ? p.left_edge : p.right_edge;
    for (int k = 0; k < 2; ++k) {
      const Eigen::Vector3d r = rayOf(cam, edge[k]), on = r - n.dot(r) * n;
      g.edges_px[i][k] = cam.project(on);
    }
  }
  const double c = n1.dot(n2);
  if (1 + c < 1e-9) refuse("--left-edge, --right-edge: the edges do not determine an axis");
  // The axis point nearest the camera centre: in the span of n1, n2 (perpendicular to the axis),
  // at distance r from both planes.
  const Eigen::Vector3d X0 = r * (n1 + n2) / (1 + c);
  Eigen::Vector3d a = n1.cross(n2).normalized();
  const double d = X0.norm();
  const Eigen::Vector3d toward_axis = X0 / d;  // z of the object frame: into the can
  if (toward_axis.z() <= 0)
    refuse("--left-edge, --right-edge: these edges put the can behind the camera");

  double y_top = axialCoordinate(p.label_top, "--label-top", cam, X0, a, r);
  double y_bottom = axialCoordinate(p.label_bottom, "--label-bottom", cam, X0, a, r);
  if (y_bottom < y_top) {  // y runs from the top border to the bottom one
    a = -a;
    y_top = -y_top;
    y_bottom = -y_bottom;
  }
  const double ppm = o.pixels_per_metre > 0 ? o.pixels_per_metre : f / (d - r);
  const double height = y_bottom - y_top;
  if (height * ppm < kMinLabelPx)
    refuse("--label-top, --label-bottom: the label is " + yamlNumber(height * ppm) + " px high, less than " +
           std::to_string(kMinLabelPx) + " px");

  g.axis_distance_m = d;
  g.half_angle_rad = halfAngle(d, r, o.max_incidence_rad);
  const double width = 2 * g.half_angle_rad * r;
  const long W = std::lround(width * ppm), H = std::lround(height * ppm);
  if (W < kMinLabelPx)
    refuse("--left-edge, --right-edge: the unrolled part is " + std::to_string(W) + " px wide, less than " +
           std::to_string(kMinLabelPx) + " px: the can is too small in the photo");
  if (W > kMaxLabelPx || H > kMaxLabelPx || static_cast<double>(W) * H > kMaxLabelPixels)
    refuse("--pixels-per-metre: the label would be " + std::to_string(W) + "x" + std::to_string(H) +
           " px, more than " + std::to_string(kMaxLabelPx) + " px a side or 2^25 pixels");
  g.label = CylinderLabel{r, width, height, static_cast<int>(W), static_cast<int>(H)};
  Eigen::Matrix3d R;
  R.col(1) = a;
  R.col(2) = toward_axis;
  R.col(0) = a.cross(toward_axis);
  g.cMo = Pose(R, X0 + 0.5 * (y_top + y_bottom) * a - r * toward_axis);
  return g;
}

cv::Mat unrollLabel(const cv::Mat& photo, const Intrinsics& cam, const CylinderGeometry& g) {
  const CylinderLabel& L = g.label;
  const auto photoPx = [&](double u, double v) { return cam.project(g.cMo * L.point({u, v})); };
  // Supersampling: the largest photo footprint of a label pixel, over a grid of label pixels.
  double footprint = 1;
  for (int i = 0; i <= 8; ++i)
    for (int j = 0; j <= 8; ++j) {
      const double u = (L.image_width - 1) * j / 8.0, v = (L.image_height - 1) * i / 8.0;
      footprint = std::max({footprint, (photoPx(u + 0.5, v) - photoPx(u - 0.5, v)).norm(),
                            (photoPx(u, v + 0.5) - photoPx(u, v - 0.5)).norm()});
    }
  const double pixels = static_cast<double>(L.image_width) * L.image_height;
  const int S = std::max(1, std::min({kMaxSupersampling, static_cast<int>(std::ceil(footprint - 1e-6)),
                                      static_cast<int>(std::sqrt(kMaxSamples / pixels))}));
  cv::Mat map_x(L.image_height * S, L.image_width * S, CV_32FC1), map_y(map_x.size(), CV_32FC1);
  for (int i = 0; i < map_x.rows; ++i)
    for (int j = 0; j < map_x.cols; ++j) {
      // Sub-sample k of label pixel u sits at u - 1/2 + (k + 1/2) / S.
      const Eigen::Vector2d q = photoPx((j + 0.5) / S - 0.5, (i + 0.5) / S - 0.5);
      if (!q.allFinite() || q.x() < -0.5 || q.y() < -0.5 || q.x() > photo.cols - 0.5 || q.y() > photo.rows - 0.5)
        refuse("--image: the unrolled part of the label runs out of the photo at " + point(q) +
               " px: the can must be wholly in view");
      map_x.at<float>(i, j) = static_cast<float>(q.x());
      map_y.at<float>(i, j) = static_cast<float>(q.y());
    }
  cv::Mat fine, label;
  cv::remap(photo, fine, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  if (S == 1) return fine;
  cv::resize(fine, label, {L.image_width, L.image_height}, 0, 0, cv::INTER_AREA);  // S x S box average
  return label;
}

void writeCylinderDefinition(const std::string& yaml_path, const std::string& name, const std::string& label_path,
                             const CylinderGeometry& g) {
  const std::filesystem::path dir = std::filesystem::path(yaml_path).parent_path();
  std::ofstream out = detail::openDefinition(yaml_path);
  out << "# Object definition (docs/formats.md \"Object definition\") made by make_reference --cylinder: the\n"
      << "# label unrolled over theta in [-" << yamlNumber(g.half_angle_rad / kDeg) << ", "
      << yamlNumber(g.half_angle_rad / kDeg) << "] deg about the column that faced the camera,\n"
      << "# the axis " << yamlNumber(g.axis_distance_m) << " m from it. Object frame (core/cylinder.h): origin on the\n"
      << "# surface at the label image's centre, x along its columns, y along its rows (the axis), z into the can.\n"
      << "# In the photo: cMo " << detail::yamlPose(g.cMo) << "\n"
      << "name: " << detail::yamlQuoted(name) << "\n"
      << "reference_image: " << detail::yamlQuoted(detail::relativeTo(label_path, dir)) << "\n"
      << "cylinder:\n"
      << "  radius_m: " << yamlNumber(g.label.radius_m) << "\n"
      << "  label_size_m: [" << yamlNumber(g.label.width_m) << ", " << yamlNumber(g.label.height_m)
      << "]   # arc length x height, metres\n";
  detail::finishDefinition(out, yaml_path);
}

cv::Mat drawCylinder(const cv::Mat& photo, const CylinderGeometry& g, const Intrinsics& cam) {
  cv::Mat img = detail::checkCanvas(photo);
  const int thick = detail::checkThickness(img);
  const auto pt = [](const Eigen::Vector2d& q) { return cv::Point(cvRound(q.x()), cvRound(q.y())); };
  for (const auto& e : g.edges_px) {  // each edge line across the image
    const Eigen::Vector2d dir = (e[1] - e[0]).normalized() * (img.cols + img.rows);
    cv::Point a = pt(e[0] - dir), b = pt(e[0] + dir);
    if (cv::clipLine(img.size(), a, b)) cv::line(img, a, b, cv::Scalar(255, 0, 255), thick, cv::LINE_AA);
  }
  const CylinderLabel& L = g.label;
  const auto photoPt = [&](double u, double v) { return pt(cam.project(g.cMo * L.point({u, v}))); };
  std::vector<cv::Point> outline;
  const double u0 = -0.5, u1 = L.image_width - 0.5, v0 = -0.5, v1 = L.image_height - 0.5;
  for (int k = 0; k <= 32; ++k) outline.push_back(photoPt(u0 + (u1 - u0) * k / 32, v0));
  for (int k = 0; k <= 32; ++k) outline.push_back(photoPt(u1, v0 + (v1 - v0) * k / 32));
  for (int k = 0; k <= 32; ++k) outline.push_back(photoPt(u1 - (u1 - u0) * k / 32, v1));
  for (int k = 0; k <= 32; ++k) outline.push_back(photoPt(u0, v1 - (v1 - v0) * k / 32));
  cv::polylines(img, outline, true, cv::Scalar(0, 255, 255), thick, cv::LINE_AA);
  const Eigen::Vector3d top = g.cMo * L.axisPoint(-L.height_m / 2), bottom = g.cMo * L.axisPoint(L.height_m / 2);
  cv::line(img, pt(cam.project(top)), pt(cam.project(bottom)), cv::Scalar(255, 255, 0), thick, cv::LINE_AA);
  detector::drawAxes(img, cam, g.cMo, L.radius_m, 2 * thick);
  return img;
}

}  // namespace refgrasp::reference
