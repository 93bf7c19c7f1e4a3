#include "robot/sim/realistic_scene.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "robot/sim/degrade.h"
#include "robot/sim/synthetic_scene.h"

namespace refgrasp::testing {

namespace {

double uni(std::mt19937_64& rng, double a, double b) {
  return std::uniform_real_distribution<double>(a, b)(rng);
}
int uniInt(std::mt19937_64& rng, int a, int b) { return std::uniform_int_distribution<int>(a, b)(rng); }
bool chance(std::mt19937_64& rng, double p) { return uni(rng, 0, 1) < p; }

// Mosaic a gray image as an RGGB sensor would see a gray world with slightly different channel
// gains, demosaic bilinearly (OpenCV), back to gray: the zipper and colour-interpolation artefacts.
void bayerRoundTrip(cv::Mat& img) {
  cv::Mat raw(img.size(), CV_8UC1);
  const float gain[2][2] = {{1.08f, 0.97f}, {0.97f, 0.90f}};  // R G / G B
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      raw.at<uchar>(y, x) = cv::saturate_cast<uchar>(gain[y & 1][x & 1] * img.at<uchar>(y, x));
  cv::Mat bgr;
  cv::cvtColor(raw, bgr, cv::COLOR_BayerBG2BGR);  // OpenCV's name for an RGGB sensor
  cv::cvtColor(bgr, img, cv::COLOR_BGR2GRAY);
}

std::array<Eigen::Vector2d, 4> projectCorners(const Intrinsics& cam, const Pose& cMp, double w, double h) {
  sim::TexturedPlane p;
  p.texture = cv::Mat(2, 2, CV_8UC1);
  p.width_m = w;
  p.height_m = h;
  p.cMp = cMp;
  return sim::projectPlaneCorners(cam, p);
}

// A plane pose looking at image point `at` from `dist` with the given tilt, its direction, and
// in-plane rotation (the plane's normal, z, points away from the camera).
Pose lookingPose(const Intrinsics& cam, const Eigen::Vector2d& at, double dist, double tilt,
                 double tilt_dir, double spin) {
  const Eigen::Vector3d ray = (cam.K().inverse() * at.homogeneous()).normalized();
  const Eigen::Vector3d e1 = ray.cross(Eigen::Vector3d::UnitY()).normalized();
  const Eigen::Vector3d e2 = ray.cross(e1);
  const Eigen::Vector3d axis = std::cos(tilt_dir) * e1 + std::sin(tilt_dir) * e2;
  const Eigen::Vector3d z = axisAngle(axis, tilt) * ray;
  Eigen::Vector3d x = Eigen::Vector3d::UnitX() - z * z.x();
  x = axisAngle(z, spin) * x.normalized();
  Eigen::Matrix3d R;
  R << x, z.cross(x), z;
  return Pose(R, dist * ray);
}

}  // namespace

void applyCameraLook(cv::Mat& img, const CameraLook& k, std::mt19937_64& rng) {
  CV_Assert(img.type() == CV_8UC1);
  cv::Mat f;
  img.convertTo(f, CV_32F, 1.0 / 255);
  // Light: gain and gamma (exposure, tone curve), a gradient across the image, a highlight.
  if (k.gain != 1 || k.gamma != 1) {
    f *= k.gain;
    cv::max(f, 0, f);
    cv::pow(f, k.gamma, f);
  }
  const double diag = std::hypot(img.cols, img.rows);
  const Eigen::Vector2d centre((img.cols - 1) / 2.0, (img.rows - 1) / 2.0);
  if (k.gradient != 0 || k.highlight > 0 || k.vignetting > 0) {
    const Eigen::Vector2d dir(std::cos(k.gradient_angle_rad), std::sin(k.gradient_angle_rad));
    cv::Mat light(img.size(), CV_32F), add(img.size(), CV_32F);
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) {
        const Eigen::Vector2d p(x, y);
        light.at<float>(y, x) = static_cast<float>(1 + k.gradient * dir.dot(p - centre) / diag);
        const double r2 = (p - k.highlight_px).squaredNorm() / (k.highlight_radius_px * k.highlight_radius_px);
        add.at<float>(y, x) = static_cast<float>(k.highlight / 255 * std::exp(-0.5 * r2));
      }
    f = f.mul(light) + add;
  }
  // Optics.
  if (k.defocus_sigma_px > 0.05) cv::GaussianBlur(f, f, cv::Size(0, 0), k.defocus_sigma_px);
  if (k.motion_blur_px >= 0.5)
    cv::filter2D(f, f, CV_32F, sim::motionBlurKernel(k.motion_blur_px, k.motion_blur_angle_rad),
                 cv::Point(-1, -1), 0, cv::BORDER_REFLECT);
  if (k.vignetting > 0) {
    const double rmax2 = centre.squaredNorm();
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) {
        const double r2 = (Eigen::Vector2d(x, y) - centre).squaredNorm() / rmax2;
        f.at<float>(y, x) *= static_cast<float>(1 - k.vignetting * r2 * (2 - r2));
      }
  }
  f.convertTo(img, CV_8U, 255);
  // Sensor, then compression.
  sim::Degradation d;
  d.noise_sigma = k.noise_sigma;
  sim::degrade(img, d, rng);
  if (k.bayer) bayerRoundTrip(img);
  if (k.jpeg_quality > 0) {
    std::vector<uchar> buf;
    cv::imencode(".jpg", img, buf, {cv::IMWRITE_JPEG_QUALITY, k.jpeg_quality});
    img = cv::imdecode(buf, cv::IMREAD_GRAYSCALE);
  }
}

