#include "reference/make_reference.h"

#include <visp3/core/vpImageConvert.h>
#include <visp3/detection/vpDetectorAprilTag.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>
#include <Eigen/Eigenvalues>

#include "core/error.h"
#include "detector/draw.h"
#include "reference/definition_text.h"

namespace refgrasp::reference {

using detail::refuse;
using detail::yamlNumber;
using detail::yamlQuoted;

namespace {

double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

// Corners TL, TR, BR, BL of a w x h rectangle in the object frame (z = 0, x right, y down).
std::array<Eigen::Vector3d, 4> rectangle(double w, double h) {
  return {Eigen::Vector3d(-w / 2, -h / 2, 0), Eigen::Vector3d(w / 2, -h / 2, 0),
          Eigen::Vector3d(w / 2, h / 2, 0), Eigen::Vector3d(-w / 2, h / 2, 0)};
}

// Planar PnP (IPPE, then Levenberg-Marquardt) on the undistorted corners.
Pose planarPnP(const std::array<Eigen::Vector2d, 4>& px, double w, double h, const Intrinsics& cam,
               double* rms_px) {
  std::vector<cv::Point3d> obj;
  std::vector<cv::Point2d> img;
  const auto rect = rectangle(w, h);
  for (size_t i = 0; i < 4; ++i) {
    obj.emplace_back(rect[i].x(), rect[i].y(), 0);
    const Eigen::Vector2d u = cam.undistortPixel(px[i]);
    img.emplace_back(u.x(), u.y());
  }
  cv::Mat K;
  cv::eigen2cv(cam.K(), K);
  cv::Mat rvec, tvec;
  if (!cv::solvePnP(obj, img, K, cv::noArray(), rvec, tvec, false, cv::SOLVEPNP_IPPE))
    refuse("--corners: no pose fits these corners");
  cv::solvePnPRefineLM(obj, img, K, cv::noArray(), rvec, tvec);
  const Pose cMo = Pose::fromRotationVector({rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2)},
                                            {tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)});
  double ss = 0;
  for (size_t i = 0; i < 4; ++i) ss += (cam.project(cMo * rect[i]) - px[i]).squaredNorm();
  *rms_px = std::sqrt(ss / 4);
  if (cMo.t.z() <= 0) refuse("--corners: the pose puts the rectangle behind the camera");
  return cMo;
}

void checkQuad(const std::array<Eigen::Vector2d, 4>& c, const Intrinsics& cam, const std::string& what) {
  for (const auto& p : c) {
    if (!p.allFinite()) refuse(what + ": corners must be finite numbers");
    if (p.x() < -0.5 || p.y() < -0.5 || p.x() > cam.width - 0.5 || p.y() > cam.height - 0.5)
      refuse(what + ": corner (" + std::to_string(p.x()) + ", " + std::to_string(p.y()) +
             ") is outside the " + std::to_string(cam.width) + "x" + std::to_string(cam.height) +
             " image");
  }
  int pos = 0, neg = 0;
  double area = 0;
  for (size_t i = 0; i < 4; ++i) {
    const double z = cross(c[(i + 1) % 4] - c[i], c[(i + 2) % 4] - c[(i + 1) % 4]);
    (z > 0 ? pos : neg)++;
    area += cross(c[i], c[(i + 1) % 4]);
  }
  if (neg == 4) refuse(what + ": corners go anticlockwise; give them as TL, TR, BR, BL");
  if (pos != 4) refuse(what + ": the corners are not a convex quadrilateral (order TL, TR, BR, BL)");
  if (0.5 * area < 100) refuse(what + ": the quadrilateral is too small (< 100 px^2)");
}

