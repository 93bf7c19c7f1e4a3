#include "targets.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "core/camera.h"
#include "core/error.h"
#include "core/image_io.h"
#include "detector/detector_config.h"
#include "detector/object.h"
#include "robot/enon_model.h"
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
