#include "grasp/grasp_log.h"

#include <cmath>
#include <filesystem>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "detector/draw.h"
#include "detector/sanity.h"
#include "robot/files/frame_json.h"

namespace refgrasp::grasp_app {

namespace fs = std::filesystem;

namespace {

const char* headMode(robot::HeadMode m) {
  return m == robot::HeadMode::kPosition ? "position" : "velocity";
}

const char* gripperCommand(robot::GripperCommand g) {
  switch (g) {
    case robot::GripperCommand::kNone: return "none";
    case robot::GripperCommand::kOpen: return "open";
    case robot::GripperCommand::kClose: return "close";
  }
  return "?";
}

Json vec(const Eigen::VectorXd& v) {
  Json a = Json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) a.push_back(v[i]);
  return a;
}

Json optionalPose(const std::optional<Pose>& p) { return p ? poseJson(*p) : Json(nullptr); }

// What the detector saw of the target in this frame (left eye), when it ran: formats.md
// "control.jsonl".
Json detectorJson(const servo::TargetObservation& o) {
  if (!o.detector_stats) return Json(nullptr);
  const detector::ObjectStats& st = *o.detector_stats;
  const detector::MatchRejects& r = st.rejected;
  Json j = {{"scene_features", st.scene_features},
            {"global_matches", st.global_matches},
            {"hypotheses", st.hypotheses_evaluated},
            {"candidates", st.candidates},
            {"views", st.views_matched},
            {"weak_regions", st.weak_regions},
            {"rejected", {{"too_few_local_matches", r.too_few_local_matches},
                          {"too_few_inliers", r.too_few_inliers},
                          {"not_significant", r.not_significant},
                          {"implausible_homography", r.implausible_homography},
                          {"narrow_inlier_spread", r.narrow_inlier_spread}}},
            {"miss", detector::missReasonName(st.miss)},
            {"sanity", detector::sanityStatusName(st.sanity)}};
  if (o.detector_best && o.detector_best->found) {
    const detector::Detection& d = *o.detector_best;
    j["found"] = {{"inliers", d.inliers}, {"log10_nfa", d.log10_nfa}, {"correlation", d.correlation},
                  {"pose_rms_px", d.pose_rms_px}};
  } else {
    j["found"] = nullptr;
  }
  return j;
}

}  // namespace

Json GraspLog::line(const servo::GraspIteration& it, const std::string& target,
                    std::optional<int64_t> frame) {
  Json j;
  j["t"] = it.t;
  j["phase"] = toString(it.phase);
  j["detail"] = it.detail;
  j["event"] = it.event;
  j["observed"] = toString(it.observed);
  j["confirmed"] = it.confirmed;
  j["target_driven"] = it.target_driven;
  j["frame"] = frame ? Json(*frame) : Json(nullptr);
  j["frame_index"] = it.frame ? Json(it.frame->index) : Json(nullptr);
  j["frame_stamp"] = it.frame ? Json(it.frame->stamp) : Json(nullptr);
  j["source"] = it.observation.source;
  j["cMo"] = optionalPose(it.observation.cMo);
  std::optional<Pose> truth;
  for (const robot::ObjectTruth& t : it.truth)
    if (t.object == target) truth = t.cMo;
  j["truth_cMo"] = it.frame ? optionalPose(truth) : Json(nullptr);
  if (it.frame && truth && it.observation.cMo) {
    j["cMo_error"] = {{"position_m", translationError(*it.observation.cMo, *truth)},
                      {"rotation_rad", rotationError(*it.observation.cMo, *truth)}};
  }
  j["detector"] = it.frame ? detectorJson(it.observation) : Json(nullptr);
  if (it.look_started) {
    const servo::SearchLook& l = *it.look_started;
    j["look"] = Json{{"index", l.index},
                     {"camera_xy", {l.camera_w.x(), l.camera_w.y()}},
                     {"bearing_rad", l.bearing_rad},
                     {"half_fov_rad", l.half_fov_rad},
                     {"range_m", l.range_m},
                     {"expected_gain", l.expected_gain}};
  } else {
    j["look"] = nullptr;
  }
  j["wMo"] = optionalPose(it.wMo);
  j["bMe_desired"] = optionalPose(it.bMe_desired);
  j["distance_m"] = it.distance_m;
  j["error"] = {{"position_m", it.error_position_m}, {"rotation_rad", it.error_rotation_rad}};
  const robot::RobotCommand& c = it.command;
  j["command"] = {{"base_v_mps", c.base_v_mps},   {"base_w_radps", c.base_w_radps},
                  {"head_mode", headMode(c.head_mode)}, {"pan", c.pan},
                  {"tilt", c.tilt},               {"arm_qdot_radps", vec(c.arm_qdot_radps)},
                  {"gripper", gripperCommand(c.gripper)}};
  j["state"] = files::robotStateToJson(it.state);
  return j;
}