// Sub-pixel refinement of a dark square on a light border (the tag's black square in its white
// quiet zone): along each side, the points where the intensity crosses half-way between the
// square and the border (searched along the side's normal, bilinear samples), a least-squares
// line per side, the corners where adjacent lines meet. Unbiased for a symmetric blur; the side
// ends (12 % each) are left out. Returns the input when a side has too few edge points.
std::array<Eigen::Vector2d, 4> refineSquareEdges(const cv::Mat& gray, const std::array<Eigen::Vector2d, 4>& c) {
  const auto sample = [&](const Eigen::Vector2d& p) {
    const double x = std::clamp(p.x(), 0.0, gray.cols - 1.001), y = std::clamp(p.y(), 0.0, gray.rows - 1.001);
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    const double fx = x - x0, fy = y - y0;
    const auto at = [&](int r, int q) { return static_cast<double>(gray.at<uchar>(r, q)); };
    return (1 - fy) * ((1 - fx) * at(y0, x0) + fx * at(y0, x0 + 1)) +
           fy * ((1 - fx) * at(y0 + 1, x0) + fx * at(y0 + 1, x0 + 1));
  };
  const Eigen::Vector2d centre = 0.25 * (c[0] + c[1] + c[2] + c[3]);
  const double side = 0.25 * ((c[1] - c[0]).norm() + (c[2] - c[1]).norm() + (c[3] - c[2]).norm() +
                              (c[0] - c[3]).norm());
  const double reach = std::max(1.5, 0.25 * side / 8);  // a quarter of a cell either side
  std::array<Eigen::Vector3d, 4> lines;                 // n.x = d, n unit, per side i -> i+1
  for (size_t i = 0; i < 4; ++i) {
    const Eigen::Vector2d a = c[i], b = c[(i + 1) % 4], dir = (b - a).normalized();
    Eigen::Vector2d n(-dir.y(), dir.x());
    if (n.dot(a - centre) < 0) n = -n;  // outwards
    std::vector<Eigen::Vector2d> pts;
    for (int k = 0; k <= 30; ++k) {
      const Eigen::Vector2d p = a + (0.12 + 0.76 * k / 30.0) * (b - a);
      const double dark = sample(p - reach * n), light = sample(p + reach * n);
      if (light - dark < 20) continue;  // no clear edge here
      const double mid = 0.5 * (dark + light);
      double prev = sample(p - reach * n) - mid;
      for (double s = -reach + 0.05; s <= reach; s += 0.05) {
        const double v = sample(p + s * n) - mid;
        if (prev < 0 && v >= 0) {
          pts.push_back(p + (s - 0.05 * v / (v - prev)) * n);
          break;
        }
        prev = v;
      }
    }
    if (pts.size() < 8) return c;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const auto& p : pts) mean += p;
    mean /= static_cast<double>(pts.size());
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (const auto& p : pts) cov += (p - mean) * (p - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(cov);
    const Eigen::Vector2d normal = es.eigenvectors().col(0);  // smallest spread
    lines[i] = Eigen::Vector3d(normal.x(), normal.y(), normal.dot(mean));
  }
  std::array<Eigen::Vector2d, 4> out;
  for (size_t i = 0; i < 4; ++i) {  // corner i is where side i-1 meets side i
    const Eigen::Vector3d& l1 = lines[(i + 3) % 4];
    const Eigen::Vector3d& l2 = lines[i];
    const double det = l1.x() * l2.y() - l1.y() * l2.x();
    if (std::abs(det) < 1e-9) return c;
    out[i] = Eigen::Vector2d((l1.z() * l2.y() - l1.y() * l2.z()) / det, (l1.x() * l2.z() - l1.z() * l2.x()) / det);
    if ((out[i] - c[i]).norm() > 2.0) return c;  // far from apriltag's corner: keep those
  }
  return out;
}

vpDetectorAprilTag::vpAprilTagFamily family(const std::string& name) {
  std::string f = name.rfind("tag", 0) == 0 ? name.substr(3) : name;
  static const std::map<std::string, vpDetectorAprilTag::vpAprilTagFamily> kFamilies = {
      {"36h11", vpDetectorAprilTag::TAG_36h11},
      {"25h9", vpDetectorAprilTag::TAG_25h9},
      {"16h5", vpDetectorAprilTag::TAG_16h5},
      {"circle21h7", vpDetectorAprilTag::TAG_CIRCLE21h7}};
  const auto it = kFamilies.find(f);
  if (it == kFamilies.end())
    refuse("--apriltag: unknown family '" + name + "' (36h11, 25h9, 16h5, circle21h7)");
  return it->second;
}

