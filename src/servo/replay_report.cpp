#include "servo/replay_report.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <thread>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/image_io.h"
#include "core/error.h"
#include "core/json.h"
#include "detector/detection_json.h"
#include "detector/draw.h"
#include "servo/surface_model.h"

namespace refgrasp::servo {

namespace fs = std::filesystem;

namespace {

constexpr double kDeg = 180.0 / M_PI;

// detect_object's detection fields (detector/detection_json.h): "found", then "homography",
// "corners", "R", "t", "inliers" as detected; a tracked pose (or a fused stereo pose) replaces R
// and t in place, corners projected from it stand in when there is no detection in this image; a
// tracked 2D-only object gives its tracked homography and corners.
void detectionFields(const ObjectFrame& o, Json* j) {
  if (o.detection.found) {
    *j = detector::detectionJson(o.detection, *j);
  } else {
    (*j)["found"] = o.mode != TrackMode::kLost;
    if (o.H) (*j)["homography"] = matrixJson(*o.H / (*o.H)(2, 2));
    if (o.corners) {
      (*j)["corners"] = Json::array();
      for (const auto& c : *o.corners) (*j)["corners"].push_back({c.x(), c.y()});
    }
  }
  if (o.cMo) putPose(j, *o.cMo);
}

Eigen::Quaterniond quaternion(const Pose& P) {
  Eigen::Quaterniond q(P.R);
  q.normalize();
  if (q.w() < 0) q.coeffs() *= -1;  // one of the two equivalent quaternions, always the same
  return q;
}

std::string tumLine(Seconds stamp, const Pose& P) {
  const Eigen::Quaterniond q = quaternion(P);
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%.6f %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", stamp, P.t.x(),
                P.t.y(), P.t.z(), q.x(), q.y(), q.z(), q.w());
  return buf;
}

std::string num(double v, const char* fmt = "%.9g") {
  char buf[48];
  std::snprintf(buf, sizeof(buf), fmt, v);
  return buf;
}

std::string safeName(const std::string& s) {
  std::string out;
  for (char c : s) out += std::isalnum(static_cast<unsigned char>(c)) || c == '-' ? c : '_';
  return out;
}

struct Stats {
  double median = 0, p95 = 0, max = 0;
};

Stats stats(std::vector<double> v) {
  Stats s;
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  const auto at = [&](double q) {
    return v[std::min(v.size() - 1, static_cast<size_t>(std::floor(q * (v.size() - 1) + 0.5)))];
  };
  s.median = at(0.5);
  s.p95 = at(0.95);
  s.max = v.back();
  return s;
}

Json statsJson(const Stats& s) { return {{"median", s.median}, {"p95", s.p95}, {"max", s.max}}; }

cv::Scalar modeColour(TrackMode m) {
  switch (m) {
    case TrackMode::kDetect: return {0, 170, 0};
    case TrackMode::kTrack: return {220, 120, 0};
    case TrackMode::kLost: return {0, 0, 220};
  }
  return {0, 0, 0};
}

// Half the larger side of an object's pattern (several views: of the largest), metres: the
// overlay's axis length.
double axisLength(const detector::ObjectModel& m) {
  double len = 0;
  for (const std::array<Eigen::Vector3d, 4>& c : patternQuads(m))
    len = std::max(len, 0.5 * std::max((c[1] - c[0]).norm(), (c[3] - c[0]).norm()));
  return len;
}

}  // namespace

struct ReplayReport::Sample {
  int64_t frame;
  Seconds stamp;
  int object;
  TrackMode mode;
  std::optional<Pose> cMo, truth;
};

// ---- overlay -----------------------------------------------------------------------------------