GraspLog::GraspLog(const std::string& dir, const StereoRig& rig, const std::string& source,
                   const std::string& target_name)
    : dir_(dir), target_(target_name) {
  files::RecordingOptions o;
  o.source = source;
  o.created_by = "enon_grasp";
  o.fsync = false;  // a log, not a capture to protect from power loss; the loop keeps its pace
  recording_ = files::RecordingWriter::createStereo(dir, rig, o);
  const fs::path p = fs::path(dir) / "control.jsonl";
  control_.open(p);
  if (!control_) throw ConfigError(p.string(), "cannot create");
}

bool GraspLog::add(const servo::GraspIteration& it, const Json& extra, std::string* error) {
  std::optional<int64_t> frame;
  if (it.frame && !it.frame->left.empty()) {
    const files::WriteStatus w = recording_->write(*it.frame, &it.state);
    if (!w.ok) {
      *error = w.error;
      return false;
    }
    frame = recording_->frames() - 1;
  }
  Json j = line(it, target_, frame);
  for (auto e = extra.begin(); e != extra.end(); ++e) j[e.key()] = e.value();
  control_ << j.dump() << '\n';
  control_.flush();
  if (!control_) {
    *error = (fs::path(dir_) / "control.jsonl").string() + ": cannot write";
    return false;
  }
  return true;
}

GraspVideo::GraspVideo(const std::string& path, const detector::ObjectModel& target,
                       const Intrinsics& camera, double fps)
    : path_(path), target_(target), camera_(camera), fps_(std::clamp(fps, 1.0, 120.0)) {}

