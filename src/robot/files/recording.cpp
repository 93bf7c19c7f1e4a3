#include "robot/files/recording.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "core/error.h"
#include "core/file.h"
#include "core/image_io.h"
#include "robot/files/frame_json.h"

namespace refgrasp::files {

namespace fs = std::filesystem;

namespace {

std::string errnoText() { return std::strerror(errno); }

// Writes all of `n` bytes (retrying short writes); false with errno set on failure.
bool writeAll(int fd, const void* data, size_t n) {
  const char* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    if (w == 0) {
      errno = EIO;
      return false;
    }
    p += w;
    n -= static_cast<size_t>(w);
  }
  return true;
}

// `path` gets `bytes` atomically: hidden temporary name in the same folder, fsync, rename.
// "" on success, else a one-line error naming the file (the temporary is removed).
std::string writeFileAtomically(const fs::path& path, const std::vector<uchar>& bytes,
                                bool sync) {
  const fs::path tmp = path.parent_path() / ("." + path.filename().string() + ".tmp");
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return path.string() + ": cannot create: " + errnoText();
  std::string err;
  if (!writeAll(fd, bytes.data(), bytes.size()))
    err = path.string() + ": write failed: " + errnoText();
  else if (sync && ::fsync(fd) != 0)
    err = path.string() + ": fsync failed: " + errnoText();
  if (::close(fd) != 0 && err.empty()) err = path.string() + ": close failed: " + errnoText();
  if (err.empty() && ::rename(tmp.c_str(), path.c_str()) != 0)
    err = path.string() + ": rename failed: " + errnoText();
  if (!err.empty()) ::unlink(tmp.c_str());
  return err;
}

// Small text files at start-up (recording.json): atomic, throws ConfigError.
void writeTextAtomically(const fs::path& path, const std::string& text, bool sync) {
  const std::string err =
      writeFileAtomically(path, std::vector<uchar>(text.begin(), text.end()), sync);
  if (!err.empty()) throw ConfigError(path.string(), err.substr(path.string().size() + 2));
}

std::string frameName(int64_t frame, const char* suffix) {
  char buf[48];
  std::snprintf(buf, sizeof(buf), "%06lld%s.png", static_cast<long long>(frame), suffix);
  return buf;
}

std::string isoNow() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::string sizeText(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

// True when the file is a regular file that ends with the PNG IEND chunk (a write that stopped
// half-way leaves no end chunk). Cheap: reads 12 bytes; opened without blocking (a FIFO named by a
// hostile index is refused, not waited on).
bool pngComplete(const fs::path& p) {
  static const unsigned char kIend[12] = {0, 0, 0, 0, 'I', 'E', 'N', 'D', 0xAE, 0x42, 0x60, 0x82};
  const int fd = ::open(p.c_str(), O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
  if (fd < 0) return false;
  struct stat st {};
  unsigned char tail[12];
  const bool ok = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size >= 12 + 8 &&
                  ::pread(fd, tail, 12, st.st_size - 12) == 12 && std::memcmp(tail, kIend, 12) == 0;
  ::close(fd);
  return ok;
}

}  // namespace

void RecordingOptions::check() const {
  refgrasp::check(png_compression >= 0 && png_compression <= 9, "RecordingOptions.png_compression",
                  "must be in 0..9");
}

// ---- writer ------------------------------------------------------------------------------------

RecordingWriter::RecordingWriter(const std::string& dir, bool stereo,
                                 const RecordingOptions& options)
    : dir_(dir), stereo_(stereo), opt_(options) {
  opt_.check();
  std::error_code ec;
  if (fs::exists(dir_, ec) && !(fs::is_directory(dir_, ec) && fs::is_empty(dir_, ec)))
    throw ConfigError(dir_, "exists and is not an empty folder (refusing to overwrite)");
  fs::create_directories(fs::path(dir_) / "frames", ec);
  if (!ec) fs::create_directories(fs::path(dir_) / "calib", ec);
  if (ec) throw ConfigError(dir_, "cannot create the recording folder: " + ec.message());
}

std::unique_ptr<RecordingWriter> RecordingWriter::createStereo(const std::string& dir,
                                                               const StereoRig& rig,
                                                               const RecordingOptions& options) {
  std::unique_ptr<RecordingWriter> w(new RecordingWriter(dir, true, options));
  w->rig_ = rig;
  const fs::path d(dir);
  saveCameraFile((d / "calib/left.yaml").string(), rig.left, "left");
  saveCameraFile((d / "calib/right.yaml").string(), rig.right, "right");
  saveStereoRig((d / "calib/rig.yaml").string(), rig, "left.yaml", "right.yaml");
  w->start({{"rig", "calib/rig.yaml"}, {"left", "calib/left.yaml"}, {"right", "calib/right.yaml"}});
  return w;
}

std::unique_ptr<RecordingWriter> RecordingWriter::createMono(const std::string& dir,
                                                             const Intrinsics& camera,
                                                             const RecordingOptions& options) {
  std::unique_ptr<RecordingWriter> w(new RecordingWriter(dir, false, options));
  w->camera_ = camera;
  saveCameraFile((fs::path(dir) / "calib/camera.yaml").string(), camera, "camera");
  w->start({{"camera", "calib/camera.yaml"}});
  return w;
}

void RecordingWriter::start(const std::vector<std::pair<std::string, std::string>>& calibration) {
  const fs::path d(dir_);
  Json files = Json::object();
  for (const auto& [key, file] : calibration) files[key] = file;
  const Json meta = {{"format", kRecordingFormat},  {"version", kRecordingVersion},
                     {"kind", stereo_ ? "stereo" : "mono"}, {"calibration", files},
                     {"source", opt_.source},       {"created_by", opt_.created_by},
                     {"created_at", isoNow()}};
  writeTextAtomically(d / "recording.json", meta.dump(2) + "\n", opt_.fsync);
  index_fd_ = ::open((d / "index.jsonl").c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (index_fd_ < 0) throw ConfigError((d / "index.jsonl").string(), "cannot create: " + errnoText());
  frames_fd_ = ::open((d / "frames").c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (frames_fd_ < 0) throw ConfigError((d / "frames").string(), "cannot open: " + errnoText());
}

RecordingWriter::~RecordingWriter() {
  if (index_fd_ >= 0) ::close(index_fd_);
  if (frames_fd_ >= 0) ::close(frames_fd_);
}

WriteStatus RecordingWriter::failed(const std::string& error) {
  error_ = error;
  return {false, error, true};
}

WriteStatus RecordingWriter::write(const robot::StereoFrame& f, const robot::RobotState* robot) {
  if (!stereo_) return {false, dir_ + ": a stereo frame written to a mono recording"};
  return append({{&f.left, &rig_.left, "frames/" + frameName(frames_, "_left"), "left"},
                 {&f.right, &rig_.right, "frames/" + frameName(frames_, "_right"), "right"}},
                f.index, f.stamp, f.capture, f.truth, robot);
}

WriteStatus RecordingWriter::write(const robot::MonoFrame& f, const robot::RobotState* robot) {
  if (stereo_) return {false, dir_ + ": a mono frame written to a stereo recording"};
  return append({{&f.image, &camera_, "frames/" + frameName(frames_, ""), "image"}}, f.index,
                f.stamp, f.capture, f.truth, robot);
}

WriteStatus RecordingWriter::append(const std::vector<Image>& images, int64_t index,
                                    Seconds stamp, const robot::CaptureState& capture,
                                    const std::vector<robot::ObjectTruth>& truth,
                                    const robot::RobotState* robot) {
  if (!error_.empty()) return {false, error_, true};
  const std::string where = dir_ + ": frame " + std::to_string(frames_);
  // A bad frame is refused without spoiling the recording (the next good frame is written).
  for (const Image& im : images) {
    const cv::Mat& m = *im.image;
    if (m.empty() || m.depth() != CV_8U || (m.channels() != 1 && m.channels() != 3))
      return {false, where + ": " + im.key + " image is empty or not 8-bit gray/BGR"};
    if (m.cols != im.camera->width || m.rows != im.camera->height)
      return {false, where + ": " + im.key + " image is " + sizeText(m.cols, m.rows) +
                         ", the calibration is " + sizeText(im.camera->width, im.camera->height)};
  }
  if (!std::isfinite(stamp)) return {false, where + ": stamp is not finite"};

  Json files = Json::object();
  std::vector<fs::path> written;  // removed again when the frame cannot be completed
  const auto fail = [&](const std::string& err) {
    for (const fs::path& p : written) ::unlink(p.c_str());
    return failed(err);
  };
  for (const Image& im : images) {
    std::vector<uchar> png;
    try {
      if (!cv::imencode(".png", *im.image, png, {cv::IMWRITE_PNG_COMPRESSION, opt_.png_compression}))
        return {false, where + ": PNG encoding failed"};
    } catch (const cv::Exception& e) {
      return {false, where + ": PNG encoding failed: " + e.what()};
    }
    const fs::path path = fs::path(dir_) / im.file;
    const std::string err = writeFileAtomically(path, png, opt_.fsync);
    if (!err.empty()) return fail(err);
    written.push_back(path);
    files[im.key] = im.file;
  }
  if (opt_.fsync && ::fsync(frames_fd_) != 0)
    return fail(dir_ + "/frames: fsync failed: " + errnoText());

  Json line = {{"frame", frames_}, {"index", index}, {"stamp", stamp}, {"files", files},
               {"capture", captureToJson(capture)}};
  if (!truth.empty()) line["truth"] = truthToJson(truth);
  if (robot) line["robot"] = robotStateToJson(*robot);
  const std::string text = line.dump() + "\n";
  const std::string index_path = dir_ + "/index.jsonl";
  if (!writeAll(index_fd_, text.data(), text.size())) {
    const std::string err = index_path + ": write failed: " + errnoText();
    // Cut a partly written line so that the index stays valid (readers cope if this fails too).
    if (::ftruncate(index_fd_, index_size_) != 0) { /* the reader drops a truncated last line */ }
    return fail(err);
  }
  index_size_ += static_cast<long long>(text.size());
  ++frames_;
  // The line is in the index (and its images on disk): keep them, but stop recording.
  if (opt_.fsync && ::fsync(index_fd_) != 0)
    return failed(index_path + ": fsync failed: " + errnoText());
  return {};
}

// ---- reader ------------------------------------------------------------------------------------

bool isRecording(const std::string& dir) {
  std::error_code ec;
  return fs::is_regular_file(fs::path(dir) / "recording.json", ec);
}

namespace {

// The checks of one index line: "" with *e filled, else the problem (the recording ends there).
std::string parseIndexLine(std::string_view line, const fs::path& d, bool stereo,
                           size_t expected_frame, IndexEntry* e) {
  Json j;
  try {
    j = Json::parse(line);
  } catch (const std::exception&) {
    return "not valid JSON";
  }
  std::string problem;
  const auto integer = [&](const char* key, int64_t* out) {
    if (!j.contains(key) || !j[key].is_number_integer()) {
      problem = std::string(key) + ": missing or not an integer";
      return false;
    }
    *out = j[key].get<int64_t>();
    return true;
  };
  if (!j.is_object() || !integer("frame", &e->frame) || !integer("index", &e->index))
    return problem.empty() ? "not an object" : problem;
  if (e->frame != static_cast<int64_t>(expected_frame))
    return "frame " + std::to_string(e->frame) + " out of order (expected " +
           std::to_string(expected_frame) + ")";
  if (!j.contains("stamp") || !j["stamp"].is_number() || !std::isfinite(j["stamp"].get<double>()))
    return "stamp: missing or not a finite number";
  e->stamp = j["stamp"].get<double>();
  const bool files_ok = j.contains("files") && j["files"].is_object();
  for (const char* k : stereo ? std::vector<const char*>{"left", "right"} : std::vector<const char*>{"image"}) {
    if (!files_ok || !j["files"].contains(k) || !j["files"][k].is_string())
      return std::string("files: needs ") + (stereo ? "left and right" : "image");
    e->files.push_back(j["files"][k].get<std::string>());
  }
  for (const std::string& f : e->files)
    if (!pngComplete(d / f)) return (d / f).string() + " is missing or truncated";
  if (j.contains("capture") && !captureFromJson(j["capture"], &e->capture, &problem))
    return "capture." + problem;
  if (j.contains("truth") && !truthFromJson(j["truth"], &e->truth, &problem)) return problem;
  if (j.contains("robot")) {
    robot::RobotState s;
    if (!robotStateFromJson(j["robot"], &s, &problem)) return "robot." + problem;
    e->robot = s;
  }
  return "";
}

}  // namespace

void Recording::readMeta(const std::string& meta_path) {
  const fs::path d(dir_);
  if (regularFileProblem(meta_path, kMaxConfigFileBytes) == "file not found")
    throw ConfigError(meta_path, "missing: not a refgrasp recording");
  Json meta;
  try {
    meta = Json::parse(readRegularFile(meta_path, kMaxConfigFileBytes));
  } catch (const ConfigError&) {
    throw;
  } catch (const std::exception&) {
    throw ConfigError(meta_path, "not valid JSON");
  }
  if (!meta.is_object()) throw ConfigError(meta_path, "not a JSON object");
  const auto str = [&](const char* key) {
    if (!meta.contains(key) || !meta[key].is_string())
      throw ConfigError(meta_path, key, "missing or not a string");
    return meta[key].get<std::string>();
  };
  if (str("format") != kRecordingFormat)
    throw ConfigError(meta_path, "format", "is not " + std::string(kRecordingFormat));
  if (!meta.contains("version") || !meta["version"].is_number_integer())
    throw ConfigError(meta_path, "version", "missing or not an integer");
  const int64_t version = meta["version"].get<int64_t>();
  if (version > kRecordingVersion || version < 1)
    throw ConfigError(meta_path, "version",
                      std::to_string(version) + " is not supported (this reader: " +
                          std::to_string(kRecordingVersion) + ")");
  const std::string kind = str("kind");
  if (kind != "mono" && kind != "stereo") throw ConfigError(meta_path, "kind", "must be mono or stereo");
  stereo_ = kind == "stereo";
  if (meta.contains("source") && meta["source"].is_string()) source_ = meta["source"];
  if (!meta.contains("calibration") || !meta["calibration"].is_object())
    throw ConfigError(meta_path, "calibration", "missing");
  const auto calib = [&](const char* key) {
    const Json& c = meta["calibration"];
    if (!c.contains(key) || !c[key].is_string())
      throw ConfigError(meta_path, std::string("calibration.") + key, "missing or not a string");
    const std::string p = (d / c[key].get<std::string>()).string();
    calibration_.emplace_back(key, p);
    return p;
  };
  try {
    if (stereo_) {
      rig_ = loadStereoRig(calib("rig"));
      calib("left");
      calib("right");
    } else {
      camera_ = loadCameraFile(calib("camera"));
    }
  } catch (const ConfigError& e) {
    throw ConfigError(meta_path, "calibration", e.what());
  }
}

Recording Recording::open(const std::string& dir) {
  Recording r;
  r.dir_ = dir;
  const fs::path d(dir);
  std::error_code ec;
  if (!fs::is_directory(d, ec)) throw ConfigError(dir, "no such folder");
  r.readMeta((d / "recording.json").string());

  const std::string index_path = (d / "index.jsonl").string();
  if (regularFileProblem(index_path, kMaxIndexBytes) == "file not found")
    throw ConfigError(index_path, "missing");
  std::string why;
  uint64_t bad_line = 0;
  forEachLine(index_path, kMaxIndexBytes, kMaxIndexLineBytes, [&](const TextLine& l) {
    if (r.entries_.size() >= kMaxIndexFrames)
      throw ConfigError(index_path, "line " + std::to_string(l.number),
                        "more than " + std::to_string(kMaxIndexFrames) + " frames (the reader's limit)");
    IndexEntry e;
    why = l.complete ? parseIndexLine(l.text, d, r.stereo_, r.entries_.size(), &e)
                     : "truncated (no end of line)";
    if (why.empty()) r.entries_.push_back(std::move(e));
    bad_line = l.number;
    return why.empty();
  });
  const std::string where = "line " + std::to_string(bad_line);
  // "Nothing to do" is an error: a tool fed an empty recording says so instead of succeeding.
  if (r.entries_.empty() && why.empty())
    throw ConfigError(index_path, "no frames (an empty recording): nothing to do");
  if (r.entries_.empty()) throw ConfigError(index_path, where, why + "; no frame before it: nothing to do");
  if (!why.empty())
    r.warning_ = index_path + ": " + where + ": " + why + "; read the " +
                 std::to_string(r.entries_.size()) + " frames before it";
  return r;
}

const std::string& Recording::calibrationFile(const std::string& key) const {
  static const std::string none;
  for (const auto& [k, p] : calibration_)
    if (k == key) return p;
  return none;
}

bool Recording::readImage(const std::string& rel, const Intrinsics& cam, cv::Mat* out,
                          std::string* error) const {
  const std::string path = (fs::path(dir_) / rel).string();
  ImageRead img = refgrasp::readImage(path, ImageMode::kUnchanged);  // not this member
  if (!img.ok()) {
    *error = img.error;
    return false;
  }
  *out = std::move(img.image);
  if (out->depth() != CV_8U || (out->channels() != 1 && out->channels() != 3)) {
    *error = path + ": cannot decode as an 8-bit gray or BGR image";
    return false;
  }
  if (out->cols != cam.width || out->rows != cam.height) {
    *error = path + ": image is " + sizeText(out->cols, out->rows) + ", the calibration is " +
             sizeText(cam.width, cam.height);
    return false;
  }
  return true;
}

bool Recording::read(size_t i, robot::StereoFrame* f, std::string* error) const {
  if (!stereo_) {
    *error = dir_ + ": a mono recording has no stereo frames";
    return false;
  }
  const IndexEntry& e = entries_.at(i);
  *f = {};
  if (!readImage(e.files[0], rig_.left, &f->left, error) ||
      !readImage(e.files[1], rig_.right, &f->right, error))
    return false;
  f->stamp = e.stamp;
  f->index = e.index;
  f->capture = e.capture;
  f->truth = e.truth;
  return true;
}

bool Recording::read(size_t i, robot::MonoFrame* f, std::string* error) const {
  const IndexEntry& e = entries_.at(i);
  *f = {};
  if (!readImage(e.files[0], camera(), &f->image, error)) return false;
  f->stamp = e.stamp;
  f->index = e.index;
  f->capture = e.capture;
  f->truth = e.truth;
  return true;
}

// ---- sources -----------------------------------------------------------------------------------

namespace {

template <class Base, class Frame>
class RecordingSource : public Base {
 public:
  explicit RecordingSource(Recording rec) : rec_(std::move(rec)) {}
  robot::ReturnType grab(Seconds, std::optional<Frame>* frame) override {
    frame->reset();
    if (next_ >= rec_.entries().size()) return robot::ReturnType::kDeactivate;
    Frame f;
    if (!rec_.read(next_++, &f, &error_)) return robot::ReturnType::kError;
    *frame = std::move(f);
    return robot::ReturnType::kOk;
  }
  std::string lastError() const override { return error_; }

 protected:
  Recording rec_;
  size_t next_ = 0;
  std::string error_;
};

class StereoRecordingSource : public RecordingSource<robot::StereoSource, robot::StereoFrame> {
 public:
  using RecordingSource::RecordingSource;
  const StereoRig& rig() const override { return rec_.rig(); }
};

class MonoRecordingSource : public RecordingSource<robot::FrameSource, robot::MonoFrame> {
 public:
  using RecordingSource::RecordingSource;
  const Intrinsics& camera() const override { return rec_.camera(); }
};

}  // namespace

std::unique_ptr<robot::StereoSource> makeRecordingStereoSource(Recording recording) {
  if (!recording.stereo())
    throw ConfigError(recording.dir(), "is a mono recording; stereo needs a stereo recording");
  return std::make_unique<StereoRecordingSource>(std::move(recording));
}

std::unique_ptr<robot::FrameSource> makeRecordingMonoSource(Recording recording) {
  return std::make_unique<MonoRecordingSource>(std::move(recording));
}

}  // namespace refgrasp::files
