#include "eval/detector_accuracy.h"

#include <algorithm>
#include <array>
#include <map>
#include <random>

#include "detector/detector.h"
#include "detector/detector_internal.h"
#include "detector/homography.h"
#include "detector/matching.h"
#include "robot/sim/degrade.h"
#include "robot/sim/synthetic_scene.h"

namespace refgrasp::eval {

namespace {

constexpr double kDeg = M_PI / 180;
constexpr double kWidth = 0.20;  // the poster's width, metres
const char* const kPoster = "targets/poster_concert.png";

double heightOf(const cv::Mat& tex, double width) { return width * tex.rows / tex.cols; }

using Corners = std::array<Eigen::Vector2d, 4>;

double worstCorner(const Corners& a, const Corners& b) {
  double e = 0;
  for (int i = 0; i < 4; ++i) e = std::max(e, (a[i] - b[i]).norm());
  return e;
}

}  // namespace

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size() - 1) + 0.5))];
}

double sampleStd(const std::vector<double>& v) {
  if (v.size() < 2) return NAN;
  double m = 0, s = 0;
  for (double x : v) m += x;
  m /= static_cast<double>(v.size());
  for (double x : v) s += (x - m) * (x - m);
  return std::sqrt(s / static_cast<double>(v.size() - 1));
}

double positionJitter(const std::vector<Pose>& poses) {
  double s2 = 0;
  for (int k = 0; k < 3; ++k) {
    std::vector<double> v;
    for (const auto& p : poses) v.push_back(p.t[k]);
    s2 += std::pow(sampleStd(v), 2);
  }
  return std::sqrt(s2);
}

void PoseErrors::add(const std::optional<Pose>& estimate, const Pose& truth) {
  ++n;
  if (!estimate) return;
  const double r = rotationError(*estimate, truth) / kDeg;
  const double t = translationError(*estimate, truth) / truth.t.norm();
  rot_deg.push_back(r);
  rel_t.push_back(t);
  if (r < 1.0 && t < 0.01) ++ok;
}

PoseAccuracy poseAccuracy(int poses, uint64_t seed) {
  using namespace detector;
  const cv::Mat tex = testing::loadMedia(kPoster);
  const Intrinsics cam = testing::sceneCamera();
  Detector det;
  const int id = det.addObject(textureObject("poster", tex, kWidth));
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> blur(0.0, 1.5), angle(0, M_PI);
  PoseAccuracy out;
  for (int i = 0; i < poses; ++i) {
    testing::SceneSpec spec;
    spec.cMo = testing::randomVisiblePose(rng, cam, kWidth, heightOf(tex, kWidth), 0.3, 1.2, 50 * kDeg);
    spec.motion_blur_px = blur(rng);
    spec.motion_blur_angle_rad = angle(rng);
    spec.seed = 1000 + static_cast<uint64_t>(i);
    const testing::RenderedScene s = testing::renderTarget(cam, tex, kWidth, heightOf(tex, kWidth), spec);
    PoseAccuracyFrame f;
    f.truth = s.cMo;
    f.tilt_deg = std::acos(std::abs(s.cMo.R(2, 2))) / kDeg;
    // Both methods on the same matches.
    const Features features = DetectorInternals::extract(det, s.image, cam);
    const GridIndex grid(features.keypoints, features.image_size);
    const MatchResult m = matchObject(DetectorInternals::referenceIndex(det, id), features, grid, det.options().match);
    if (!m.instances.empty()) {
      f.inliers = static_cast<int>(m.instances[0].inliers.size());
      const PoseResult a = DetectorInternals::estimatePose(det, id, m.instances[0], features, cam, PoseMethod::kPaper);
      const PoseResult b = DetectorInternals::estimatePose(det, id, m.instances[0], features, cam, PoseMethod::kRefined);
      if (a.ok) f.paper = a.cMo;
      if (b.ok) f.refined = b.cMo;
    }
    // The facade (default method, sanity check) on the same frame.
    if (const std::optional<Detection> d = det.detect(s.image, cam).find(id)) {
      f.detected = d->cMo;
      f.detected_corner_px = worstCorner(d->corners, s.corners);
    }
    out.paper.add(f.paper, f.truth);
    out.refined.add(f.refined, f.truth);
    out.detected.add(f.detected, f.truth);
    out.frames.push_back(f);
  }
  return out;
}