cv::Mat drawOverlay(const cv::Mat& image, const ReplayFrame& r, const detector::Detector& det,
                    const Intrinsics& cam) {
  cv::Mat img;
  if (image.channels() == 1)
    cv::cvtColor(image, img, cv::COLOR_GRAY2BGR);
  else
    img = image.clone();
  const auto pt = [](const Eigen::Vector2d& p) { return cv::Point(cvRound(p.x()), cvRound(p.y())); };
  const bool several = r.objects.size() > 1;
  for (const ObjectFrame& o : r.objects) {
    if (o.corners) {
      std::vector<cv::Point> poly;
      for (const auto& c : *o.corners) poly.push_back(pt(c));
      cv::polylines(img, poly, true, o.mode == TrackMode::kTrack ? cv::Scalar(255, 255, 0)
                                                                 : cv::Scalar(0, 255, 255),
                    2, cv::LINE_AA);
      if (several)
        cv::putText(img, o.name, poly[0] + cv::Point(4, -6), cv::FONT_HERSHEY_SIMPLEX, 0.45,
                    cv::Scalar(0, 255, 255), 1, cv::LINE_AA);
    }
    const double len = axisLength(det.object(o.object));
    if (o.cMo && len > 0) detector::drawAxes(img, cam, *o.cMo, len);
  }
  char head[96];
  std::snprintf(head, sizeof(head), "frame %lld  t %.3f s", static_cast<long long>(r.frame),
                r.stamp.stamp);
  cv::rectangle(img, cv::Rect(0, 0, img.cols, 22 + 18 * static_cast<int>(r.objects.size())),
                cv::Scalar(0, 0, 0), cv::FILLED);
  cv::putText(img, head, {8, 16}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(255, 255, 255), 1,
              cv::LINE_AA);
  int y = 34;
  for (const ObjectFrame& o : r.objects) {
    const std::string text = (several ? o.name + ": " : std::string()) + toString(o.mode) +
                             (r.ok ? "" : " (frame error)");
    cv::Scalar c = modeColour(o.mode);
    c = cv::Scalar(std::min(255.0, c[0] + 60), std::min(255.0, c[1] + 60), std::min(255.0, c[2] + 60));
    cv::putText(img, text, {8, y}, cv::FONT_HERSHEY_SIMPLEX, 0.5, c, 1, cv::LINE_AA);
    y += 18;
  }
  return img;
}

// ---- plot --------------------------------------------------------------------------------------

