#include "targets.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

#include "core/camera.h"
#include "core/error.h"
#include "core/image_io.h"
#include "detector/detector_config.h"
#include "detector/object.h"
#include "robot/enon_model.h"
#include "robot/files/image_sources.h"
#include "robot/files/recording.h"
#include "robot/sim/scenario.h"

namespace refgrasp::fuzz {
namespace fs = std::filesystem;

namespace {

// A private tree mirroring the source tree's config/ and media/ (symlinks), so that the relative
// paths of the seeds (../../media/..., cameras/bb2_rig.yaml) resolve for the file under test.
const fs::path& tree() {
  static const fs::path root = [] {
    const fs::path r = fs::temp_directory_path() / ("refgrasp_fuzz_" + std::to_string(::getpid()));
    const fs::path src = REFGRASP_SOURCE_DIR;
    fs::create_directories(r / "config");
    std::error_code ec;
    fs::create_directory_symlink(src / "media", r / "media", ec);
    for (const auto& d : fs::directory_iterator(src / "config")) {
      if (!d.is_directory()) continue;
      fs::create_directories(r / "config" / d.path().filename());
      for (const auto& f : fs::directory_iterator(d.path()))
        fs::create_symlink(f.path(), r / "config" / d.path().filename() / f.path().filename(), ec);
    }
    return r;
  }();
  return root;
}

// Writes the input where the shipped files of its kind live; returns the path.
std::string place(const std::string& rel, const std::string& bytes) {
  const fs::path p = tree() / rel;
  std::ofstream(p, std::ios::binary | std::ios::trunc) << bytes;
  return p.string();
}

void objectFile(const std::string& b) { detector::loadObjectDefinition(place("config/objects/fuzz.yaml", b)); }
void cameraYaml(const std::string& b) { loadCameraFile(place("config/objects/fuzz_camera.yaml", b)); }
void cameraXml(const std::string& b) { loadCameraFile(place("config/cameras/fuzz_camera.xml", b)); }
void stereoRig(const std::string& b) { loadStereoRig(place("config/cameras/fuzz_rig.yaml", b)); }
void scenario(const std::string& b) { sim::loadScenario(place("config/scenarios/fuzz.yaml", b)); }
void robotModel(const std::string& b) { robot::loadEnonModel(place("config/fuzz_enon.yaml", b)); }
void detectorOptions(const std::string& b) { detector::loadDetectorOptions(place("config/fuzz_detector.yaml", b)); }
// Both ways the tools decode: as stored (recordings, image folders) and as gray (detector).
void image(const std::string& b) {
  ImageLimits limits;
  limits.max_pixels = 1 << 22;  // keep each execution fast; the check itself is what is tested
  decodeImage("fuzz", b, ImageMode::kUnchanged, limits);
  decodeImage("fuzz", b, ImageMode::kGray, limits);
}

// Recordings whose files the index seeds name (frames 0-2: frames/00000N.png mono,
// frames/00000N_left.png and _right.png stereo), written once by RecordingWriter: mono/,
// stereo/, and meta/ with both calibrations and an index line naming both kinds' files (so that
// a recording.json of either kind reads through to its index).
const fs::path& recordings() {
  static const fs::path root = [] {
    const fs::path r = tree() / "recordings";
    fs::remove_all(r);
    fs::create_directories(r);
    const Intrinsics cam = Intrinsics::pinhole(16, 12, 20, 7.5, 5.5);
    StereoRig rig{cam, cam, Pose{}};
    rig.lMr.t = Eigen::Vector3d(0.12, 0, 0);
    files::RecordingOptions o;
    o.fsync = false;
    auto mono = files::RecordingWriter::createMono((r / "mono").string(), cam, o);
    auto stereo = files::RecordingWriter::createStereo((r / "stereo").string(), rig, o);
    const cv::Mat image(12, 16, CV_8UC1, cv::Scalar(128));
    for (int i = 0; i < 3; ++i) {
      robot::MonoFrame m;
      m.image = image;
      m.stamp = 0.1 * i;
      m.index = i;
      mono->write(m);
      robot::StereoFrame st;
      st.left = st.right = image;
      st.stamp = 0.1 * i;
      st.index = i;
      stereo->write(st);
    }
    fs::copy(r / "stereo", r / "meta", fs::copy_options::recursive);
    fs::copy_file(r / "mono/calib/camera.yaml", r / "meta/calib/camera.yaml");
    for (int i = 0; i < 3; ++i) {
      const std::string f = "frames/00000" + std::to_string(i) + ".png";
      fs::copy_file(r / "mono" / f, r / "meta" / f);
    }
    std::ofstream(r / "meta/index.jsonl", std::ios::trunc)
        << "{\"frame\": 0, \"index\": 0, \"stamp\": 0, \"files\": {\"image\": \"frames/000000.png\", "
           "\"left\": \"frames/000000_left.png\", \"right\": \"frames/000000_right.png\"}}\n";
    return r;
  }();
  return root;
}

// The bytes as a recording's index.jsonl, read by a mono and by a stereo recording; refused
// (the stereo reader's ConfigError) when neither reads it.
void recordingIndex(const std::string& b) {
  bool read = false;
  for (const char* kind : {"mono", "stereo"}) {
    const fs::path d = recordings() / kind;
    std::ofstream(d / "index.jsonl", std::ios::binary | std::ios::trunc) << b;
    try {
      files::Recording::open(d.string());
      read = true;
    } catch (const ConfigError&) {
      if (!read && std::string(kind) == "stereo") throw;
    }
  }
}
// The bytes as a recording's recording.json (calibrations and index of both kinds beside it).
void recordingJson(const std::string& b) {
  const fs::path d = recordings() / "meta";
  std::ofstream(d / "recording.json", std::ios::binary | std::ios::trunc) << b;
  files::Recording::open(d.string());
}
// The bytes as an image folder's stamps file: the folder holds img_0..2.png and, for the
// "STAMP FILE" form, rgb/0.1.png, rgb/0.2.png, rgb/0.3.png.
void stampsFile(const std::string& b) {
  static const fs::path dir = [] {
    const fs::path d = tree() / "stamps";
    fs::create_directories(d / "rgb");
    const cv::Mat image(12, 16, CV_8UC1, cv::Scalar(128));
    for (int i = 0; i < 3; ++i) {
      cv::imwrite((d / ("img_" + std::to_string(i) + ".png")).string(), image);
      cv::imwrite((d / "rgb" / ("0." + std::to_string(i + 1) + ".png")).string(), image);
    }
    return d;
  }();
  files::FolderOptions o;
  o.stamps_file = (dir / "stamps.txt").string();
  std::ofstream(o.stamps_file, std::ios::binary | std::ios::trunc) << b;
  files::listImages(dir.string(), o);
}

}  // namespace

const std::vector<Target>& targets() {
  static const std::vector<Target> all = {
      {"object", objectFile, {"config/objects"}},
      {"camera_yaml", cameraYaml, {"config/cameras", "config/objects"}},
      {"camera_xml", cameraXml, {"fuzz/seeds/camera_xml"}},
      {"rig", stereoRig, {"config/cameras"}},
      {"scenario", scenario, {"config/scenarios"}},
      {"robot_model", robotModel, {"config"}},
      {"detector_options", detectorOptions, {"config"}},
      {"image", image, {"fuzz/seeds/image", "media/targets"}},
      {"recording_index", recordingIndex, {"fuzz/seeds/recording_index"}},
      {"recording_json", recordingJson, {"fuzz/seeds/recording_json"}},
      {"stamps", stampsFile, {"fuzz/seeds/stamps"}},
  };
  return all;
}

const Target* findTarget(const std::string& name) {
  for (const Target& t : targets())
    if (t.name == name) return &t;
  return nullptr;
}

std::string runChecked(const Target& target, const std::string& bytes) {
  try {
    target.run(bytes);
  } catch (const ConfigError&) {
  } catch (const std::invalid_argument&) {
  } catch (const std::exception& e) {
    return std::string("escaped: ") + e.what();
  } catch (...) {
    return "escaped: unknown exception";
  }
  return "";
}

}  // namespace refgrasp::fuzz