std::vector<std::optional<double>> jitterDepths(int frames) {
  using namespace detector;
  const cv::Mat tex = testing::loadMedia(kPoster);
  const Intrinsics cam = testing::sceneCamera();
  Detector det;
  det.addObject(textureObject("poster", tex, kWidth));
  const Pose truth = Pose::fromRotationVector({0.25, -0.15, 0.1}, {0.02, -0.01, 0.5});
  std::vector<std::optional<double>> z;
  for (int i = 0; i < frames; ++i) {
    testing::SceneSpec spec;
    spec.cMo = truth;
    spec.noise_sigma = 2.0;
    spec.seed = 77 + static_cast<uint64_t>(i);
    const testing::RenderedScene s = testing::renderTarget(cam, tex, kWidth, heightOf(tex, kWidth), spec);
    const std::optional<Detection> d = det.detect(s.image, cam).find(0);
    z.push_back(d && d->cMo ? std::optional<double>(d->cMo->t.z()) : std::nullopt);
  }
  return z;
}

StereoJitter stereoJitter(int frames) {
  using namespace detector;
  const cv::Mat tex = testing::loadMedia(kPoster);
  StereoRig rig;
  rig.left = rig.right = testing::sceneCamera();
  rig.lMr = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.12, 0, 0));
  Detector det;
  det.addObject(textureObject("poster", tex, kWidth));
  StereoJitter out;
  out.lMo_truth = Pose::fromRotationVector({0.3, 0.2, -0.1}, {0.06, 0.01, 0.8});
  const Pose rMo = rig.lMr.inverse() * out.lMo_truth;
  for (int i = 0; i < frames; ++i) {
    testing::SceneSpec sl, sr;
    sl.cMo = out.lMo_truth;
    sr.cMo = rMo;
    sl.seed = 500 + 2 * static_cast<uint64_t>(i);
    sr.seed = 501 + 2 * static_cast<uint64_t>(i);
    const cv::Mat L = testing::renderTarget(rig.left, tex, kWidth, heightOf(tex, kWidth), sl).image;
    const cv::Mat R = testing::renderTarget(rig.right, tex, kWidth, heightOf(tex, kWidth), sr).image;
    const StereoDetectionResult r = det.detectStereo(L, R, rig);
    StereoJitterFrame f;
    f.ok = r.ok;
    f.error = r.error;
    f.objects = r.objects.size();
    if (r.ok && r.objects.size() == 1) {
      const StereoDetection& s = r.objects[0];
      f.fused = s.fused.lMo.has_value();
      f.both = f.fused && s.fused.eyes == EyesUsed::kBoth;
      if (f.both) {
        f.left = s.left.cMo;
        f.right_in_left = rig.lMr * *s.right.cMo;
        f.lMo = s.fused.lMo;
      }
    }
    out.frames.push_back(f);
  }
  return out;
}

StereoJitter::Summary StereoJitter::summary() const {
  std::vector<Pose> left, right, fused;
  for (const StereoJitterFrame& f : frames) {
    if (!f.both) continue;
    left.push_back(*f.left);
    right.push_back(*f.right_in_left);
    fused.push_back(*f.lMo);
  }
  Summary s;
  s.both = static_cast<int>(fused.size());
  s.left_m = positionJitter(left);
  s.right_m = positionJitter(right);
  s.fused_m = positionJitter(fused);
  return s;
}

