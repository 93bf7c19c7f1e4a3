#include "robot/sim/synthetic_scene.h"

#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "core/image_io.h"
#include "robot/sim/degrade.h"

namespace refgrasp::testing {

namespace {

double uni(std::mt19937_64& rng, double a, double b) {
  return std::uniform_real_distribution<double>(a, b)(rng);
}
int uniInt(std::mt19937_64& rng, int a, int b) { return std::uniform_int_distribution<int>(a, b)(rng); }

const std::vector<std::string>& clutterTextures() {
  static const std::vector<std::string> names = {
      "clutter/clutter_00.png", "clutter/clutter_01.png", "clutter/clutter_02.png",
      "clutter/clutter_03.png", "clutter/clutter_04.png", "clutter/clutter_05.png",
      "clutter/clutter_06.png", "clutter/clutter_07.png", "boxes/box_side_a.png",
      "boxes/box_side_b.png",   "backgrounds/wall.png",   "backgrounds/table_wood.png"};
  return names;
}

const char* const kClutterWords[] = {"EXIT", "Room 12", "push", "coffee", "A4", "memo",
                                     "7", "lab", "STOP", "notes", "3.14", "ok"};

}  // namespace

std::string mediaDir() {
  if (const char* d = std::getenv("REFGRASP_MEDIA_DIR"); d && *d) return d;
  return REFGRASP_MEDIA_DIR;
}

Intrinsics sceneCamera() { return Intrinsics::pinhole(640, 480, 550, 319.5, 239.5); }

cv::Mat loadMedia(const std::string& relpath) {
  static std::mutex mu;
  static std::map<std::string, cv::Mat> cache;
  std::lock_guard<std::mutex> lock(mu);
  const auto it = cache.find(relpath);
  if (it != cache.end()) return it->second;
  const std::string path = mediaDir() + "/" + relpath;
  const ImageRead img = readImage(path, ImageMode::kGray);
  if (!img.ok())
    throw std::runtime_error(img.error + " (a media texture: run build/app/make_media --out media)");
  cache[relpath] = img.image;
  return img.image;
}

const std::vector<std::string>& targetTextures() {
  static const std::vector<std::string> names = {
      "targets/poster_concert.png", "targets/cereal_box.png", "targets/book_cover.png",
      "targets/tea_box.png", "targets/magazine.png"};
  return names;
}

cv::Mat clutterBackground(uint64_t seed, int width, int height) {
  std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ull + 17);
  // Smooth base: a coarse random grid upsampled bicubically.
  cv::Mat grid(4, 5, CV_8U);
  for (int i = 0; i < grid.rows * grid.cols; ++i) grid.data[i] = static_cast<uchar>(uniInt(rng, 40, 210));
  cv::Mat img;
  cv::resize(grid, img, cv::Size(width, height), 0, 0, cv::INTER_CUBIC);

  // Patches of clutter textures at random scales, rotations and brightness.
  const int patches = uniInt(rng, 7, 12);
  for (int i = 0; i < patches; ++i) {
    const auto& names = clutterTextures();
    const cv::Mat tex = loadMedia(names[static_cast<size_t>(uniInt(rng, 0, static_cast<int>(names.size()) - 1))]);
    const double scale = uni(rng, 0.25, 1.0) * std::min(width, height) / std::max(tex.cols, tex.rows);
    const cv::Point2f centre(static_cast<float>(uni(rng, 0, width)), static_cast<float>(uni(rng, 0, height)));
    cv::Mat M = cv::getRotationMatrix2D(cv::Point2f(tex.cols / 2.f, tex.rows / 2.f), uni(rng, -180, 180), scale);
    M.at<double>(0, 2) += centre.x - tex.cols / 2.0;
    M.at<double>(1, 2) += centre.y - tex.rows / 2.0;
    cv::Mat shaded;
    tex.convertTo(shaded, CV_8U, uni(rng, 0.6, 1.2), uni(rng, -30, 30));
    cv::warpAffine(shaded, img, M, img.size(), cv::INTER_LINEAR, cv::BORDER_TRANSPARENT);
  }
  // Shapes and words on top.
  const int shapes = uniInt(rng, 10, 25);
  for (int i = 0; i < shapes; ++i) {
    const cv::Point c(uniInt(rng, 0, width - 1), uniInt(rng, 0, height - 1));
    const int s = uniInt(rng, 5, 60);
    const cv::Scalar col(uniInt(rng, 0, 255));
    const int thick = uniInt(rng, 0, 1) ? cv::FILLED : uniInt(rng, 1, 4);
    switch (uniInt(rng, 0, 2)) {
      case 0:
        cv::circle(img, c, s, col, thick, cv::LINE_AA);
        break;
      case 1:
        cv::rectangle(img, cv::Rect(c.x, c.y, s, uniInt(rng, 5, 60)), col, thick, cv::LINE_AA);
        break;
      default:
        cv::line(img, c, c + cv::Point(uniInt(rng, -80, 80), uniInt(rng, -80, 80)), col,
                 uniInt(rng, 1, 4), cv::LINE_AA);
    }
  }
  const int words = uniInt(rng, 4, 10);
  for (int i = 0; i < words; ++i)
    cv::putText(img, kClutterWords[uniInt(rng, 0, 11)],
                cv::Point(uniInt(rng, 0, width - 40), uniInt(rng, 15, height - 1)),
                uniInt(rng, 0, 7), uni(rng, 0.4, 1.6), cv::Scalar(uniInt(rng, 0, 255)),
                uniInt(rng, 1, 3), cv::LINE_AA);
  return img;
}

