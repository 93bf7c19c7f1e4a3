// openSource: the one place that knows every camera backend (as backends.cpp knows every robot).
#include "robot/sources.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <set>

#include "core/error.h"
#include "robot/dc1394/bumblebee2.h"
#include "robot/enon_model.h"
#include "robot/files/image_sources.h"
#include "robot/files/recording.h"
#include "robot/sim/scenario.h"
#include "robot/sim/sim_enon.h"

namespace refgrasp::robot {

namespace fs = std::filesystem;

namespace {

// The left eye of a stereo source, as a mono source.
class LeftEye : public FrameSource {
 public:
  explicit LeftEye(std::unique_ptr<StereoSource> s) : s_(std::move(s)) {}
  const Intrinsics& camera() const override { return s_->rig().left; }
  ReturnType grab(Seconds time, std::optional<MonoFrame>* frame) override {
    frame->reset();
    std::optional<StereoFrame> f;
    const ReturnType r = s_->grab(time, &f);
    if (f) {
      MonoFrame m;
      m.image = f->left;
      m.stamp = f->stamp;
      m.index = f->index;
      m.capture = f->capture;
      m.truth = f->truth;
      for (ObjectTruth& t : m.truth) t.rMo.reset();
      *frame = std::move(m);
    }
    return r;
  }
  std::string lastError() const override { return s_->lastError(); }

 private:
  std::unique_ptr<StereoSource> s_;
};

// onCallerClock's adaptor.
class CallerClock : public StereoSource {
 public:
  CallerClock(std::unique_ptr<StereoSource> s, bool host_unix_clock)
      : s_(std::move(s)), unix_(host_unix_clock) {}
  const StereoRig& rig() const override { return s_->rig(); }
  ReturnType grab(Seconds time, std::optional<StereoFrame>* frame) override {
    const ReturnType r = s_->grab(time, frame);
    if (*frame) {
      if (unix_) {
        const double now = std::chrono::duration<double>(
                               std::chrono::system_clock::now().time_since_epoch()).count();
        (*frame)->stamp -= now - time;
      } else {
        (*frame)->stamp = time;
      }
    }
    return r;
  }
  std::string lastError() const override { return s_->lastError(); }

