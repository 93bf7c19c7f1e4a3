#include "robot/files/image_sources.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <sstream>

#include "core/error.h"
#include "core/file.h"
#include "core/image_io.h"

namespace refgrasp::files {

namespace fs = std::filesystem;
using robot::ReturnType;

namespace {

std::string sizeText(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

// "" when the image suits the camera, else the problem.
std::string checkImage(const cv::Mat& m, const Intrinsics& cam) {
  if (m.empty()) return "cannot decode as an image";
  if (m.depth() != CV_8U || (m.channels() != 1 && m.channels() != 3))
    return "not an 8-bit gray or BGR image";
  if (m.cols != cam.width || m.rows != cam.height)
    return "image is " + sizeText(m.cols, m.rows) + ", the calibration is " +
           sizeText(cam.width, cam.height);
  return "";
}


// Reads an 8-bit gray or BGR image (as stored) for `cam`; "" or "<path>: <problem>".
std::string loadFrameImage(const std::string& path, const Intrinsics& cam, cv::Mat* out) {
  ImageRead img = readImage(path, ImageMode::kAnyColor);
  if (!img.ok()) return img.error;
  *out = std::move(img.image);
  const std::string problem = checkImage(*out, cam);
  return problem.empty() ? "" : path + ": " + problem;
}

std::string trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t\r");
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(" \t\r") - a + 1);
}

std::string msText(double s) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.3f ms", s * 1e3);
  return buf;
}

class FolderSource : public robot::FrameSource {
 public:
  FolderSource(ImageList list, const Intrinsics& cam) : list_(std::move(list)), cam_(cam) {}
  const Intrinsics& camera() const override { return cam_; }
  ReturnType grab(Seconds, std::optional<robot::MonoFrame>* frame) override {
    frame->reset();
    if (next_ >= list_.files.size()) return ReturnType::kDeactivate;
    const size_t i = next_++;
    robot::MonoFrame f;
    error_ = loadFrameImage(list_.files[i], cam_, &f.image);
    if (!error_.empty()) return ReturnType::kError;
    f.stamp = list_.stamps[i];
    f.index = static_cast<int64_t>(i);
    *frame = std::move(f);
    return ReturnType::kOk;
  }
  std::string lastError() const override { return error_; }

 private:
  ImageList list_;
  Intrinsics cam_;
  size_t next_ = 0;
  std::string error_;
};

class StereoFolderSource : public robot::StereoSource {
 public:
  StereoFolderSource(ImageList left, ImageList right, const StereoRig& rig, double max_skew_s)
      : left_(std::move(left)), right_(std::move(right)), rig_(rig), max_skew_s_(max_skew_s) {}
  const StereoRig& rig() const override { return rig_; }
  ReturnType grab(Seconds, std::optional<robot::StereoFrame>* frame) override {
    frame->reset();
    if (next_ >= left_.files.size()) return ReturnType::kDeactivate;
    const size_t i = next_++;
    const double skew = right_.stamps[i] - left_.stamps[i];
    if (std::abs(skew) > max_skew_s_) {
      char buf[160];
      std::snprintf(buf, sizeof(buf),
                    ": pair %zu: stamps differ by %s (left %.6f s, right %.6f s; max %s)", i,
                    msText(std::abs(skew)).c_str(), left_.stamps[i], right_.stamps[i],
                    msText(max_skew_s_).c_str());
      error_ = right_.files[i] + buf;
      return ReturnType::kError;
    }
    robot::StereoFrame f;
    error_ = loadFrameImage(left_.files[i], rig_.left, &f.left);
    if (error_.empty()) error_ = loadFrameImage(right_.files[i], rig_.right, &f.right);
    if (!error_.empty()) return ReturnType::kError;
    f.stamp = left_.stamps[i];
    f.index = static_cast<int64_t>(i);
    *frame = std::move(f);
    return ReturnType::kOk;
  }
  std::string lastError() const override { return error_; }

 private:
  ImageList left_, right_;
  StereoRig rig_;
  double max_skew_s_;
  size_t next_ = 0;
  std::string error_;
};

// A cv::VideoCapture whose first frame was read at open (so that an undecodable file is a
// start-up error); shared by the video file and the webcam sources.
class CaptureSource : public robot::FrameSource {
 public:
  CaptureSource(std::string name, std::unique_ptr<cv::VideoCapture> cap, const Intrinsics& cam,
                double fps_hz)
      : name_(std::move(name)), cap_(std::move(cap)), cam_(cam), fps_hz_(fps_hz) {
    read();
  }
  bool firstFrameOk() const { return !frame_.image.empty(); }
  std::string firstFrameProblem() const { return checkImage(frame_.image, cam_); }

