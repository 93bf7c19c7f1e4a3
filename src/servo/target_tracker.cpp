#include "servo/target_tracker.h"

#include <chrono>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "servo/homography_tracker.h"
#include "servo/surface_model.h"

namespace refgrasp::servo {

const char* toString(TrackMode m) {
  switch (m) {
    case TrackMode::kDetect: return "detect";
    case TrackMode::kTrack: return "track";
    case TrackMode::kLost: return "lost";
  }
  return "?";
}

const char* toString(SearchScope s) {
  switch (s) {
    case SearchScope::kNone: return "none";
    case SearchScope::kPrior: return "prior";
    case SearchScope::kWholeFrame: return "whole";
  }
  return "?";
}

void TargetTrackerOptions::check() const {
  auto need = [](bool ok, const char* field, const char* problem) {
    if (!ok) throw std::invalid_argument(std::string("TargetTrackerOptions.") + field + ": " + problem);
  };
  need(confirm_detections >= 1, "confirm_detections", "must be >= 1");
  need(std::isfinite(confirm_max_translation_fraction) && confirm_max_translation_fraction > 0,
       "confirm_max_translation_fraction", "must be > 0");
  need(std::isfinite(confirm_max_corner_fraction) && confirm_max_corner_fraction > 0,
       "confirm_max_corner_fraction", "must be > 0");
  need(std::isfinite(confirm_max_rotation_rad) && confirm_max_rotation_rad > 0,
       "confirm_max_rotation_rad", "must be > 0");
  need(confirm_max_frames >= confirm_detections, "confirm_max_frames", "must be >= confirm_detections");
  need(prior_frames >= 0, "prior_frames", "must be >= 0");
  need(std::isfinite(prior_roi_margin) && prior_roi_margin >= 0, "prior_roi_margin", "must be >= 0");
  need(std::isfinite(prior_max_scale) && prior_max_scale >= 0, "prior_max_scale", "must be >= 0");
  need(std::isfinite(prior_scale_margin) && prior_scale_margin >= 1, "prior_scale_margin", "must be >= 1");
  need(redetect_every_frames >= 0, "redetect_every_frames", "must be >= 0");
  tracker.check();
}

const TargetState* TargetFrame::find(int object) const {
  for (const TargetState& o : objects)
    if (o.object == object) return &o;
  return nullptr;
}

std::optional<Pose> transportPose(const Pose& c1Mo, const robot::CaptureState& from,
                                  const robot::CaptureState& to) {
  if (!from.bMc || !to.bMc) return std::nullopt;
  Pose w1 = *from.bMc, w2 = *to.bMc;  // camera in the base frame, or in the odometry frame
  if (from.wMb_odom && to.wMb_odom) {
    w1 = *from.wMb_odom * w1;
    w2 = *to.wMb_odom * w2;
  }
  return w2.inverse() * w1 * c1Mo;
}

std::optional<std::array<Eigen::Vector2d, 4>> projectPattern(const detector::ObjectModel& object,
                                                             const Pose& cMo, const Intrinsics& camera) {
  const std::optional<std::array<Eigen::Vector3d, 4>> q = facingQuad(patternQuads(object), cMo);
  if (!q) return std::nullopt;
  std::array<Eigen::Vector2d, 4> px;
  for (size_t i = 0; i < 4; ++i) px[i] = camera.project(cMo * (*q)[i]);
  return px;
}

namespace {

cv::Mat toGray(const cv::Mat& image) {
  if (image.channels() == 1) return image;
  cv::Mat g;
  cv::cvtColor(image, g, image.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
  return g;
}

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// One eye's image and camera, and where the other eye sits (lMe: eye in the left frame).
struct Eye {
  cv::Mat gray;
  Intrinsics camera;
  Pose lMe;
};

/// Detection of one object in one frame, fused over the eyes (mono: the left only).
struct EyesDetection {
  detector::Detection eye[2];
  std::optional<detector::ObjectStats> stats;  ///< the left (or only) eye's
  std::optional<Pose> lMo;
  detector::EyesUsed eyes = detector::EyesUsed::kNone;
};

/// Where to detect an object: around a predicted pose (left frame), around a 2D-only object's
/// predicted homography in the left image (the right eye searches its whole frame), or, with
/// neither, in the whole frame.
struct Search {
  std::optional<Pose> cMo;
  std::optional<Eigen::Matrix3d> H;  ///< undistorted reference px -> undistorted left image px
  bool prior() const { return cMo.has_value() || H.has_value(); }
};

/// The bounding box of corners grown by `margin` x its larger side on each side, in the image.
std::optional<cv::Rect> cornerRegion(const std::array<Eigen::Vector2d, 4>& c, double margin, const Intrinsics& cam) {
  Eigen::Vector2d lo = c[0], hi = c[0];
  for (const auto& p : c) {
    if (!p.allFinite()) return std::nullopt;
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double m = margin * (hi - lo).maxCoeff();
  const cv::Rect r(cv::Point(static_cast<int>(std::floor(std::max(0.0, lo.x() - m))),
                             static_cast<int>(std::floor(std::max(0.0, lo.y() - m)))),
                   cv::Point(static_cast<int>(std::ceil(std::min<double>(cam.width, hi.x() + m))),
                             static_cast<int>(std::ceil(std::min<double>(cam.height, hi.y() + m)))));
  if (r.width < 16 || r.height < 16) return std::nullopt;
  return r;
}

}  // namespace

struct TargetTracker::Impl {
  struct Target {
    std::unique_ptr<FrameTracker> tracker[2];  ///< left (or mono), right
    bool active[2] = {false, false};
    /// 2D-only objects: the homography tracker (left or only eye), and its state: the last H
    /// and its change over the last frame (H_t H_{t-1}^-1), undistorted image px.
    std::unique_ptr<HomographyTracker> htracker;
    bool h_active = false;
    std::optional<Eigen::Matrix3d> last_H, velocity_H, disputed_H;
    std::array<Eigen::Vector2d, 4> corners_ref{};  ///< undistorted reference px
    bool confirmed = false;          ///< internal: survives a short loss (prior_frames)
    int agree = 0;                   ///< consecutive agreeing detections
    int unconfirmed_frames = 0;      ///< frames since the hypothesis appeared, while unconfirmed
    std::optional<Pose> last_cMo;    ///< left camera at the capture of the last pose
    robot::CaptureState last_capture;
    int frames_since_pose = 1 << 20; ///< 0: the previous frame had a pose
    int frames_since_detection = 1 << 20;
    std::optional<Pose> velocity;    ///< pose change over the last frame (camera frame)
    /// The last periodic re-detection that disagreed with the confirmed track; how many in a row
    /// did, and how many of them in a row agreed with each other.
    std::optional<Pose> disputed;
    int disputes = 0, disputed_agree = 0;
    bool anyActive() const { return active[0] || active[1]; }
    void stop() { active[0] = active[1] = h_active = false; }
    void clearDispute() {
      disputed.reset();
      disputed_H.reset();
      disputes = disputed_agree = 0;
    }
  };

  Impl(const detector::Detector& d, const TargetTrackerOptions& o, TrackerFactory f)
      : det(d), opt(o) {
    opt.check();
    if (!f && opt.track) f = planarTrackerFactory(opt.tracker, &det);
    for (int id = 0; id < det.objectCount(); ++id) {
      Target t;
      // Only objects whose detections give a pose can be tracked (the tracker starts from it).
      const detector::ObjectModel& m = det.object(id);
      if (f && opt.track && m.hasPose()) t.tracker[0] = f(m);
      // An object without metric geometry is followed by its homography.
      if (opt.track && !m.hasPose()) t.htracker = makeHomographyTracker(det, id, opt.tracker);
      for (size_t i = 0; i < 4; ++i) t.corners_ref[i] = m.camera ? m.camera->undistortPixel(m.corners_px[i]) : m.corners_px[i];
      targets.push_back(std::move(t));
    }
    factory = std::move(f);
  }

  /// The right eyes' trackers, made on the first stereo frame.
  void makeRightTrackers() {
    for (int id = 0; id < det.objectCount(); ++id) {
      Target& t = targets[static_cast<size_t>(id)];
      if (t.tracker[0] && !t.tracker[1]) t.tracker[1] = factory(det.object(id));
    }
  }

  bool tracking() const {
    for (const Target& t : targets)
      if (t.tracker[0] || t.htracker) return true;
    return false;
  }

  TargetFrame begin(const FrameStamp& stamp, const robot::CaptureState& capture) const {
    TargetFrame r;
    r.stamp = stamp;
    r.capture = capture;
    for (int id = 0; id < det.objectCount(); ++id) {
      TargetState s;
      s.object = id;
      s.name = det.object(id).name;
      s.detection.object = id;
      r.objects.push_back(s);
    }
    return r;
  }

  TargetFrame failed(const FrameStamp& stamp, const robot::CaptureState& capture,
                     const std::string& error) {
    TargetFrame r = begin(stamp, capture);
    r.ok = false;
    r.error = error;
    for (Target& t : targets) {
      t.stop();
      t.frames_since_pose = t.frames_since_detection = 1 << 20;
      t.confirmed = false;
      t.agree = 0;
      t.velocity.reset();
      t.velocity_H.reset();
    }
    return r;
  }

  /// The pose expected in this frame from the last one: camera motion when the captures know
  /// it, else the last frame-to-frame motion (constant_velocity), else the last pose.
  std::optional<Pose> predict(const Target& t, const robot::CaptureState& now) const {
    if (!t.last_cMo) return std::nullopt;
    if (auto p = transportPose(*t.last_cMo, t.last_capture, now)) return p;
    if (opt.constant_velocity && t.velocity && t.frames_since_pose == 0) return *t.velocity * *t.last_cMo;
    return t.last_cMo;
  }

  /// 2D-only objects: H expected in this frame (the last motion repeated, else the last H).
  std::optional<Eigen::Matrix3d> predictH(const Target& t) const {
    if (!t.last_H) return std::nullopt;
    if (opt.constant_velocity && t.velocity_H && t.frames_since_pose == 0) return Eigen::Matrix3d(*t.velocity_H * *t.last_H);
    return t.last_H;
  }

  /// 2D-only objects: the pattern corners under a and b (undistorted px) differ by at most
  /// confirm_max_corner_fraction of the pattern's diagonal.
  bool agreesH(const Target& t, const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) const {
    std::array<Eigen::Vector2d, 4> ca, cb;
    double gap = 0;
    for (size_t i = 0; i < 4; ++i) {
      ca[i] = (a * t.corners_ref[i].homogeneous()).hnormalized();
      cb[i] = (b * t.corners_ref[i].homogeneous()).hnormalized();
      gap = std::max(gap, (ca[i] - cb[i]).norm());
    }
    const double diag = 0.5 * ((ca[2] - ca[0]).norm() + (ca[3] - ca[1]).norm());
    return std::isfinite(gap) && gap <= opt.confirm_max_corner_fraction * std::max(diag, 1.0);
  }

  bool agrees(const Pose& a, const Pose& b) const {
    const double dist = std::max(1e-3, 0.5 * (a.t.norm() + b.t.norm()));
    return translationError(a, b) <= opt.confirm_max_translation_fraction * dist &&
           rotationError(a, b) <= opt.confirm_max_rotation_rad;
  }

  /// Detects the objects with a non-empty request in every eye: a prior pose (left frame) or the
  /// whole frame. Fills out[id]; false + error when the detector rejects the frame.
  bool detectObjects(const std::vector<Eye>& eyes, const FrameStamp& stamp,
                     const std::vector<std::optional<Search>>& request,
                     std::vector<EyesDetection>* out, std::string* error) const {
    const int n = det.objectCount();
    bool all_whole = true, any = false;
    for (const auto& r : request) {
      any = any || r.has_value();
      all_whole = all_whole && r.has_value() && !r->prior();
    }
    if (!any) return true;
    for (size_t e = 0; e < eyes.size(); ++e) {
      detector::DetectionQuery q;
      if (!all_whole) {
        q.only_priors = true;
        for (int id = 0; id < n; ++id) {
          const auto& r = request[static_cast<size_t>(id)];
          if (!r) continue;
          detector::ObjectPrior p;
          p.object = id;
          p.roi_margin = opt.prior_roi_margin;
          p.scale_margin = opt.prior_scale_margin;
          p.max_scale = opt.prior_max_scale;
          if (r->cMo) {
            p.cMo = eyes[e].lMe.inverse() * *r->cMo;
          } else if (r->H && e == 0) {
            p.H = *r->H;
          } else {
            p.roi = cv::Rect(0, 0, eyes[e].camera.width, eyes[e].camera.height);
          }
          q.priors.push_back(p);
        }
      }
      const detector::DetectionResult d = det.detect(eyes[e].gray, eyes[e].camera, stamp, q);
      if (!d.ok) {
        *error = (eyes.size() == 2 ? (e == 0 ? "left: " : "right: ") : "") + d.error;
        return false;
      }
      for (int id = 0; id < n; ++id) {
        if (!request[static_cast<size_t>(id)]) continue;
        EyesDetection& o = (*out)[static_cast<size_t>(id)];
        o.eye[e].object = id;
        if (const auto hit = d.find(id)) o.eye[e] = *hit;
        if (e == 0 && static_cast<size_t>(id) < d.stats.size()) o.stats = d.stats[static_cast<size_t>(id)];
      }
    }
    for (int id = 0; id < n; ++id) {
      if (!request[static_cast<size_t>(id)]) continue;
      EyesDetection& o = (*out)[static_cast<size_t>(id)];
      if (eyes.size() == 1) {
        if (o.eye[0].found) {
          o.lMo = o.eye[0].cMo;  // empty for 2D-only objects
          o.eyes = detector::EyesUsed::kLeft;
        }
      } else {
        StereoRig rig;
        rig.lMr = eyes[1].lMe;
        const detector::FusedPose f = detector::fuseStereo(o.eye[0].found ? o.eye[0].cMo : std::nullopt,
                                                           o.eye[1].found ? o.eye[1].cMo : std::nullopt, rig);
        o.lMo = f.lMo;
        o.eyes = f.eyes;
        // 2D-only objects: the eyes that saw them, without a pose (as Detector::detectStereo).
        if (!det.object(id).hasPose() && f.eyes == detector::EyesUsed::kNone) {
          if (o.eye[0].found && o.eye[1].found) o.eyes = detector::EyesUsed::kBoth;
          else if (o.eye[0].found) o.eyes = detector::EyesUsed::kLeft;
          else if (o.eye[1].found) o.eyes = detector::EyesUsed::kRight;
        }
      }
    }
    return true;
  }

  /// Starts the trackers of every eye at lMo (an eye that cannot see the pattern stays stopped).
  void startTrackers(Target* t, const std::vector<Eye>& eyes, const Pose& lMo) {
    for (size_t e = 0; e < eyes.size(); ++e) {
      if (!t->tracker[e]) continue;
      t->active[e] = t->tracker[e]->start(eyes[e].gray, eyes[e].camera, eyes[e].lMe.inverse() * lMo).ok;
    }
  }

  /// Tracks the active eyes from `pred`; fuses. Empty when every eye lost it.
  std::optional<Pose> trackEyes(Target* t, const std::vector<Eye>& eyes, const Pose& pred,
                                TargetState* s) {
    std::optional<Pose> eye_lMo[2];
    for (size_t e = 0; e < eyes.size(); ++e) {
      if (!t->active[e]) continue;
      const TrackStep step =
          t->tracker[e]->track(eyes[e].gray, eyes[e].camera, eyes[e].lMe.inverse() * pred);
      (e == 0 ? s->quality : s->quality_right) = step.quality;
      t->active[e] = step.ok;
      if (step.ok) eye_lMo[e] = eyes[e].lMe * step.cMo;
      else if (s->lost_reason.empty()) s->lost_reason = (eyes.size() == 2 ? (e == 0 ? "left: " : "right: ") : "") + step.lost_reason;
    }
    if (eyes.size() == 1) {
      if (eye_lMo[0]) s->eyes = detector::EyesUsed::kLeft;
      return eye_lMo[0];
    }
    StereoRig rig;
    rig.lMr = eyes[1].lMe;
    const detector::FusedPose f = detector::fuseStereo(
        eye_lMo[0], eye_lMo[1] ? std::optional<Pose>(eyes[1].lMe.inverse() * *eye_lMo[1]) : std::nullopt, rig);
    s->eyes = f.eyes;
    if (f.lMo) {
      // An eye that lost the pattern restarts from the other one's pose when it sees it again.
      for (size_t e = 0; e < 2; ++e)
        if (!t->active[e] && t->tracker[e])
          t->active[e] = t->tracker[e]->start(eyes[e].gray, eyes[e].camera, eyes[e].lMe.inverse() * *f.lMo).ok;
    }
    return f.lMo;
  }

  // A confirmed, tracked target is detected only when its periodic re-detection is due. One that
  // agrees restarts the tracker. One that disagrees is not believed alone (a close-up partly
  // hidden by the gripper, a look-alike): the track goes on and the next frames are detected too;
  // confirm_detections + 1 of them in a row agreeing with each other replace the track (it had
  // drifted): one more than a new target needs, since the track is evidence too. After
  // kMaxDisputes in a row without that, a full period passes. True when the track overrules the
  // detection `found`; *settled when the detections replace the track. T: a pose (disputed:
  // &t->disputed) or a 2D-only object's homography (&t->disputed_H); agree compares two.
  template <class T, class Agree>
  bool overrules(Target* t, const T& tracked, const std::optional<T>& found, std::optional<T>* disputed,
                 Agree agree, bool* settled) const {
    constexpr int kMaxDisputes = 5;
    *settled = false;
    bool overruled = false;
    if (t->confirmed && found && !agree(*found, tracked)) {
      t->disputed_agree = *disputed && agree(*found, **disputed) ? t->disputed_agree + 1 : 1;
      *disputed = found;
      *settled = t->disputed_agree >= opt.confirm_detections + 1;
      if (!*settled) {
        overruled = true;
        const bool again = ++t->disputes < kMaxDisputes;
        t->frames_since_detection = again ? opt.redetect_every_frames - 2 : -1;
        if (!again) t->clearDispute();
      }
    }
    if (!overruled) t->clearDispute();
    return overruled;
  }

  /// A target's prediction and tracking in this frame: a pose, or a 2D-only object's homography.
  struct Followed {
    std::optional<Pose> pred, cMo;
    std::optional<Eigen::Matrix3d> predH;
    std::optional<HomographyStep> h;  ///< ok steps only
    bool any() const { return cMo.has_value() || h.has_value(); }
  };

  /// 1. Tracks a target from its prediction (stopped when every eye lost it).
  Followed follow(Target* t, const std::vector<Eye>& eyes, const robot::CaptureState& capture, TargetState* s) {
    Followed k;
    if (t->htracker) {
      k.predH = predictH(*t);
      if (t->h_active && k.predH) {
        HomographyStep step = t->htracker->track(eyes[0].gray, eyes[0].camera, k.predH);
        s->quality = step.quality;
        if (step.ok) k.h = std::move(step);
        else s->lost_reason = step.lost_reason;
      }
    } else {
      k.pred = predict(*t, capture);
      if (t->anyActive() && k.pred) k.cMo = trackEyes(t, eyes, *k.pred, s);
    }
    if (!k.any()) t->stop();
    return k;
  }

  /// 2. What to detect: nothing (tracked, confirmed, no re-detection due), the predicted region,
  /// or the whole frame.
  std::optional<Search> searchFor(const Target& t, const Followed& k, const Intrinsics& left) const {
    const bool due = opt.redetect_every_frames > 0 && t.frames_since_detection + 1 >= opt.redetect_every_frames;
    const bool recent = t.frames_since_pose < opt.prior_frames;
    Search s;
    if (t.htracker) {
      if (k.h && t.confirmed && !due) return std::nullopt;
      // The homography gives the detector the region and the keypoint sizes; one whose corners
      // give no usable region is searched in the whole frame.
      if (k.h) {
        if (cornerRegion(k.h->corners, opt.prior_roi_margin, left)) s.H = k.h->H;
      } else if (k.predH && recent && cornerRegion(cornersUnderH(*k.predH, t.corners_ref, left), opt.prior_roi_margin, left)) {
        s.H = *k.predH;
      }
      return s;
    }
    if (!t.tracker[0]) return s;  // detect-only: whole frame
    if (k.cMo && t.confirmed && !due) return std::nullopt;
    if (k.cMo) s.cMo = k.cMo;
    else if (k.pred && recent) s.cMo = k.pred;
    return s;
  }

  /// Whether the detection found the object (a pose, or a 2D-only object seen by an eye).
  bool detected(int id, const EyesDetection& d) const {
    return d.eyes != detector::EyesUsed::kNone && (d.lMo.has_value() || !det.object(id).hasPose());
  }

  /// 3. Whether a detection that the track did not overrule agrees with the target's previous
  /// estimate brought to this frame: tracked, or predicted (by the camera motion, or by the last
  /// motion, or unmoved: a sudden stop is no disagreement).
  bool agreesWithPrevious(const Target& t, const EyesDetection& d, const Followed& k,
                          const robot::CaptureState& capture) const {
    const bool recent = t.frames_since_pose <= opt.prior_frames;
    if (t.htracker) {
      if (!d.eye[0].found) return false;
      const Eigen::Matrix3d& H = d.eye[0].H;
      if (k.h) return agreesH(t, H, k.h->H);
      return t.last_H && recent && ((k.predH && agreesH(t, H, *k.predH)) || agreesH(t, H, *t.last_H));
    }
    if (!d.lMo) return false;
    if (k.cMo) return agrees(*d.lMo, *k.cMo);
    if (!t.last_cMo || !recent) return false;
    const bool camera_motion_known = t.last_capture.bMc && capture.bMc;
    return (k.pred && agrees(*d.lMo, *k.pred)) || (!camera_motion_known && agrees(*d.lMo, *t.last_cMo));
  }

  /// 3. Whether the confirmed track overrules this detection (the dispute rule, overrules()).
  bool trackOverrules(Target* t, const EyesDetection& d, const Followed& k, bool* settled) {
    *settled = false;
    if (k.cMo)
      return overrules(t, *k.cMo, d.lMo, &t->disputed, [this](const Pose& a, const Pose& b) { return agrees(a, b); },
                       settled);
    if (k.h) {
      const std::optional<Eigen::Matrix3d> H = d.eye[0].found ? std::optional<Eigen::Matrix3d>(d.eye[0].H) : std::nullopt;
      return overrules(t, k.h->H, H, &t->disputed_H,
                       [this, t](const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) { return agreesH(*t, a, b); },
                       settled);
    }
    t->clearDispute();
    return false;
  }

  /// 3. The mode of a target this frame from its detection and tracking.
  void decide(int id, Target* tp, TargetState* sp, const EyesDetection& d, const Followed& k,
              const std::vector<Eye>& eyes, const robot::CaptureState& capture) {
    Target& t = *tp;
    TargetState& s = *sp;
    s.detector_stats = d.stats;
    if (d.eye[0].found) s.detector_best = d.eye[0];
    std::optional<Eigen::Matrix3d> H;  // 2D-only: this frame's homography (left eye)
    bool settled = false, overruled = false;
    if (detected(id, d) && k.any()) overruled = trackOverrules(&t, d, k, &settled);
    else t.clearDispute();
    if (detected(id, d) && !overruled) {
      const bool agree = settled || agreesWithPrevious(t, d, k, capture);
      if (agree) {
        ++t.agree;
      } else {
        t.agree = 1;
        t.confirmed = false;
        t.unconfirmed_frames = 0;
      }
      if (t.agree >= opt.confirm_detections) t.confirmed = true;
      s.mode = TrackMode::kDetect;
      s.cMo = d.lMo;
      s.eyes = d.eyes;
      s.detection = d.eye[0].found ? d.eye[0] : s.detection;
      s.quality = TrackQuality();
      s.quality_right = TrackQuality();
      t.frames_since_detection = 0;
      if (t.tracker[0] && d.lMo) startTrackers(&t, eyes, *d.lMo);
      if (t.htracker && d.eye[0].found) {
        H = d.eye[0].H;
        t.h_active = t.htracker->start(eyes[0].gray, eyes[0].camera, *H).ok;
      }
    } else if (k.any()) {
      s.mode = TrackMode::kTrack;
      s.cMo = k.cMo;
      if (k.h) {
        H = k.h->H;
        s.H = H;
        s.eyes = detector::EyesUsed::kLeft;
        s.corners = k.h->corners;
      }
      ++t.frames_since_detection;
    } else {
      s.mode = TrackMode::kLost;
      ++t.frames_since_detection;
    }
    if (!t.confirmed && s.mode != TrackMode::kLost && ++t.unconfirmed_frames > opt.confirm_max_frames) {
      // A hypothesis that no detection confirmed in time is dropped.
      s.mode = TrackMode::kLost;
      s.lost_reason = "not confirmed";
      t.stop();
      t.agree = 0;
      t.unconfirmed_frames = 0;
    }
    remember(&t, &s, H, capture);
    if (s.mode == TrackMode::kDetect && s.detection.found)
      s.corners = s.detection.corners;
    else if (s.cMo)
      s.corners = projectPattern(det.object(id), *s.cMo, eyes[0].camera);
  }

  /// The target's memory after this frame's mode: the last estimate and motion, the frames
  /// since a pose, the confirmation dropped after a loss longer than prior_frames.
  void remember(Target* tp, TargetState* sp, const std::optional<Eigen::Matrix3d>& H,
                const robot::CaptureState& capture) const {
    Target& t = *tp;
    TargetState& s = *sp;
    if (s.mode == TrackMode::kLost) {
      s.cMo.reset();
      s.corners.reset();
      s.H.reset();
      s.eyes = detector::EyesUsed::kNone;
      ++t.frames_since_pose;
      if (t.frames_since_pose > opt.prior_frames) {
        t.confirmed = false;
        t.agree = 0;
        t.velocity.reset();
        t.velocity_H.reset();
      }
    } else {
      if (s.cMo && t.last_cMo && t.frames_since_pose == 0) t.velocity = *s.cMo * t.last_cMo->inverse();
      else t.velocity.reset();
      if (s.cMo) {
        t.last_cMo = s.cMo;
        t.last_capture = capture;
      }
      if (H && t.last_H && t.frames_since_pose == 0) t.velocity_H = Eigen::Matrix3d(*H * t.last_H->inverse());
      else t.velocity_H.reset();
      if (H) t.last_H = H;
      t.frames_since_pose = 0;
    }
    s.confirmed = t.confirmed && s.mode != TrackMode::kLost;
    s.agreeing_detections = s.mode == TrackMode::kLost ? 0 : t.agree;
  }

  TargetFrame run(const std::vector<Eye>& eyes, const FrameStamp& stamp,
                  const robot::CaptureState& capture, const std::vector<robot::ObjectTruth>&) {
    TargetFrame r = begin(stamp, capture);
    if (eyes.size() == 2) makeRightTrackers();
    const size_t n = static_cast<size_t>(det.objectCount());
    std::vector<Followed> followed(n);
    std::vector<std::optional<Search>> request(n);
    bool any = false;
    for (size_t id = 0; id < n; ++id) {
      followed[id] = follow(&targets[id], eyes, capture, &r.objects[id]);
      request[id] = searchFor(targets[id], followed[id], eyes[0].camera);
      if (request[id]) r.objects[id].searched = request[id]->prior() ? SearchScope::kPrior : SearchScope::kWholeFrame;
      any = any || request[id].has_value();
    }
    std::vector<EyesDetection> found(n);
    std::string error;
    if (any) {
      ++r.detector_calls;
      if (!detectObjects(eyes, stamp, request, &found, &error)) return failed(stamp, capture, error);
      // A prior search that failed for a target the tracker lost: the whole frame now.
      std::vector<std::optional<Search>> again(n);
      bool retry = false;
      for (size_t id = 0; id < n; ++id) {
        const auto& q = request[id];
        if (q && q->prior() && !followed[id].any() && !detected(static_cast<int>(id), found[id])) {
          again[id] = Search();
          r.objects[id].searched = SearchScope::kWholeFrame;
          retry = true;
        }
      }
      if (retry) {
        ++r.detector_calls;
        if (!detectObjects(eyes, stamp, again, &found, &error)) return failed(stamp, capture, error);
      }
    }
    for (size_t id = 0; id < n; ++id)
      decide(static_cast<int>(id), &targets[id], &r.objects[id], found[id], followed[id], eyes, capture);
    return r;
  }

  const detector::Detector& det;
  TargetTrackerOptions opt;
  TrackerFactory factory;
  std::vector<Target> targets;
};

namespace {

std::string sizeProblem(const cv::Mat& image, const Intrinsics& cam, const char* eye) {
  if (image.empty()) return std::string(eye) + "empty image";
  if (image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3 && image.channels() != 4))
    return std::string(eye) + "unsupported pixel type (expected 8-bit gray, BGR or BGRA)";
  if (image.cols == cam.width && image.rows == cam.height) return "";
  return std::string(eye) + "image is " + std::to_string(image.cols) + "x" +
         std::to_string(image.rows) + ", the camera calibration is " + std::to_string(cam.width) +
         "x" + std::to_string(cam.height);
}

}  // namespace

TargetTracker::TargetTracker(const detector::Detector& detector, const TargetTrackerOptions& options,
                             TrackerFactory trackers)
    : p_(std::make_unique<Impl>(detector, options, std::move(trackers))) {}
TargetTracker::~TargetTracker() = default;
TargetTracker::TargetTracker(TargetTracker&&) noexcept = default;
TargetTracker& TargetTracker::operator=(TargetTracker&&) noexcept = default;

bool TargetTracker::tracking() const { return p_->tracking(); }
const TargetTrackerOptions& TargetTracker::options() const { return p_->opt; }

void TargetTracker::reset() { p_->failed({}, {}, ""); }

TargetFrame TargetTracker::failed(const FrameStamp& stamp, const std::string& error) {
  return p_->failed(stamp, {}, error);
}

TargetFrame TargetTracker::process(const robot::MonoFrame& f, const Intrinsics& camera) {
  const auto t0 = std::chrono::steady_clock::now();
  try {
    const std::string bad = sizeProblem(f.image, camera, "");
    if (!bad.empty()) return p_->failed(f.frameStamp(), f.capture, bad);
    std::vector<Eye> eyes{{toGray(f.image), camera, Pose()}};
    TargetFrame r = p_->run(eyes, f.frameStamp(), f.capture, f.truth);
    r.time_ms = msSince(t0);
    return r;
  } catch (const std::exception& e) {  // out of memory
    return p_->failed(f.frameStamp(), f.capture, std::string("tracking failed: ") + e.what());
  }
}

TargetFrame TargetTracker::process(const robot::StereoFrame& f, const StereoRig& rig) {
  const auto t0 = std::chrono::steady_clock::now();
  try {
    std::string bad = f.left.empty() || f.right.empty() ? "empty image" : sizeProblem(f.left, rig.left, "left ");
    if (bad.empty()) bad = sizeProblem(f.right, rig.right, "right ");
    if (!bad.empty()) return p_->failed(f.frameStamp(), f.capture, bad);
    std::vector<Eye> eyes{{toGray(f.left), rig.left, Pose()}, {toGray(f.right), rig.right, rig.lMr}};
    TargetFrame r = p_->run(eyes, f.frameStamp(), f.capture, f.truth);
    r.time_ms = msSince(t0);
    return r;
  } catch (const std::exception& e) {
    return p_->failed(f.frameStamp(), f.capture, std::string("tracking failed: ") + e.what());
  }
}

}  // namespace refgrasp::servo