namespace {

struct Series {
  std::string title;
  std::vector<std::optional<double>> est, truth;  ///< per sample
};

// One object's block of panels: mode strip, then one panel per series.
cv::Mat drawObjectPlot(const std::string& name, const std::vector<Seconds>& t,
                       const std::vector<TrackMode>& modes, const std::vector<Series>& series) {
  const int W = 1280, left = 96, right = 16, strip = 16, panel = 104, gap = 10, top = 26;
  const int H = top + strip + gap + static_cast<int>(series.size()) * (panel + gap) + 28;
  cv::Mat img(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  const int pw = W - left - right;
  const double t0 = t.empty() ? 0 : t.front(), t1 = t.empty() ? 1 : t.back();
  const double span = t1 > t0 ? t1 - t0 : 1;
  const auto xpx = [&](double ti) { return left + static_cast<int>(std::lround((ti - t0) / span * pw)); };
  // Half-way between neighbouring samples: the extent of sample i on the time axis.
  const auto extent = [&](size_t i) {
    const double a = i > 0 ? 0.5 * (t[i - 1] + t[i]) : t[i] - (t.size() > 1 ? 0.5 * (t[1] - t[0]) : 0.5);
    const double b = i + 1 < t.size() ? 0.5 * (t[i] + t[i + 1])
                                      : t[i] + (t.size() > 1 ? 0.5 * (t[i] - t[i - 1]) : 0.5);
    return std::make_pair(std::max(left, xpx(a)), std::min(left + pw, std::max(xpx(a) + 1, xpx(b))));
  };
  int n_detect = 0, n_track = 0, n_lost = 0;
  for (TrackMode m : modes) (m == TrackMode::kDetect ? n_detect : m == TrackMode::kTrack ? n_track : n_lost)++;
  const std::string title = name + ":  detect " + std::to_string(n_detect) + ", track " +
                            std::to_string(n_track) + ", lost " + std::to_string(n_lost) + " frames";
  cv::putText(img, title, {left, 18}, cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::putText(img, "detect", {W - 260, 18}, cv::FONT_HERSHEY_SIMPLEX, 0.45, modeColour(TrackMode::kDetect), 1, cv::LINE_AA);
  cv::putText(img, "track", {W - 190, 18}, cv::FONT_HERSHEY_SIMPLEX, 0.45, modeColour(TrackMode::kTrack), 1, cv::LINE_AA);
  cv::putText(img, "lost", {W - 130, 18}, cv::FONT_HERSHEY_SIMPLEX, 0.45, modeColour(TrackMode::kLost), 1, cv::LINE_AA);
  cv::putText(img, "mode", {8, top + 12}, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  for (size_t i = 0; i < t.size(); ++i) {
    const auto [a, b] = extent(i);
    cv::rectangle(img, cv::Rect(a, top, std::max(1, b - a), strip), modeColour(modes[i]), cv::FILLED);
  }
  int y0 = top + strip + gap;
  for (const Series& s : series) {
    const cv::Rect box(left, y0, pw, panel);
    for (size_t i = 0; i < t.size(); ++i)  // lost frames shaded
      if (modes[i] == TrackMode::kLost) {
        const auto [a, b] = extent(i);
        cv::rectangle(img, cv::Rect(a, y0, std::max(1, b - a), panel), cv::Scalar(225, 225, 255), cv::FILLED);
      }
    double lo = 1e300, hi = -1e300;
    for (const auto* v : {&s.est, &s.truth})
      for (const auto& x : *v)
        if (x) lo = std::min(lo, *x), hi = std::max(hi, *x);
    if (lo > hi) lo = -1, hi = 1;
    if (hi - lo < 1e-9) lo -= 1e-3, hi += 1e-3;
    const double pad = 0.06 * (hi - lo);
    lo -= pad;
    hi += pad;
    const auto ypx = [&](double v) { return y0 + panel - static_cast<int>(std::lround((v - lo) / (hi - lo) * panel)); };
    cv::rectangle(img, box, cv::Scalar(160, 160, 160), 1);
    if (lo < 0 && hi > 0) cv::line(img, {left, ypx(0)}, {left + pw, ypx(0)}, cv::Scalar(220, 220, 220), 1);
    const auto polyline = [&](const std::vector<std::optional<double>>& v, const cv::Scalar& c, int thick) {
      for (size_t i = 1; i < v.size(); ++i)
        if (v[i] && v[i - 1])
          cv::line(img, {xpx(t[i - 1]), ypx(*v[i - 1])}, {xpx(t[i]), ypx(*v[i])}, c, thick, cv::LINE_AA);
      for (size_t i = 0; i < v.size(); ++i)  // isolated samples still show
        if (v[i] && (i == 0 || !v[i - 1]) && (i + 1 == v.size() || !v[i + 1]))
          cv::circle(img, {xpx(t[i]), ypx(*v[i])}, 2, c, cv::FILLED);
    };
    polyline(s.truth, cv::Scalar(150, 150, 150), 3);
    polyline(s.est, cv::Scalar(60, 30, 0), 1);
    cv::putText(img, s.title, {8, y0 + 16}, cv::FONT_HERSHEY_SIMPLEX, 0.42, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    cv::putText(img, num(hi - pad, "%.4g"), {8, y0 + 40}, cv::FONT_HERSHEY_SIMPLEX, 0.38, cv::Scalar(90, 90, 90), 1, cv::LINE_AA);
    cv::putText(img, num(lo + pad, "%.4g"), {8, y0 + panel - 4}, cv::FONT_HERSHEY_SIMPLEX, 0.38, cv::Scalar(90, 90, 90), 1, cv::LINE_AA);
    y0 += panel + gap;
  }
  for (int k = 0; k <= 5; ++k) {  // time axis
    const double ti = t0 + span * k / 5.0;
    const int x = xpx(ti);
    cv::line(img, {x, y0 - gap}, {x, y0 - gap + 5}, cv::Scalar(0, 0, 0), 1);
    cv::putText(img, num(ti - t0, "%.2f") + (k == 5 ? " s" : ""), {x - 14, y0 + 12},
                cv::FONT_HERSHEY_SIMPLEX, 0.38, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  return img;
}

}  // namespace

// ---- report ------------------------------------------------------------------------------------

ReplayReport::ReplayReport(const std::string& outdir, const detector::Detector& detector,
                           const ReplayReportOptions& options)
    : dir_(outdir), det_(detector), opt_(options) {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec || !fs::is_directory(dir_)) throw ConfigError(dir_, "cannot create the output folder");
  if (opt_.png_frames) {
    fs::create_directories(fs::path(dir_) / "frames", ec);
    if (ec) throw ConfigError(dir_ + "/frames", "cannot create: " + ec.message());
  }
  const auto open = [&](std::ofstream& f, const std::string& name) {
    f.open(fs::path(dir_) / name, std::ios::binary | std::ios::trunc);
    if (!f) throw ConfigError((fs::path(dir_) / name).string(), "cannot open for writing");
  };
  open(jsonl_, "poses.jsonl");
  open(csv_, "poses.csv");
  const bool several = det_.objectCount() > 1;
  csv_ << "frame,stamp," << (several ? "object," : "")
       << "mode,tx,ty,tz,qx,qy,qz,qw,rx_deg,ry_deg,rz_deg,inliers,truth_tx,truth_ty,truth_tz,"
          "truth_rx_deg,truth_ry_deg,truth_rz_deg,error_translation_mm,error_rotation_deg\n";
  for (int id = 0; id < det_.objectCount(); ++id) {
    const std::string suffix = several ? "_" + safeName(det_.object(id).name) : "";
    tum_names_.push_back("trajectory" + suffix + ".tum");
    truth_names_.push_back("truth" + suffix + ".tum");
    tum_.push_back(std::make_unique<std::ofstream>());
    truth_tum_.push_back(std::make_unique<std::ofstream>());
    open(*tum_.back(), tum_names_.back());
    *tum_.back() << "# cMo of " << det_.object(id).name
                 << " (object in camera frame), TUM: stamp tx ty tz qx qy qz qw\n";
  }
}

ReplayReport::~ReplayReport() = default;

std::vector<std::string> ReplayReport::jsonLines(const ReplayFrame& r, bool tag_objects) {
  std::vector<std::string> lines;
  for (const ObjectFrame& o : r.objects) {
    Json j = {{"frame", r.frame}, {"index", r.stamp.index}, {"stamp", r.stamp.stamp}};
    if (tag_objects) j["object"] = o.name;
    j["mode"] = toString(o.mode);
    detectionFields(o, &j);
    if (!o.eyes.empty()) j["eyes"] = o.eyes;
    if (o.mode != TrackMode::kLost) j["confirmed"] = o.confirmed;
    if (o.mode == TrackMode::kTrack)
      j["track"] = {{"features", o.quality.features},
                    {"projection_error_px", o.quality.projection_error_px}};
    if (o.mode == TrackMode::kTrack && o.H) j["track"]["correlation"] = o.quality.correlation;
    if (o.truth_cMo) {
      j["truth"] = poseJson(*o.truth_cMo);
      if (o.cMo)
        j["error"] = {{"translation_m", translationError(*o.cMo, *o.truth_cMo)},
                      {"rotation_deg", rotationError(*o.cMo, *o.truth_cMo) * kDeg}};
    }
    if (!r.ok) j["error_text"] = r.error;
    lines.push_back(j.dump());
  }
  return lines;
}

bool ReplayReport::add(const ReplayFrame& r, const cv::Mat& image, const Intrinsics& camera,
                       std::string* error) {
  const bool several = det_.objectCount() > 1;
  if (samples_.empty()) first_stamp_ = r.stamp.stamp;
  for (const std::string& line : jsonLines(r, several)) jsonl_ << line << "\n";
  for (const ObjectFrame& o : r.objects) {
    samples_.push_back({r.frame, r.stamp.stamp, o.object, o.mode, o.cMo, o.truth_cMo});
    csv_ << r.frame << "," << num(r.stamp.stamp, "%.6f") << "," << (several ? o.name + "," : "")
         << toString(o.mode) << ",";
    if (o.cMo) {
      const Eigen::Quaterniond q = quaternion(*o.cMo);
      const Eigen::Vector3d rv = o.cMo->rotationVector() * kDeg;
      csv_ << num(o.cMo->t.x()) << "," << num(o.cMo->t.y()) << "," << num(o.cMo->t.z()) << ","
           << num(q.x()) << "," << num(q.y()) << "," << num(q.z()) << "," << num(q.w()) << ","
           << num(rv.x()) << "," << num(rv.y()) << "," << num(rv.z()) << ",";
      *tum_[static_cast<size_t>(o.object)] << tumLine(r.stamp.stamp, *o.cMo);
    } else {
      csv_ << ",,,,,,,,,,";
    }
    csv_ << (o.detection.found ? std::to_string(o.detection.inliers) : "") << ",";
    if (o.truth_cMo) {
      const Eigen::Vector3d rv = o.truth_cMo->rotationVector() * kDeg;
      csv_ << num(o.truth_cMo->t.x()) << "," << num(o.truth_cMo->t.y()) << ","
           << num(o.truth_cMo->t.z()) << "," << num(rv.x()) << "," << num(rv.y()) << ","
           << num(rv.z()) << ",";
      std::ofstream& tt = *truth_tum_[static_cast<size_t>(o.object)];
      if (!tt.is_open()) {
        tt.open(fs::path(dir_) / truth_names_[static_cast<size_t>(o.object)], std::ios::trunc);
        tt << "# ground-truth cMo of " << o.name << ", TUM: stamp tx ty tz qx qy qz qw\n";
      }
      tt << tumLine(r.stamp.stamp, *o.truth_cMo);
      if (o.cMo)
        csv_ << num(translationError(*o.cMo, *o.truth_cMo) * 1e3) << ","
             << num(rotationError(*o.cMo, *o.truth_cMo) * kDeg);
      else
        csv_ << ",";
    } else {
      csv_ << ",,,,,,,";
    }
    csv_ << "\n";
  }
  if (!r.ok) {
    ++failed_;
    if (errors_.size() < 20) errors_.push_back("frame " + std::to_string(r.frame) + ": " + r.error);
  }
  time_ms_.push_back(r.time_ms);
  bool ok = true;
  for (const auto& f : tum_) ok = ok && f->good();
  for (const auto& f : truth_tum_) ok = ok && (!f->is_open() || f->good());
  if (!jsonl_.flush() || !csv_.flush() || !ok) {
    *error = dir_ + ": cannot write the pose files (disk full?)";
    return false;
  }
  if (image.empty()) return true;
  return writeOverlay(drawOverlay(image, r, det_, camera), r.frame, error);
}

bool ReplayReport::writeOverlay(const cv::Mat& overlay, int64_t frame, std::string* error) {
  if (opt_.png_frames || video_failed_) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06lld.png", static_cast<long long>(frame));
    const fs::path p = fs::path(dir_) / "frames" / name;
    const std::string problem = writeImageFile(p.string(), overlay);
    if (!problem.empty()) *error = p.string() + ": cannot write: " + problem;
    return problem.empty();
  }
  if (!video_.isOpened()) {
    if (pending_overlay_.empty()) {  // wait for the second frame: it gives the frame rate
      pending_overlay_ = overlay;
      return true;
    }
    const Seconds dt = samples_.empty() ? 0 : samples_.back().stamp - first_stamp_;
    const double fps = std::clamp(dt > 0 ? 1.0 / dt : 30.0, 1.0, 120.0);
    const std::string path = (fs::path(dir_) / "overlay.mp4").string();
    for (const char* fcc : {"avc1", "mp4v"}) {
      try {
        video_.open(path, cv::CAP_FFMPEG, cv::VideoWriter::fourcc(fcc[0], fcc[1], fcc[2], fcc[3]),
                    fps, overlay.size());
      } catch (const cv::Exception&) {
      }
      if (video_.isOpened()) break;
    }
    if (!video_.isOpened()) {
      notes_.push_back(path + ": no H.264 or MPEG-4 encoder; overlay frames written to " + dir_ +
                       "/frames/ instead");
      video_failed_ = true;
      std::error_code ec;
      fs::create_directories(fs::path(dir_) / "frames", ec);
      return writeOverlay(pending_overlay_, frame - 1, error) && writeOverlay(overlay, frame, error);
    }
    video_.write(pending_overlay_);
    pending_overlay_.release();
  }
  video_.write(overlay);
  return true;
}

ReplayRunResult replaySource(robot::OpenedSource& src, PoseReplay& replay, ReplayReport& report,
                             const Intrinsics& cam, const StereoRig& rig,
                             const std::function<void(const std::string&)>& on_error,
                             const std::function<void(int64_t)>& on_progress) {
  ReplayRunResult res;
  Seconds last_stamp = 0;  // a frame the source cannot deliver has no stamp of its own
  for (int64_t k = 0;;) {
    ReplayFrame r;
    cv::Mat image;
    robot::ReturnType st;
    if (src.stereo) {
      std::optional<robot::StereoFrame> f;
      st = src.stereo->grab(0, &f);
      if (f) {
        r = replay.process(k, *f, rig);
        image = f->left;
      }
    } else {
      std::optional<robot::MonoFrame> f;
      st = src.mono->grab(0, &f);
      if (f) {
        r = replay.process(k, *f, cam);
        image = f->image;
      }
    }
    if (image.empty() && st == robot::ReturnType::kDeactivate) break;
    if (image.empty() && st != robot::ReturnType::kError) {  // live: no new frame yet
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
      continue;
    }
    if (image.empty()) {
      r = replay.failed(k, {last_stamp, -1},
                        src.stereo ? src.stereo->lastError() : src.mono->lastError());
      on_error(r.error);
    } else if (!r.ok) {
      on_error(src.description + ": frame " + std::to_string(k) + ": " + r.error);
      image.release();  // a frame the replay rejected gets no overlay
    }
    if (!r.ok) ++res.failed;
    last_stamp = r.stamp.stamp;
    if (!report.add(r, image, src.stereo ? rig.left : cam, &res.write_error)) return res;
    res.frames = ++k;
    on_progress(res.frames);
  }
  return res;
}

bool ReplayReport::finish(std::string* error) {
  if (!pending_overlay_.empty() && !video_.isOpened() && !opt_.png_frames && !video_failed_) {
    // A single frame: write it as a picture.
    opt_.png_frames = true;
    std::error_code ec;
    fs::create_directories(fs::path(dir_) / "frames", ec);
    if (!writeOverlay(pending_overlay_, samples_.empty() ? 0 : samples_.front().frame, error))
      return false;
  }
  if (video_.isOpened()) video_.release();
  for (auto& f : tum_) f->close();
  for (auto& f : truth_tum_)
    if (f->is_open()) f->close();

  Json summary = {{"input", opt_.input}, {"stereo", opt_.stereo}, {"tracking", opt_.tracking}};
  const int n_obj = det_.objectCount();
  const int64_t frames = n_obj > 0 ? static_cast<int64_t>(samples_.size()) / n_obj : 0;
  summary["frames"] = frames;
  summary["frames_failed"] = failed_;
  summary["errors"] = errors_;
  Json objects = Json::array();
  std::vector<cv::Mat> blocks;
  for (int id = 0; id < n_obj; ++id) {
    std::vector<Seconds> t;
    std::vector<TrackMode> modes;
    std::vector<Series> series(6);
    const char* titles[6] = {"x [m]", "y [m]", "z [m]", "theta*u x [deg]", "theta*u y [deg]", "theta*u z [deg]"};
    for (int k = 0; k < 6; ++k) series[static_cast<size_t>(k)].title = titles[k];
    Series terr{"error t [mm]", {}, {}}, rerr{"error R [deg]", {}, {}};
    std::vector<double> te, re;
    int64_t counts[3] = {0, 0, 0}, with_pose = 0, changes = 0, with_truth = 0;
    Json lost_segments = Json::array();
    int64_t lost_start = -1;
    std::optional<TrackMode> prev;
    for (const Sample& s : samples_) {
      if (s.object != id) continue;
      t.push_back(s.stamp);
      modes.push_back(s.mode);
      ++counts[static_cast<int>(s.mode)];
      if (prev && *prev != s.mode) ++changes;
      prev = s.mode;
      if (s.mode == TrackMode::kLost && lost_start < 0) lost_start = s.frame;
      if (s.mode != TrackMode::kLost && lost_start >= 0) {
        lost_segments.push_back({lost_start, s.frame - 1});
        lost_start = -1;
      }
      const auto component = [](const std::optional<Pose>& P, int k) -> std::optional<double> {
        if (!P) return std::nullopt;
        return k < 3 ? P->t[k] : P->rotationVector()[k - 3] * kDeg;
      };
      for (int k = 0; k < 6; ++k) {
        series[static_cast<size_t>(k)].est.push_back(component(s.cMo, k));
        series[static_cast<size_t>(k)].truth.push_back(component(s.truth, k));
      }
      if (s.cMo) ++with_pose;
      if (s.truth) ++with_truth;
      if (s.cMo && s.truth) {
        te.push_back(translationError(*s.cMo, *s.truth));
        re.push_back(rotationError(*s.cMo, *s.truth) * kDeg);
        terr.est.push_back(te.back() * 1e3);
        rerr.est.push_back(re.back());
      } else {
        terr.est.push_back(std::nullopt);
        rerr.est.push_back(std::nullopt);
      }
      terr.truth.push_back(std::nullopt);
      rerr.truth.push_back(std::nullopt);
    }
    if (lost_start >= 0 && !samples_.empty()) lost_segments.push_back({lost_start, samples_.back().frame});
    Json o = {{"name", det_.object(id).name},
              {"frames_with_pose", with_pose},
              {"modes", {{"detect", counts[0]}, {"track", counts[1]}, {"lost", counts[2]}}},
              {"mode_changes", changes},
              {"lost_segments", lost_segments},
              {"trajectory", tum_names_[static_cast<size_t>(id)]}};
    if (with_truth > 0) {
      o["ground_truth"] = {{"frames", with_truth},
                           {"frames_with_pose", static_cast<int64_t>(te.size())},
                           {"translation_error_m", statsJson(stats(te))},
                           {"rotation_error_deg", statsJson(stats(re))},
                           {"trajectory", truth_names_[static_cast<size_t>(id)]}};
      series.push_back(terr);
      series.push_back(rerr);
    }
    objects.push_back(o);
    blocks.push_back(drawObjectPlot(det_.object(id).name, t, modes, series));
  }
  summary["objects"] = objects;
  summary["outputs"] = {{"poses", "poses.jsonl"}, {"csv", "poses.csv"}, {"plot", "plot.png"},
                        {"overlay", opt_.png_frames || video_failed_ ? "frames/" : "overlay.mp4"}};
  const Stats ts = stats(time_ms_);
  double total = 0;
  for (double v : time_ms_) total += v;
  summary["timing_ms"] = {{"note", "wall clock, not deterministic"},
                          {"per_frame", statsJson(ts)},
                          {"total_s", total * 1e-3}};
  std::ofstream out(fs::path(dir_) / "summary.json", std::ios::trunc);
  out << summary.dump(2) << "\n";
  if (!out.flush()) {
    *error = dir_ + "/summary.json: cannot write";
    return false;
  }
  cv::Mat plot;
  if (!blocks.empty()) cv::vconcat(blocks, plot);
  if (!plot.empty()) {
    if (const std::string p = writeImageFile((fs::path(dir_) / "plot.png").string(), plot); !p.empty()) {
      *error = dir_ + "/plot.png: cannot write: " + p;
      return false;
    }
  }
  jsonl_.close();
  csv_.close();
  return true;
}

}  // namespace refgrasp::servo