namespace {

using Vec2 = Eigen::Vector2d;
constexpr double kFoundPx = 3.0;
constexpr int kHardScenes = 10;

/// Largest corner error of H against the truth, over the allowed corner relabellings
/// (identity only, or the 8 symmetries of a square texture).
double cornerError(const Eigen::Matrix3d& H, const cv::Mat& tex, const Corners& truth, bool square_symmetry) {
  const Corners c = {Vec2(-0.5, -0.5), Vec2(tex.cols - 0.5, -0.5), Vec2(tex.cols - 0.5, tex.rows - 0.5),
                     Vec2(-0.5, tex.rows - 0.5)};
  double best = 1e18;
  for (int flip = 0; flip < (square_symmetry ? 2 : 1); ++flip) {
    for (int rot = 0; rot < (square_symmetry ? 4 : 1); ++rot) {
      double e = 0;
      for (int i = 0; i < 4; ++i) {
        const int j = flip ? (rot - i + 4) % 4 : (rot + i) % 4;
        e = std::max(e, (detector::applyHomography(H, c[i]) - truth[j]).norm());
      }
      best = std::min(best, e);
    }
  }
  return best;
}

/// Instances (of up to max_instances) within kFoundPx of distinct true targets.
int countFound(const detector::MatchResult& r, const cv::Mat& tex, const std::vector<Corners>& truth,
               bool square_symmetry) {
  std::vector<bool> hit(truth.size(), false);
  int found = 0;
  for (const auto& inst : r.instances)
    for (size_t t = 0; t < truth.size(); ++t)
      if (!hit[t] && cornerError(inst.H, tex, truth[t], square_symmetry) < kFoundPx) {
        hit[t] = true;
        ++found;
        break;
      }
  return found;
}

/// Both matchers on one scene; the reference index (the same for both matcher types) is built
/// once per texture.
struct HardCaseMatcher {
  std::map<const uchar*, detector::ReferenceIndex> indices;

  void run(const cv::Mat& tex, const cv::Mat& image, const std::vector<Corners>& truth, int max_instances,
           bool square_symmetry, HardCaseRow* row) {
    using namespace detector;
    MatchOptions paper, ratio;
    paper.max_instances = ratio.max_instances = max_instances;
    ratio.matcher = MatcherType::kRatio;
    auto it = indices.find(tex.data);
    if (it == indices.end())
      it = indices.emplace(tex.data, buildReferenceIndex(extractSift(tex, SiftOptions{}), {}, paper)).first;
    const Features f = extractSift(image, SiftOptions{});
    const GridIndex grid(f.keypoints, f.image_size);
    row->paper += countFound(matchObject(it->second, f, grid, paper), tex, truth, square_symmetry);
    row->ratio += countFound(matchObject(it->second, f, grid, ratio), tex, truth, square_symmetry);
    row->total += static_cast<int>(truth.size());
  }
};

/// Single-target category: random visible poses in [dmin, dmax] m, tilt <= max_tilt.
HardCaseRow singleTarget(HardCaseMatcher& m, const std::string& category, const std::vector<std::string>& textures,
                         double width_m, double dmin, double dmax, double max_tilt_rad, double blur_px,
                         bool square_symmetry, uint64_t seed) {
  HardCaseRow row{category};
  const Intrinsics cam = testing::sceneCamera();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> angle(0, M_PI);
  for (int k = 0; k < kHardScenes; ++k) {
    const cv::Mat tex = testing::loadMedia(textures[static_cast<size_t>(k) % textures.size()]);
    const double h = width_m * tex.rows / tex.cols;
    testing::SceneSpec spec;
    spec.cMo = testing::randomVisiblePose(rng, cam, width_m, h, dmin, dmax, max_tilt_rad);
    spec.motion_blur_px = blur_px;
    spec.motion_blur_angle_rad = angle(rng);
    spec.seed = seed * 100 + static_cast<uint64_t>(k);
    const auto scene = testing::renderTarget(cam, tex, width_m, h, spec);
    m.run(tex, scene.image, {scene.corners}, 1, square_symmetry, &row);
  }
  return row;
}

HardCaseRow multipleInstances(HardCaseMatcher& m, uint64_t seed) {
  HardCaseRow row{"3 instances"};
  const Intrinsics cam = testing::sceneCamera();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  const auto& names = testing::targetTextures();
  for (int k = 0; k < kHardScenes; ++k) {
    const cv::Mat tex = testing::loadMedia(names[static_cast<size_t>(k) % names.size()]);
    std::vector<sim::TexturedPlane> planes;
    for (int c = 0; c < 3; ++c) {
      sim::TexturedPlane p;
      p.texture = tex;
      p.width_m = 0.11;
      p.height_m = p.width_m * tex.rows / tex.cols;
      p.cMp = Pose(axisAngle(Eigen::Vector3d(u(rng), u(rng), 0), 0.5 * std::abs(u(rng))) *
                       axisAngle(Eigen::Vector3d::UnitZ(), M_PI * u(rng)),
                   Eigen::Vector3d((c - 1) * 0.17, 0.05 * u(rng), 0.65 + 0.1 * u(rng)));
      planes.push_back(p);
    }
    testing::SceneSpec spec;
    spec.seed = seed * 100 + static_cast<uint64_t>(k);
    spec.motion_blur_px = 1.5;
    spec.motion_blur_angle_rad = M_PI * u(rng);
    const auto scene = testing::renderTargets(cam, planes, spec);
    m.run(tex, scene.image, scene.all_corners, 3, false, &row);
  }
  return row;
}

}  // namespace