  const Intrinsics& camera() const override { return cam_; }
  ReturnType grab(Seconds, std::optional<robot::MonoFrame>* frame) override {
    frame->reset();
    if (!pending_) read();
    pending_ = false;
    if (frame_.image.empty()) return ReturnType::kDeactivate;
    const std::string problem = checkImage(frame_.image, cam_);
    if (!problem.empty()) {
      error_ = name_ + ": frame " + std::to_string(frame_.index) + ": " + problem;
      return ReturnType::kError;
    }
    *frame = frame_;
    return ReturnType::kOk;
  }
  std::string lastError() const override { return error_; }

 private:
  void read() {
    frame_ = {};
    cv::Mat m;
    try {
      if (!cap_->read(m)) m.release();
    } catch (const cv::Exception&) {
      m.release();
    }
    if (m.empty()) return;
    frame_.image = m;
    frame_.index = count_++;
    const double ms = cap_->get(cv::CAP_PROP_POS_MSEC);
    frame_.stamp = fps_hz_ > 0 || !std::isfinite(ms) || ms < 0
                       ? static_cast<double>(frame_.index) / (fps_hz_ > 0 ? fps_hz_ : 30.0)
                       : ms * 1e-3;
    pending_ = true;
  }

  std::string name_;
  std::unique_ptr<cv::VideoCapture> cap_;
  Intrinsics cam_;
  double fps_hz_;
  robot::MonoFrame frame_;
  bool pending_ = false;
  int64_t count_ = 0;
  std::string error_;
};

}  // namespace

bool hasImageExtension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  static const char* kExt[] = {".png", ".jpg", ".jpeg", ".bmp", ".pgm", ".ppm",
                               ".pnm", ".tif", ".tiff", ".webp"};
  return std::any_of(std::begin(kExt), std::end(kExt), [&](const char* e) { return ext == e; });
}

void FolderOptions::check() const {
  refgrasp::check(std::isfinite(fps_hz) && fps_hz > 0, "FolderOptions.fps_hz", "must be positive");
  refgrasp::check(std::isfinite(max_stamp_skew_s) && max_stamp_skew_s >= 0,
                  "FolderOptions.max_stamp_skew_s", "must be >= 0");
}

void VideoOptions::check() const {
  refgrasp::check(std::isfinite(fps_hz) && fps_hz >= 0, "VideoOptions.fps_hz", "must be >= 0");
}

void WebcamOptions::check() const {
  refgrasp::check(width >= 0 && height >= 0, "WebcamOptions.width/height", "must be >= 0");
  refgrasp::check(std::isfinite(fps_hz) && fps_hz >= 0, "WebcamOptions.fps_hz", "must be >= 0");
}

namespace {

// The stamps file `stamps` of folder `dir` into list->stamps, and the files its "STAMP FILE"
// lines name into *listed.
void readStamps(const std::string& stamps, const std::string& dir, ImageList* list,
                std::vector<std::string>* listed) {
  if (regularFileProblem(stamps, kMaxStampsFileBytes) == "file not found")
    throw ConfigError(stamps, "cannot read the stamps file");
  list->stamps_file = stamps;
  int columns = 0;
  forEachLine(stamps, kMaxStampsFileBytes, kMaxStampsLineBytes, [&](const TextLine& l) {
    const std::string line = trim(std::string(l.text));
    if (line.empty() || line[0] == '#') return true;
    const std::string where = "line " + std::to_string(l.number);
    if (list->stamps.size() >= kMaxStamps)
      throw ConfigError(stamps, where, "more than " + std::to_string(kMaxStamps) + " stamps (the reader's limit)");
    std::istringstream ss(line);
    std::string a, b;
    ss >> a >> b;
    const int cols = b.empty() ? 1 : 2;
    if (columns != 0 && cols != columns)
      throw ConfigError(stamps, where, "mixes 'STAMP' and 'STAMP FILE' lines");
    columns = cols;
    double t = 0;
    try {
      size_t used = 0;
      t = std::stod(a, &used);
      if (used != a.size()) throw std::invalid_argument(a);
    } catch (const std::exception&) {
      throw ConfigError(stamps, where, "'" + a + "' is not a time stamp (seconds)");
    }
    if (!std::isfinite(t)) throw ConfigError(stamps, where, "stamp is not finite");
    if (!list->stamps.empty() && t <= list->stamps.back())
      throw ConfigError(stamps, where, "stamps must increase");
    list->stamps.push_back(t);
    if (cols == 2) {
      std::error_code ec;
      const fs::path f = fs::path(b).is_absolute() ? fs::path(b) : fs::path(dir) / b;
      if (!fs::is_regular_file(f, ec)) throw ConfigError(stamps, where, f.string() + ": no such file");
      listed->push_back(f.string());
    }
    return true;
  });
}

}  // namespace