Pose randomVisiblePose(std::mt19937_64& rng, const Intrinsics& cam, double width_m, double height_m,
                       double min_dist_m, double max_dist_m, double max_tilt_rad) {
  return randomVisiblePoseIn(rng, cam, width_m, height_m, min_dist_m, max_dist_m, 0, max_tilt_rad);
}

Pose randomVisiblePoseIn(std::mt19937_64& rng, const Intrinsics& cam, double width_m, double height_m,
                         double min_dist_m, double max_dist_m, double min_tilt_rad, double max_tilt_rad) {
  constexpr double kMargin = 10;
  constexpr int kTries = 20000;
  const Eigen::Matrix3d Kinv = cam.K().inverse();
  for (int attempt = 0; attempt < kTries; ++attempt) {
    const Eigen::Vector3d ray =
        (Kinv * Eigen::Vector3d(uni(rng, 0, cam.width - 1), uni(rng, 0, cam.height - 1), 1)).normalized();
    const double dist = uni(rng, min_dist_m, max_dist_m);
    const double tilt = uni(rng, min_tilt_rad, max_tilt_rad), tilt_dir = uni(rng, 0, 2 * M_PI);
    const double spin = uni(rng, 0, 2 * M_PI);
    // Basis perpendicular to the ray; the tilt axis lies in it.
    const Eigen::Vector3d e1 = ray.cross(Eigen::Vector3d::UnitY()).normalized();
    const Eigen::Vector3d e2 = ray.cross(e1);
    const Eigen::Vector3d axis = std::cos(tilt_dir) * e1 + std::sin(tilt_dir) * e2;
    const Eigen::Vector3d z = axisAngle(axis, tilt) * ray;  // points away from the camera
    Eigen::Vector3d x = Eigen::Vector3d::UnitX() - z * z.x();
    x = axisAngle(z, spin) * x.normalized();
    Eigen::Matrix3d R;
    R << x, z.cross(x), z;
    const Pose cMo(R, dist * ray);
    bool ok = true;
    for (const double sx : {-0.5, 0.5})
      for (const double sy : {-0.5, 0.5}) {
        const Eigen::Vector3d X = cMo * Eigen::Vector3d(sx * width_m, sy * height_m, 0);
        if (X.z() <= 0.01) {
          ok = false;
          continue;
        }
        const Eigen::Vector2d p = cam.project(X);
        ok = ok && p.x() >= kMargin && p.y() >= kMargin && p.x() <= cam.width - 1 - kMargin &&
             p.y() <= cam.height - 1 - kMargin;
      }
    if (ok) return cMo;
  }
  throw std::runtime_error("randomVisiblePose: no pose of a " + std::to_string(width_m) + " x " +
                           std::to_string(height_m) + " m plane at " + std::to_string(min_dist_m) +
                           ".." + std::to_string(max_dist_m) + " m fits in the image");
}

RenderedScene renderTargets(const Intrinsics& cam, const std::vector<sim::TexturedPlane>& targets,
                            const SceneSpec& spec) {
  RenderedScene out;
  out.image = sim::renderView(cam, targets, clutterBackground(spec.seed, cam.width, cam.height));
  sim::Degradation d;
  d.noise_sigma = spec.noise_sigma;
  d.motion_blur_px = spec.motion_blur_px;
  d.motion_blur_angle_rad = spec.motion_blur_angle_rad;
  std::mt19937_64 rng(spec.seed ^ 0xD1B54A32D192ED03ull);
  sim::degrade(out.image, d, rng);
  for (const auto& t : targets) {
    out.all_cMo.push_back(t.cMp);
    out.all_corners.push_back(sim::projectPlaneCorners(cam, t));
  }
  if (!targets.empty()) {
    out.cMo = out.all_cMo.front();
    out.corners = out.all_corners.front();
  }
  return out;
}

RenderedScene renderTarget(const Intrinsics& cam, const cv::Mat& texture, double width_m,
                           double height_m, const SceneSpec& spec) {
  return renderTargets(cam, {sim::TexturedPlane{texture, width_m, height_m, spec.cMo}}, spec);
}

}  // namespace refgrasp::testing