 private:
  std::unique_ptr<StereoSource> s_;
  bool unix_;
};

struct Settings {
  const SourceRequest& req;
  std::string get(const std::string& key, const std::string& fallback = "") const {
    const auto it = req.settings.find(key);
    return it == req.settings.end() ? fallback : it->second;
  }
  double number(const std::string& key, double fallback) const {
    const std::string v = get(key);
    if (v.empty()) return fallback;
    try {
      size_t n = 0;
      const double x = std::stod(v, &n);
      if (n == v.size() && std::isfinite(x)) return x;
    } catch (const std::exception&) {
    }
    throw ConfigError(req.spec, key, "'" + v + "' is not a number");
  }
  // Every given key must be a setting of the chosen kind (checked before anything is opened).
  void checkKeys(const std::string& kind) const {
    static const std::map<std::string, std::set<std::string>> kKeys = {
        {"recording", {}},
        {"folder", {"stamps", "fps_hz", "max_stamp_skew_s"}},
        {"folders", {"stamps", "fps_hz", "max_stamp_skew_s"}},
        {"video", {"fps_hz"}},
        {"v4l2", {"width", "height", "fps_hz"}},
        {"bb2", {"config", "guid", "frame_rate_hz", "shutter_s", "gain_db"}},
        {"sim", {"enon"}}};
    const std::set<std::string>& keys = kKeys.at(kind);
    for (const auto& [k, v] : req.settings)
      if (!keys.count(k)) throw ConfigError(req.spec, k, "not a setting of a " + kind + " source");
  }
};

Intrinsics needCamera(const SourceRequest& r, const std::string& kind) {
  if (r.camera) return *r.camera;
  if (r.rig) return r.rig->left;
  throw ConfigError(r.spec, "a " + kind + " source needs a camera calibration (--camera)");
}

StereoRig needRig(const SourceRequest& r, const std::string& kind) {
  if (r.rig) return *r.rig;
  throw ConfigError(r.spec, "a " + kind + " source needs a stereo rig calibration (--stereo)");
}

// Sets `out` from a stereo source, giving the left eye to a mono request.
void deliverStereo(const SourceRequest& r, std::unique_ptr<StereoSource> s, OpenedSource* out) {
  if (r.eyes == Eyes::kMono)
    out->mono = std::make_unique<LeftEye>(std::move(s));
  else
    out->stereo = std::move(s);
}

void deliverMono(const SourceRequest& r, std::unique_ptr<FrameSource> s, OpenedSource* out) {
  if (r.eyes == Eyes::kStereo)
    throw ConfigError(r.spec, "is a mono source (" + out->kind + "); stereo needs a stereo one");
  out->mono = std::move(s);
}

}  // namespace

std::unique_ptr<StereoSource> onCallerClock(OpenedSource source) {
  if (!source.stereo)
    throw ConfigError(source.description, "a stereo camera is needed, this source is mono");
  return std::make_unique<CallerClock>(std::move(source.stereo), source.kind == "bb2");
}

const char* sourceSpecHelp() {
  return "recording:DIR | folder:DIR | folders:LEFT,RIGHT | video:FILE | v4l2:DEVICE | bb2[:GUID] |\n"
         "sim:SCENARIO.yaml | PATH (a recording, a folder with left/ and right/, an image folder or\n"
         "a video file)";
}

OpenedSource openSource(const SourceRequest& r) {
  std::string kind, target;
  const size_t colon = r.spec.find(':');
  static const std::set<std::string> kKinds = {"recording", "folder", "folders", "video",
                                               "v4l2",      "bb2",    "sim"};
  if (colon != std::string::npos && kKinds.count(r.spec.substr(0, colon))) {
    kind = r.spec.substr(0, colon);
    target = r.spec.substr(colon + 1);
  } else if (r.spec == "bb2") {
    kind = "bb2";
  } else {
    target = r.spec;
    std::error_code ec;
    if (target.empty()) throw ConfigError("(empty)", "no input given");
    if (!fs::exists(target, ec)) throw ConfigError(target, "no such file or folder");
    if (fs::is_directory(target, ec)) {
      if (files::isRecording(target))
        kind = "recording";
      else if (fs::is_directory(fs::path(target) / "left", ec) &&
               fs::is_directory(fs::path(target) / "right", ec)) {
        kind = "folders";
        target = (fs::path(target) / "left").string() + "," + (fs::path(target) / "right").string();
      } else {
        kind = "folder";
      }
    } else {
      kind = "video";
    }
  }
  OpenedSource out;
  out.kind = kind;
  out.description = kind + ":" + target;
  const Settings set{r};
  set.checkKeys(kind);

  if (kind == "recording") {
    files::Recording rec = files::Recording::open(target);
    out.frames = static_cast<int64_t>(rec.entries().size());
    out.warning = rec.warning();
    out.has_truth = !rec.entries().empty() && !rec.entries().front().truth.empty();
    if (rec.stereo() && r.eyes != Eyes::kMono)
      out.stereo = files::makeRecordingStereoSource(std::move(rec));
    else if (r.eyes != Eyes::kStereo)
      out.mono = files::makeRecordingMonoSource(std::move(rec));
    else
      throw ConfigError(target, "is a mono recording; stereo needs a stereo recording");
  } else if (kind == "folder" || kind == "folders") {
    files::FolderOptions fo;
    fo.stamps_file = set.get("stamps");
    fo.fps_hz = set.number("fps_hz", fo.fps_hz);
    fo.max_stamp_skew_s = set.number("max_stamp_skew_s", fo.max_stamp_skew_s);
    if (kind == "folder") {
      const Intrinsics cam = needCamera(r, kind);
      const files::ImageList list = files::listImages(target, fo);  // counts the frames
      out.frames = static_cast<int64_t>(list.files.size());
      deliverMono(r, files::makeFolderSource(target, cam, fo), &out);
    } else {
      const size_t comma = target.find(',');
      if (comma == std::string::npos)
        throw ConfigError(r.spec, "folders: needs LEFT_DIR,RIGHT_DIR");
      const std::string left = target.substr(0, comma), right = target.substr(comma + 1);
      StereoRig rig = needRig(r, kind);
      out.frames = static_cast<int64_t>(files::listImages(left, fo).files.size());
      deliverStereo(r, files::makeStereoFolderSource(left, right, rig, fo), &out);
    }
  } else if (kind == "video") {
    files::VideoOptions vo;
    vo.fps_hz = set.number("fps_hz", vo.fps_hz);
    deliverMono(r, files::makeVideoSource(target, needCamera(r, kind), vo), &out);
  } else if (kind == "v4l2") {
    files::WebcamOptions wo;
    wo.width = static_cast<int>(set.number("width", 0));
    wo.height = static_cast<int>(set.number("height", 0));
    wo.fps_hz = set.number("fps_hz", 0);
    out.live = true;
    deliverMono(r, files::makeWebcamSource(target, needCamera(r, kind), wo), &out);
  } else if (kind == "bb2") {
    const std::string config = set.get("config");
    dc1394::Bumblebee2Options bo = config.empty() ? dc1394::Bumblebee2Options{}
                                                  : dc1394::loadBumblebee2Options(config);
    if (!target.empty()) bo.guid = target;
    bo.guid = set.get("guid", bo.guid);
    bo.frame_rate_hz = set.number("frame_rate_hz", bo.frame_rate_hz);
    bo.shutter_s = set.number("shutter_s", bo.shutter_s);
    bo.gain_db = set.number("gain_db", bo.gain_db);
    try {
      bo.check();
    } catch (const std::invalid_argument& e) {
      throw ConfigError(r.spec, e.what());
    }
    const StereoRig rig = needRig(r, kind);
    out.live = true;
    out.description = "bb2:" + bo.guid;
    deliverStereo(r, std::make_unique<dc1394::Bumblebee2Camera>(dc1394::makeLibDc1394Device(), rig, bo),
                  &out);
  } else if (kind == "sim") {
    const EnonModel model = loadEnonModel(set.get("enon", "config/enon.yaml"));
    const sim::Scenario scenario = sim::loadScenario(target);
    out.has_truth = true;
    deliverStereo(r, sim::makeStandaloneSimCamera(model, scenario), &out);
  }
  return out;
}

}  // namespace refgrasp::robot