ImageList listImages(const std::string& dir, const FolderOptions& opt) {
  opt.check();
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw ConfigError(dir, "no such folder");
  ImageList list;
  list.dir = dir;
  std::string stamps = opt.stamps_file;
  if (stamps.empty() && fs::is_regular_file(fs::path(dir) / "stamps.txt", ec))
    stamps = (fs::path(dir) / "stamps.txt").string();
  std::vector<std::string> listed;  // files named by a "STAMP FILE" stamps file
  if (!stamps.empty()) readStamps(stamps, dir, &list, &listed);
  if (!listed.empty()) {
    list.files = listed;
  } else {
    for (const auto& e : fs::directory_iterator(dir, ec))
      if (e.is_regular_file(ec) && hasImageExtension(e.path().string()))
        list.files.push_back(e.path().string());
    std::sort(list.files.begin(), list.files.end());
  }
  if (list.files.empty()) throw ConfigError(dir, "no image files in the folder: nothing to do");
  if (list.stamps_file.empty()) {
    for (size_t i = 0; i < list.files.size(); ++i)
      list.stamps.push_back(static_cast<double>(i) / opt.fps_hz);
  } else if (list.stamps.size() != list.files.size()) {
    throw ConfigError(list.stamps_file, std::to_string(list.stamps.size()) + " stamps for " +
                                            std::to_string(list.files.size()) + " images in " + dir);
  }
  return list;
}

std::unique_ptr<robot::FrameSource> makeFolderSource(const std::string& dir,
                                                     const Intrinsics& camera,
                                                     const FolderOptions& options) {
  return std::make_unique<FolderSource>(listImages(dir, options), camera);
}

std::unique_ptr<robot::StereoSource> makeStereoFolderSource(const std::string& left_dir,
                                                            const std::string& right_dir,
                                                            const StereoRig& rig,
                                                            const FolderOptions& options) {
  FolderOptions left_opt = options, right_opt = options;
  // An explicit stamps file applies to the left folder; each folder may carry its own stamps.txt.
  right_opt.stamps_file.clear();
  ImageList left = listImages(left_dir, left_opt), right = listImages(right_dir, right_opt);
  if (left.files.size() != right.files.size())
    throw ConfigError(right_dir, std::to_string(right.files.size()) + " images, but " + left_dir +
                                     " has " + std::to_string(left.files.size()));
  return std::make_unique<StereoFolderSource>(std::move(left), std::move(right), rig,
                                              options.max_stamp_skew_s);
}

std::unique_ptr<robot::FrameSource> makeVideoSource(const std::string& path,
                                                    const Intrinsics& camera,
                                                    const VideoOptions& options) {
  options.check();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw ConfigError(path, "no such file");
  auto cap = std::make_unique<cv::VideoCapture>();
  try {
    cap->open(path, cv::CAP_FFMPEG);
  } catch (const cv::Exception&) {
  }
  if (!cap->isOpened()) throw ConfigError(path, "cannot decode as a video (FFmpeg)");
  // A container that declares no frame (e.g. an AVI written without any) is said to be empty.
  const bool declared_empty = cap->get(cv::CAP_PROP_FRAME_COUNT) == 0;
  auto src = std::make_unique<CaptureSource>(path, std::move(cap), camera, options.fps_hz);
  if (!src->firstFrameOk())
    throw ConfigError(path, declared_empty ? "has no frames (an empty video): nothing to do"
                                           : "cannot decode as a video (no frame decoded)");
  return src;
}

std::unique_ptr<robot::FrameSource> makeWebcamSource(const std::string& device,
                                                     const Intrinsics& camera,
                                                     const WebcamOptions& options) {
  options.check();
  auto cap = std::make_unique<cv::VideoCapture>();
  const bool numeric = !device.empty() && std::all_of(device.begin(), device.end(), ::isdigit);
  const std::string path = numeric ? "/dev/video" + device : device;
  std::error_code ec;
  if (!fs::exists(path, ec)) throw ConfigError(path, "no such V4L2 device");
  try {
    cap->open(path, cv::CAP_V4L2);
    if (cap->isOpened()) {
      if (options.width > 0) cap->set(cv::CAP_PROP_FRAME_WIDTH, options.width);
      if (options.height > 0) cap->set(cv::CAP_PROP_FRAME_HEIGHT, options.height);
      if (options.fps_hz > 0) cap->set(cv::CAP_PROP_FPS, options.fps_hz);
      cap->set(cv::CAP_PROP_BUFFERSIZE, 1);
    }
  } catch (const cv::Exception&) {
  }
  if (!cap->isOpened()) throw ConfigError(path, "cannot open the V4L2 device");
  auto src = std::make_unique<CaptureSource>(path, std::move(cap), camera, 0);
  if (!src->firstFrameOk()) throw ConfigError(path, "the V4L2 device delivers no frame");
  const std::string problem = src->firstFrameProblem();
  if (!problem.empty()) throw ConfigError(path, problem);
  return src;
}

}  // namespace refgrasp::files