// The whole photo minus the tag (grown by a quarter to cover its white border), as one simple
// polygon: the image border, and the tag's hole reached through a 1 px slit from the top edge.
std::vector<Eigen::Vector2d> photoMinusTag(const std::array<Eigen::Vector2d, 4>& tag,
                                           const Intrinsics& cam) {
  const Eigen::Vector2d centre = 0.25 * (tag[0] + tag[1] + tag[2] + tag[3]);
  std::array<Eigen::Vector2d, 4> hole;
  for (size_t i = 0; i < 4; ++i) hole[i] = centre + 1.25 * (tag[i] - centre);
  const double W = cam.width - 1, H = cam.height - 1;
  for (auto& p : hole) p = p.cwiseMax(Eigen::Vector2d(2, 2)).cwiseMin(Eigen::Vector2d(W - 2, H - 2));
  // The topmost hole corner: the vertical slit above it stays outside the (convex) hole.
  size_t top = 0;
  for (size_t i = 1; i < 4; ++i)
    if (hole[i].y() < hole[top].y()) top = i;
  const double x = hole[top].x();
  std::vector<Eigen::Vector2d> poly = {{x + 0.5, 0}, {W, 0}, {W, H}, {0, H}, {0, 0}, {x - 0.5, 0},
                                       hole[top] - Eigen::Vector2d(0.5, 0)};
  // Around the hole the other way (TL, BL, BR, TR order from `top`), back to the slit.
  for (size_t k = 1; k < 4; ++k) poly.push_back(hole[(top + 4 - k) % 4]);
  poly.push_back(hole[top] + Eigen::Vector2d(0.5, 0));
  return poly;
}

}  // namespace

Reference fromCorners(const std::array<Eigen::Vector2d, 4>& corners_px, double width_m,
                      double height_m, const Intrinsics& camera) {
  if (!(std::isfinite(width_m) && std::isfinite(height_m) && width_m > 0 && height_m > 0))
    refuse("--size: width and height must be positive (metres)");
  checkQuad(corners_px, camera, "--corners");
  Reference r;
  r.cMo = planarPnP(corners_px, width_m, height_m, camera, &r.rms_px);
  r.corners_px = corners_px;
  r.pattern_region_px.assign(corners_px.begin(), corners_px.end());
  r.width_m = width_m;
  r.height_m = height_m;
  r.method = "corners";
  return r;
}

Reference fromTag(const cv::Mat& photo, const Intrinsics& camera, const TagOptions& o) {
  const vpDetectorAprilTag::vpAprilTagFamily fam = family(o.family);
  if (!(std::isfinite(o.tag_size_m) && o.tag_size_m > 0)) refuse("--tag-size: must be positive (metres)");
  cv::Mat gray = photo;
  if (photo.channels() == 3) cv::cvtColor(photo, gray, cv::COLOR_BGR2GRAY);
  vpImage<unsigned char> I;
  vpImageConvert::convert(gray, I);
  vpDetectorAprilTag det(fam);
  det.detect(I);
  const std::vector<int> ids = det.getTagsId();
  std::string seen;
  for (int id : ids) seen += (seen.empty() ? "" : ", ") + std::to_string(id);
  if (ids.empty()) refuse("--apriltag: no " + o.family + " tag found in the photo");
  size_t pick = ids.size();
  if (o.id < 0) {
    if (ids.size() > 1) refuse("--apriltag: " + std::to_string(ids.size()) + " tags (ids " + seen + "); choose one with --tag-id");
    pick = 0;
  } else {
    for (size_t i = 0; i < ids.size(); ++i)
      if (ids[i] == o.id) pick = i;
    if (pick == ids.size()) refuse("--tag-id: tag " + std::to_string(o.id) + " not found (found ids " + seen + ")");
  }
  // apriltag lists the corners anticlockwise from the tag's bottom-left (BL, BR, TR, TL, in the
  // tag's own upright orientation) and puts pixel centres at (0.5, 0.5): shift to ours.
  const std::vector<vpImagePoint>& poly = det.getPolygon(pick);
  std::array<Eigen::Vector2d, 4> c;
  const size_t order[4] = {3, 2, 1, 0};
  for (size_t i = 0; i < 4; ++i)
    c[i] = Eigen::Vector2d(poly[order[i]].get_u() - 0.5, poly[order[i]].get_v() - 0.5);
  c = refineSquareEdges(gray, c);
  Reference r;
  r.cMo = planarPnP(c, o.tag_size_m, o.tag_size_m, camera, &r.rms_px);
  r.corners_px = c;
  r.width_m = r.height_m = o.tag_size_m;
  r.method = "apriltag " + o.family + " id " + std::to_string(ids[pick]);
  if (o.region_px.empty()) {
    r.pattern_region_px = photoMinusTag(c, camera);
    r.region_exact = false;  // the photo shows more than the object around the tag
  } else {
    if (o.region_px.size() < 3) refuse("--region: needs at least 3 points");
    for (const auto& p : o.region_px)
      if (!p.allFinite()) refuse("--region: points must be finite numbers");
    r.pattern_region_px = o.region_px;
  }
  return r;
}