CameraLook randomCameraLook(std::mt19937_64& rng, double s, const Eigen::Vector2d& highlight_near) {
  CameraLook k;
  k.gain = 1 + s * uni(rng, -0.45, 0.45);
  k.gamma = std::exp(s * uni(rng, -0.43, 0.4));
  k.gradient = s * uni(rng, -0.45, 0.45);
  k.gradient_angle_rad = uni(rng, 0, 2 * M_PI);
  if (chance(rng, 0.35 * s)) {
    k.highlight = s * uni(rng, 40, 110);
    k.highlight_px = highlight_near + Eigen::Vector2d(uni(rng, -20, 20), uni(rng, -20, 20));
    k.highlight_radius_px = uni(rng, 8, 35);
  }
  k.defocus_sigma_px = s * uni(rng, 0, 1.4);
  k.motion_blur_px = chance(rng, 0.4) ? s * uni(rng, 0, 4) : 0;
  k.motion_blur_angle_rad = uni(rng, 0, M_PI);
  k.vignetting = s * uni(rng, 0, 0.4);
  k.noise_sigma = 1 + s * uni(rng, 0, 3);
  k.bayer = chance(rng, 0.5);
  k.jpeg_quality = s > 0 ? static_cast<int>(std::lround(90 - s * uni(rng, 0, 45))) : 0;
  return k;
}

const std::vector<std::string>& photoTextures() {
  static const std::vector<std::string> names = {
      "photos/fruits_closeup.jpg", "photos/butterfly_on_leaf.jpg", "photos/hotel_facade.jpg",
      "photos/aerial_town.jpg", "photos/cookie_box.png"};
  return names;
}

cv::Mat photoClutterBackground(uint64_t seed, int width, int height, const std::vector<std::string>& exclude) {
  cv::Mat img = clutterBackground(seed, width, height);
  std::mt19937_64 rng(seed * 0xBF58476D1CE4E5B9ull + 5);
  std::vector<std::string> pool;
  for (const auto& p : photoTextures())
    if (std::find(exclude.begin(), exclude.end(), p) == exclude.end()) pool.push_back(p);
  // The scene photo shows the cookie box: never behind a scene of it.
  if (std::find(exclude.begin(), exclude.end(), "photos/cookie_box.png") == exclude.end())
    pool.push_back("photos/cookie_box_in_scene.png");
  const int n = uniInt(rng, 2, 4);
  for (int i = 0; i < n && !pool.empty(); ++i) {
    const cv::Mat tex = loadMedia(pool[static_cast<size_t>(uniInt(rng, 0, static_cast<int>(pool.size()) - 1))]);
    const double scale = uni(rng, 0.2, 0.6) * std::min(width, height) / std::max(tex.cols, tex.rows);
    cv::Mat M = cv::getRotationMatrix2D(cv::Point2f(tex.cols / 2.f, tex.rows / 2.f), uni(rng, -40, 40), scale);
    M.at<double>(0, 2) += uni(rng, 0, width) - tex.cols / 2.0;
    M.at<double>(1, 2) += uni(rng, 0, height) - tex.rows / 2.0;
    cv::warpAffine(tex, img, M, img.size(), cv::INTER_AREA, cv::BORDER_TRANSPARENT);
  }
  return img;
}