std::vector<HardCaseRow> hardCases() {
  const auto& targets = testing::targetTextures();
  HardCaseMatcher m;
  std::vector<HardCaseRow> rows;
  // 20 cm wide target at 1.4-1.8 m: 60-80 px wide in the image.
  rows.push_back(singleTarget(m, "small (60-80 px)", targets, 0.2, 1.4, 1.8, 30 * kDeg, 0, false, 1));
  rows.push_back(singleTarget(m, "motion blur 8 px", targets, 0.2, 0.4, 0.9, 30 * kDeg, 8, false, 2));
  rows.push_back(singleTarget(m, "repeated motif", {"hard/tiled_motif.png"}, 0.2, 0.4, 0.9, 30 * kDeg, 0, false, 3));
  // A pattern with the symmetries of the square is found up to them: corners may be relabelled.
  rows.push_back(singleTarget(m, "symmetric (mod D4)", {"hard/symmetric.png"}, 0.2, 0.4, 0.9, 30 * kDeg, 0, true, 4));
  rows.push_back(multipleInstances(m, 5));
  return rows;
}

FalsePositiveRun falsePositivesOnClutter(int frames, uint64_t noise_seed) {
  using namespace detector;
  const std::vector<std::string>& targets = testing::targetTextures();
  Detector det;
  for (const auto& t : targets) det.addObject(textureObject(t, testing::loadMedia(t), 0.2));
  const Intrinsics cam = testing::sceneCamera();
  FalsePositiveRun out;
  out.frames = frames;
  out.objects = targets.size();
  std::mt19937_64 rng(noise_seed);
  sim::Degradation noise;
  noise.noise_sigma = 2.0;  // sensor noise, as in the rendered target scenes
  for (int i = 0; i < frames; ++i) {
    cv::Mat img = testing::clutterBackground(100000 + static_cast<uint64_t>(i));
    sim::degrade(img, noise, rng);
    const DetectionResult r = det.detect(img, cam);
    if (!r.ok) {
      out.failed.push_back("frame " + std::to_string(i) + ": " + r.error);
      continue;
    }
    out.total_ms += r.time_ms.total;
    for (const Detection& d : r.detections) {
      if (d.found) {
        ++out.detections;
        out.false_detections.push_back("frame " + std::to_string(i) + ": false detection of " +
                                       targets[static_cast<size_t>(d.object)] + " (" + std::to_string(d.inliers) +
                                       " inliers)");
      } else if (d.sanity != SanityStatus::kOk) {
        ++out.sanity_rejected;
      }
    }
  }
  return out;
}

}  // namespace refgrasp::eval
