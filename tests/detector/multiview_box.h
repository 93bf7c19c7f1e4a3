#pragma once
// A box defined by its faces, for the several-view tests: five faces textured with crops of the
// real photos in media/photos/ and the box top of media/boxes/ (not the box sides: the
// synthetic scenes' clutter uses them), written as five planar definitions
// (each face's texture its own reference image, seen frontally at 0.5 m) and one several-view
// definition, and rendered from any side.
//
// Box frame o: origin at the box centre, x along its width, y down (along its height), z along
// its depth (the front face is the -z face, seen from a camera on the -z side). The bottom
// (+y) is plain cardboard and not defined.
#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <string>

#include "core/camera.h"
#include "core/image_io.h"
#include "core/pose.h"
#include "robot/sim/degrade.h"
#include "robot/sim/render.h"
#include "robot/sim/scenario.h"
#include "robot/sim/synthetic_scene.h"
#include "detector/object.h"

namespace refgrasp::testing {

struct TestBox {
  Eigen::Vector3d size_m{0.20, 0.15, 0.08};
  std::array<cv::Mat, 6> textures;  ///< boxFaces order: -x, +x, -y, +y, -z, +z
  std::vector<sim::TexturedPlane> faces;  ///< face frames in the box frame (cMp holds oMp)
  /// The defined faces: boxFaces index and view name, in the several-view definition's order.
  std::vector<std::pair<int, std::string>> defined = {{4, "front"}, {5, "back"}, {0, "left"}, {1, "right"}, {2, "top"}};

  TestBox() {
    const auto photo = [](const std::string& rel, const cv::Rect& crop, double aspect) {
      cv::Mat img = loadMedia(rel);  // gray
      cv::Mat c = img(crop & cv::Rect(0, 0, img.cols, img.rows)).clone();
      cv::Mat out;
      const int h = 300;
      cv::resize(c, out, cv::Size(static_cast<int>(std::lround(h * aspect)), h), 0, 0, cv::INTER_AREA);
      return out;
    };
    const auto media = [](const std::string& rel) { return loadMedia(rel).clone(); };
    const double side_aspect = size_m.z() / size_m.y();
    textures[0] = photo("photos/fruits_closeup.jpg", cv::Rect(120, 40, 200, 375), side_aspect);
    textures[1] = photo("photos/butterfly_on_leaf.jpg", cv::Rect(150, 0, 190, 356), side_aspect);
    cv::Mat top = media("boxes/box_top.png");
    cv::resize(top(cv::Rect(0, 120, 400, 160)), textures[2], cv::Size(500, 200), 0, 0, cv::INTER_AREA);
    textures[3] = cv::Mat(300, 400, CV_8UC1, cv::Scalar(150));
    textures[4] = photo("photos/cookie_box.png", cv::Rect(13, 0, 297, 223), 4.0 / 3);
    textures[5] = photo("photos/aerial_town.jpg", cv::Rect(0, 0, 640, 480), 4.0 / 3);
    const Eigen::Vector3d Y = Eigen::Vector3d::UnitY(), Z = Eigen::Vector3d::UnitZ();
    faces = sim::boxFaces(size_m, Eigen::Vector3d::Zero(), textures, {Y, Y, Z, Z, Y, Y});
  }

  /// The box at cMo (box frame in the camera frame), over a background.
  std::vector<sim::TexturedPlane> placed(const Pose& cMo) const {
    std::vector<sim::TexturedPlane> out = faces;
    for (auto& f : out) f.cMp = cMo * f.cMp;
    return out;
  }

  /// Writes each defined face's planar definition (the texture as its reference image, a
  /// pinhole seeing it frontally at 0.5 m) and `<name>.yaml` with their views; returns its path.
  /// oMv_error: added to the last view's oMv (a wrong definition).
  std::string writeDefinitions(const std::filesystem::path& dir, const std::string& name = "box",
                               const Pose& last_error = Pose()) const {
    std::ofstream views(dir / (name + ".yaml"));
    views << "name: " << name << "\nviews:\n";
    for (size_t k = 0; k < defined.size(); ++k) {
      const auto& [i, view] = defined[k];
      const sim::TexturedPlane& f = faces[static_cast<size_t>(i)];
      const std::string stem = name + "_" + view;
      writeImageFile((dir / (stem + ".png")).string(), f.texture);
      saveCameraFile((dir / (stem + "_camera.yaml")).string(), detector::textureCamera(f.texture, f.width_m, 0.5),
                     stem);
      std::ofstream(dir / (stem + ".yaml")) << "name: " << view << "\nreference_image: " << stem
                                            << ".png\ncamera: " << stem << "_camera.yaml\n"
                                            << "reference_pose: {translation: [0, 0, 0.5], rotation_vector: [0, 0, 0]}\n";
      const Pose oMv = k + 1 == defined.size() ? last_error * f.cMp : f.cMp;
      const Eigen::Vector3d r = oMv.rotationVector();
      views.precision(17);
      views << "  - definition: " << stem << ".yaml\n    oMv: {translation: [" << oMv.t.x() << ", " << oMv.t.y()
            << ", " << oMv.t.z() << "], rotation_vector: [" << r.x() << ", " << r.y() << ", " << r.z() << "]}\n";
    }
    return (dir / (name + ".yaml")).string();
  }
};

/// The box frame in the camera frame for a camera looking at the box centre from azimuth
/// `azimuth_rad` about the box's vertical (0: in front, pi/2: on its +x side), elevation
/// `elevation_rad` above it, at `distance_m`; the camera's rows point down the box's y.
inline Pose lookAtBox(double azimuth_rad, double elevation_rad, double distance_m) {
  const Eigen::Vector3d C = distance_m * Eigen::Vector3d(std::sin(azimuth_rad) * std::cos(elevation_rad),
                                                         -std::sin(elevation_rad),
                                                         -std::cos(azimuth_rad) * std::cos(elevation_rad));
  const Eigen::Vector3d z = (-C).normalized();
  const Eigen::Vector3d y = (Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitY().dot(z) * z).normalized();
  Eigen::Matrix3d R;
  R << y.cross(z), y, z;  // oMc's rotation: camera axes in the box frame
  return Pose(R, C).inverse();
}

/// A rendered, degraded view of `planes` over a cluttered background (fixed by `seed`).
inline cv::Mat renderScene(const Intrinsics& cam, const std::vector<sim::TexturedPlane>& planes, uint64_t seed) {
  cv::Mat img = sim::renderView(cam, planes, clutterBackground(seed, cam.width, cam.height));
  sim::Degradation d;
  d.noise_sigma = 2;
  std::mt19937_64 rng(seed);
  sim::degrade(img, d, rng);
  return img;
}

}  // namespace refgrasp::testing