ReferencePhoto photographReference(const cv::Mat& texture, double width_m, double height_m,
                                   const ReferencePhotoSpec& spec) {
  std::mt19937_64 rng(spec.seed * 0x94D049BB133111EBull + 11);
  const bool big = chance(rng, 0.5);
  const Intrinsics full = big ? Intrinsics::pinhole(1024, 768, 880, 511.5, 383.5)
                              : Intrinsics::pinhole(800, 600, 640, 399.5, 299.5);
  // Roughly upright, near the image centre, at the distance that gives the requested width.
  const double dist = full.fx * width_m / spec.width_px;
  const Eigen::Vector2d at(full.cx + uni(rng, -0.1, 0.1) * full.width, full.cy + uni(rng, -0.1, 0.1) * full.height);
  const Pose cMo = lookingPose(full, at, dist, spec.tilt_rad, uni(rng, 0, 2 * M_PI), uni(rng, -0.25, 0.25));
  sim::TexturedPlane plane{texture, width_m, height_m, cMo};
  cv::Mat img = sim::renderView(full, {plane}, clutterBackground(spec.seed + 7777, full.width, full.height));
  const std::array<Eigen::Vector2d, 4> c = sim::projectPlaneCorners(full, plane);
  Eigen::Vector2d mid = Eigen::Vector2d::Zero();
  for (const auto& p : c) mid += p / 4;
  const CameraLook look = randomCameraLook(rng, spec.look_strength, mid);
  applyCameraLook(img, look, rng);

  // Crop to the pattern and a margin, as a person cuts the object out of a photo.
  Eigen::Vector2d lo = c[0], hi = c[0];
  for (const auto& p : c) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const int m = uniInt(rng, 4, 30);
  const int x0 = std::max(0, static_cast<int>(std::floor(lo.x())) - m);
  const int y0 = std::max(0, static_cast<int>(std::floor(lo.y())) - m);
  const int x1 = std::min(full.width, static_cast<int>(std::ceil(hi.x())) + m + 1);
  const int y1 = std::min(full.height, static_cast<int>(std::ceil(hi.y())) + m + 1);
  ReferencePhoto out;
  out.image = img(cv::Rect(x0, y0, x1 - x0, y1 - y0)).clone();
  out.camera = Intrinsics::pinhole(out.image.cols, out.image.rows, full.fx, full.cx - x0, full.cy - y0);
  out.cMo = cMo;
  out.tilt_rad = spec.tilt_rad;
  const Eigen::Vector2d off(x0, y0);
  for (int i = 0; i < 4; ++i) out.corners_px[i] = c[i] - off;
  out.width_px = 0.5 * ((c[1] - c[0]).norm() + (c[2] - c[3]).norm());
  // The traced outline: each corner clicked within ~0.5 px; sometimes points along the edges too.
  std::normal_distribution<double> click(0, 0.5);
  for (int i = 0; i < 4; ++i) {
    out.polygon_px.push_back(out.corners_px[i] + Eigen::Vector2d(click(rng), click(rng)));
    if (chance(rng, 0.3)) {
      const double t = uni(rng, 0.3, 0.7);
      out.polygon_px.push_back((1 - t) * out.corners_px[i] + t * out.corners_px[(i + 1) % 4] +
                               Eigen::Vector2d(click(rng), click(rng)));
    }
  }
  return out;
}

RealisticScene renderRealisticScene(const Intrinsics& cam, const cv::Mat& texture, double width_m,
                                    double height_m, const RealisticSceneSpec& spec,
                                    const std::vector<sim::TexturedPlane>& others) {
  std::mt19937_64 rng(spec.seed * 0xD6E8FEB86659FD93ull + 3);
  std::vector<sim::TexturedPlane> planes = others;
  if (!texture.empty()) planes.insert(planes.begin(), sim::TexturedPlane{texture, width_m, height_m, spec.cMo});
  RealisticScene out;
  out.image = sim::renderView(cam, planes, photoClutterBackground(spec.seed, cam.width, cam.height,
                                                                  spec.exclude_from_background));
  out.cMo = spec.cMo;
  if (!texture.empty()) {
    out.corners = projectCorners(cam, spec.cMo, width_m, height_m);
    if (spec.occlusion > 0) {
      // An occluder (a clutter texture) covering that fraction of the target's box from one side.
      Eigen::Vector2d lo = out.corners[0], hi = out.corners[0];
      for (const auto& p : out.corners) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
      cv::Rect2d r(lo.x(), lo.y(), hi.x() - lo.x(), hi.y() - lo.y());
      const int side = uniInt(rng, 0, 3);
      const double f = spec.occlusion;
      if (side == 0) r.width *= f;
      if (side == 1) { r.x += r.width * (1 - f); r.width *= f; }
      if (side == 2) r.height *= f;
      if (side == 3) { r.y += r.height * (1 - f); r.height *= f; }
      const cv::Rect box = cv::Rect(r) & cv::Rect(0, 0, cam.width, cam.height);
      if (box.area() > 0) {
        const cv::Mat tex = loadMedia("clutter/clutter_0" + std::to_string(uniInt(rng, 0, 7)) + ".png");
        cv::Mat patch;
        cv::resize(tex, patch, box.size(), 0, 0, cv::INTER_AREA);
        patch.copyTo(out.image(box));
      }
    }
  }
  applyCameraLook(out.image, spec.look, rng);
  return out;
}

}  // namespace refgrasp::testing