void writeObjectDefinition(const std::string& yaml_path, const std::string& name,
                           const std::string& photo_path, const std::string& camera_path,
                           const Reference& ref) {
  const std::filesystem::path dir = std::filesystem::path(yaml_path).parent_path();
  std::ofstream out = detail::openDefinition(yaml_path);
  const Eigen::Vector3d t = ref.cMo.t, rv = ref.cMo.rotationVector();
  out << "# Object definition (docs/formats.md \"Object definition\") made by make_reference ("
      << ref.method << ", " << yamlNumber(ref.width_m) << " x " << yamlNumber(ref.height_m)
      << " m, corner reprojection RMS " << yamlNumber(ref.rms_px) << " px).\n"
      << "# Object frame: origin at the centre of the " << (ref.method == "corners" ? "rectangle" : "tag")
      << ", x along its top edge, y along its left edge, z into the plane.\n"
      << "name: " << yamlQuoted(name) << "\n"
      << "reference_image: " << yamlQuoted(detail::relativeTo(photo_path, dir)) << "\n"
      << "camera: " << yamlQuoted(detail::relativeTo(camera_path, dir)) << "\n"
      << "reference_pose:\n"
      << "  translation: [" << yamlNumber(t.x()) << ", " << yamlNumber(t.y()) << ", " << yamlNumber(t.z())
      << "]   # metres\n"
      << "  rotation_vector: [" << yamlNumber(rv.x()) << ", " << yamlNumber(rv.y()) << ", "
      << yamlNumber(rv.z()) << "]   # radians\n"
      << "pattern_region: [";
  for (size_t i = 0; i < ref.pattern_region_px.size(); ++i)
    out << (i ? ", " : "") << "[" << yamlNumber(ref.pattern_region_px[i].x()) << ", "
        << yamlNumber(ref.pattern_region_px[i].y()) << "]";
  out << "]\n";
  if (!ref.region_exact)
    out << "pattern_region_exact: false   # the photo minus the tag: it bounds the pattern, not its outline\n";
  detail::finishDefinition(out, yaml_path);
}

cv::Mat drawReference(const cv::Mat& photo, const Reference& ref, const Intrinsics& cam) {
  cv::Mat img = detail::checkCanvas(photo);
  const auto pt = [](const Eigen::Vector2d& p) { return cv::Point(cvRound(p.x()), cvRound(p.y())); };
  const int thick = detail::checkThickness(img);
  std::vector<cv::Point> region;
  for (const auto& p : ref.pattern_region_px) region.push_back(pt(p));
  cv::polylines(img, region, true, cv::Scalar(0, 255, 255), thick, cv::LINE_AA);
  std::vector<cv::Point> quad;
  for (const auto& p : ref.corners_px) quad.push_back(pt(p));
  cv::polylines(img, quad, true, cv::Scalar(255, 0, 255), thick, cv::LINE_AA);
  detector::drawAxes(img, cam, ref.cMo, 0.5 * std::min(ref.width_m, ref.height_m), 2 * thick);
  cv::putText(img, ref.method, {10, 10 + 18 * thick}, cv::FONT_HERSHEY_SIMPLEX, 0.5 * thick,
              cv::Scalar(0, 255, 255), thick, cv::LINE_AA);
  return img;
}

}  // namespace refgrasp::reference