cv::Mat GraspVideo::draw(const servo::GraspIteration& it, const detector::ObjectModel& target,
                         const Intrinsics& camera) {
  cv::Mat img;
  const cv::Mat& src = it.frame->left;
  if (src.channels() == 1) {
    cv::cvtColor(src, img, cv::COLOR_GRAY2BGR);
  } else {
    img = src.clone();
  }
  const servo::TargetObservation& o = it.observation;
  const bool confirmed = o.status == servo::TargetStatus::kConfirmed;
  const cv::Scalar outline = confirmed ? cv::Scalar(0, 255, 255) : cv::Scalar(0, 140, 255);
  if (o.corners) {
    std::vector<cv::Point> poly;
    for (const Eigen::Vector2d& c : *o.corners) poly.emplace_back(cvRound(c.x()), cvRound(c.y()));
    cv::polylines(img, poly, true, outline, 2, cv::LINE_AA);
  }
  if (o.cMo && target.hasPose()) {
    const servo::ObjectExtent e = servo::objectExtent(target);
    detector::drawAxes(img, camera, *o.cMo, 0.5 * (e.max_o - e.min_o).maxCoeff());
  }
  char line1[128], line2[128];
  std::snprintf(line1, sizeof(line1), "t=%.2f s  %s/%s  target %s", it.t, toString(it.phase),
                it.detail.c_str(), toString(o.status));
  if (it.error_position_m >= 0) {
    std::snprintf(line2, sizeof(line2), "error %.1f mm / %.2f deg   gripper to grasp %.3f m",
                  1000 * it.error_position_m, it.error_rotation_rad * 180 / M_PI, it.distance_m);
  } else {
    line2[0] = '\0';
  }
  for (const auto& [text, y] : {std::pair<const char*, int>{line1, 20}, {line2, 42}}) {
    cv::putText(img, text, {8, y}, cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
    cv::putText(img, text, {8, y}, cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(255, 255, 255), 1,
                cv::LINE_AA);
  }
  return img;
}

void GraspVideo::showOutside(const sim::SimEnon& sim, const robot::EnonModel& model) {
  outside_ = std::make_unique<Outside>();
  outside_->sim = &sim;
  outside_->model = model;
  // The simulated odometry starts at the true start pose in the world frame: no offset.
  outside_->map = std::make_unique<TopDownMap>(sim.world(), robot::PlanarPose{});
  outside_->state.base_radius_m = model.base.body_radius_m;
}

void GraspVideo::observe(const servo::GraspIteration& it) {
  Outside& o = *outside_;
  const robot::PlanarPose b = o.sim->trueBasePose();
  const Eigen::Vector2d p(b.x_m, b.y_m);
  // The path keeps a point every 2 cm travelled.
  if (o.state.path_w.empty() || (p - o.state.path_w.back()).norm() >= 0.02) o.state.path_w.push_back(p);
  o.state.base_w = b;
  if (it.look_started) o.state.looks.push_back(*it.look_started);
  if (it.belief) o.belief = it.belief;
}

cv::Mat GraspVideo::externalPanel() {
  Outside& o = *outside_;
  const Pose wMc = o.follow.update(o.sim->trueBasePose(), o.sim->time());
  const std::vector<sim::RobotPart> parts = sim::robotParts(o.model, o.sim->shapes(), o.sim->wMb(), o.sim->wMc());
  cv::Mat img = sim::renderExternalView(o.follow.options().camera, o.sim->world(), wMc, parts);
  const char* label = "outside: camera following the robot";
  cv::putText(img, label, {8, 20}, cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
  cv::putText(img, label, {8, 20}, cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  return img;
}

cv::Mat GraspVideo::mapPanel() const {
  MapFrame f = outside_->state;
  f.belief = outside_->belief.get();
  return outside_->map->draw(outside_->sim->world(), f);
}

cv::Mat GraspVideo::sideBySide(const std::vector<cv::Mat>& panels) {
  std::vector<cv::Mat> scaled;
  for (const cv::Mat& p : panels) {
    if (p.rows == panels.front().rows) {
      scaled.push_back(p);
      continue;
    }
    cv::Mat s;
    const double k = static_cast<double>(panels.front().rows) / p.rows;
    cv::resize(p, s, cv::Size(static_cast<int>(std::lround(p.cols * k)), panels.front().rows), 0, 0, cv::INTER_AREA);
    scaled.push_back(s);
  }
  cv::Mat out;
  cv::hconcat(scaled, out);
  return out;
}

bool GraspVideo::add(const servo::GraspIteration& it, std::string* error) {
  if (outside_) observe(it);
  if (!it.frame || it.frame->left.empty()) return true;
  cv::Mat img = draw(it, target_, camera_);
  if (outside_) img = sideBySide({img, externalPanel(), mapPanel()});
  if (!writer_.isOpened()) {
    for (const char* fcc : {"avc1", "mp4v", "MJPG"}) {
      try {
        writer_.open(path_, cv::CAP_FFMPEG, cv::VideoWriter::fourcc(fcc[0], fcc[1], fcc[2], fcc[3]),
                     fps_, img.size());
      } catch (const cv::Exception&) {
      }
      if (writer_.isOpened()) break;
    }
    if (!writer_.isOpened()) {
      *error = path_ + ": cannot open a video writer (no H.264, MPEG-4 or MJPEG encoder for it)";
      return false;
    }
  }
  writer_.write(img);
  ++frames_;
  return true;
}

}  // namespace refgrasp::grasp_app
