// Hostile input to every tool, as a careless or hostile user would give it: each case
// ends with ONE line on stderr naming the file or option and the problem, and the exit code the
// tool documents; never a crash, a hang, a third-party message or CLI11's own codes (104-114).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <vector>

#include "common/app_run.h"
#include "common/hostile.h"
#include "common/temp_dir.h"

namespace fs = std::filesystem;
using refgrasp::testing::AppRun;
using refgrasp::testing::readFile;
using namespace refgrasp::testing;

namespace {

const std::string kSource = REFGRASP_SOURCE_DIR;
const std::string kEnon = kSource + "/config/enon.yaml";
const std::string kScenario = kSource + "/config/scenarios/table_single.yaml";
const std::string kTexture = kSource + "/media/targets/cereal_box.png";
const std::string kObjectCamera = kSource + "/config/objects/cereal_box_camera.yaml";

fs::path dir() { return refgrasp::testing::tempDir("refgrasp_test_hostile_apps"); }

std::string write(const std::string& name, const std::string& bytes) {
  const fs::path p = dir() / name;
  fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << bytes;
  return p.string();
}

std::string q(const std::string& s) { return "'" + s + "'"; }

// Runs `app args` with stdout to `out` (a file, or /dev/full) and stderr captured.
AppRun run(const std::string& app, const std::string& args, const std::string& out = "") {
  const fs::path o = dir() / (app + "_stdout.txt"), e = dir() / (app + "_stderr.txt");
  const std::string cmd = "timeout 120 " + std::string(REFGRASP_APP_DIR) + "/" + app + " " + args +
                          " > " + (out.empty() ? o.string() : out) + " 2> " + e.string() + " < /dev/null";
  const int st = std::system(cmd.c_str());
  return {WIFEXITED(st) ? WEXITSTATUS(st) : -1, out.empty() ? readFile(o) : "", readFile(e)};
}

size_t lines(const std::string& s) { return static_cast<size_t>(std::count(s.begin(), s.end(), '\n')); }

// The contract: the code, exactly one line of ours, naming `needle`; nothing from a library.
void expectOneLine(const AppRun& r, int code, const std::string& needle, const std::string& what) {
  EXPECT_EQ(r.status, code) << what << ": " << r.err;
  EXPECT_EQ(lines(r.err), 1u) << what << ": " << r.err;
  EXPECT_NE(r.err.find(needle), std::string::npos) << what << ": " << r.err;
  for (const char* chatter : {"libpng", "[ WARN", "terminate called", "OpenCV(", "Corrupt JPEG data:\n"})
    EXPECT_EQ(r.err.find(chatter), std::string::npos) << what << ": " << r.err;
}

std::string fifoPath() {
  const std::string fifo = (dir() / "pipe.png").string();
  if (!fs::exists(fifo)) ::mkfifo(fifo.c_str(), 0600);
  return fifo;
}

// The hostile images every image-reading tool gets, with the problem each must report.
struct BadImage {
  std::string path, problem;
};
std::vector<BadImage> badImages() {
  std::mt19937_64 rng(72);
  const std::string png = encodeImage(".png", noiseImage(rng, 64, 48)), jpg = encodeImage(".jpg", noiseImage(rng, 64, 48));
  const std::string fifo = fifoPath();
  fs::create_directories(dir() / "folder.png");
  return {
      {write("bomb.png", pngDeclaring(20000, 20000)), "PNG declares 20000x20000 pixels, more than the limit"},
      {write("cut.png", png.substr(0, png.size() / 2)), "truncated PNG"},
      {write("cut.jpg", jpg.substr(0, jpg.size() / 2)), "truncated JPEG"},
      {write("warn.jpg", corruptJpeg(jpg)), "corrupt JPEG"},
      {write("text.png", "not an image"), "not an image in a supported format"},
      {fifo, "is a FIFO, not a regular file"},
      {(dir() / "folder.png").string(), "is a directory"},
      {(dir() / "missing.png").string(), "file not found"},
  };
}

// An object definition with `extra` lines, images and camera from the source tree.
std::string objectFile(const std::string& name, const std::string& extra,
                       const std::string& image = kTexture) {
  return write(name, "reference_image: " + image + "\ncamera: " + kObjectCamera + "\n" + extra);
}
const std::string kPose = "reference_pose: {translation: [0, 0, 0.5], rotation_vector: [0, 0, 0]}\n";

std::string scenarioWith(const std::string& name, const std::string& from, const std::string& to) {
  return shippedVariant("config/scenarios/table_single.yaml", dir() / (name + ".yaml"), from, to);
}
std::string enonWith(const std::string& name, const std::string& from, const std::string& to) {
  return shippedVariant("config/enon.yaml", dir() / (name + "_enon.yaml"), from, to);
}


// Option errors: CLI11 parse errors and NaN/inf/out-of-range numbers, each the bad-input code.
void expectOptionErrors(const std::string& app, const std::string& base,
                        const std::vector<std::string>& bad, int code) {
  for (const std::string& args : bad) expectOneLine(run(app, base + " " + args), code, app + ": ", args);
  EXPECT_EQ(run(app, "--help").status, 0) << app;
}

}  // namespace

TEST(HostileDetectObject, BadImagesAreOneLineEachAndTheGoodOneIsStillProcessed) {
  const std::vector<BadImage> bad = badImages();
  std::string args = "--object " + kSource + "/config/objects/cereal_box.yaml " + kTexture;
  for (const BadImage& b : bad) args += " " + q(b.path);
  const AppRun r = run("detect_object", args);
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_EQ(lines(r.out), 1u) << r.out;  // the good image's JSON line
  EXPECT_NE(r.out.find("\"found\":true"), std::string::npos) << r.out;
  EXPECT_EQ(lines(r.err), bad.size()) << r.err;
  for (const BadImage& b : bad)
    EXPECT_NE(r.err.find(b.path + ": cannot read image: " + b.problem), std::string::npos) << b.path << "\n" << r.err;
  EXPECT_EQ(r.err.find("libpng"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("[ WARN"), std::string::npos) << r.err;
}

TEST(HostileDetectObject, BadFilesAndOptionsExit2AndAFullDiskExit3) {
  const std::string obj = "--object " + kSource + "/config/objects/cereal_box.yaml ";
  expectOptionErrors("detect_object", obj + kTexture,
                     {"--bogus", "--ratio nan"}, 2);
  const auto objectCase = [&](const std::string& file, const std::string& needle) {
    expectOneLine(run("detect_object", "--object " + file + " " + kTexture), 2, needle, file);
  };
  objectCase(objectFile("typo.yaml", "referance_pose: {translation: [0, 0, 0.5], rotation_vector: [0, 0, 0]}\n"),
             "typo.yaml: referance_pose: unknown field (did you mean reference_pose?)");
  objectCase(objectFile("typo2.yaml", kPose + "pattern_regoin: [[0, 0], [10, 0], [10, 10]]\n"),
             "pattern_regoin: unknown field (did you mean pattern_region?)");
  objectCase(objectFile("twice.yaml", kPose + "camera: " + kObjectCamera + "\n"), "twice.yaml: camera: given twice");
  objectCase(objectFile("nested.yaml", "reference_pose: {translation: [0, 0, 0.5], rotaton_vector: [0, 0, 0]}\n"),
             "reference_pose.rotaton_vector: unknown field (did you mean rotation_vector?)");
  // 100,000 points: the simplicity test is quadratic, so the loader refuses more than 1000.
  std::string region = "pattern_region: [";
  for (int i = 0; i < 100000; ++i) region += (i ? ", [" : "[") + std::to_string(i % 400) + ", " + std::to_string(i % 7) + "]";
  objectCase(objectFile("region.yaml", kPose + region + "]\n"), "pattern_region: 100000 points, more than the limit of 1000");
  objectCase(objectFile("bombref.yaml", kPose, write("bombref.png", pngDeclaring(20000, 20000))),
             "reference_image: " + (dir() / "bombref.png").string() + ": PNG declares 20000x20000");
  const std::string fifo = fifoPath();
  objectCase(fifo, fifo + ": is a FIFO, not a regular file");
  const std::string transposed = write("transposed.yaml", "image_width: 400\nimage_height: 400\n"
                                                          "camera_matrix: {data: [1000, 0, 0, 0, 1000, 0, 199.5, 199.5, 1]}\n");
  expectOneLine(run("detect_object", obj + "--camera " + transposed + " " + kTexture), 2,
                "camera_matrix.data: not [fx, 0, cx, 0, fy, cy, 0, 0, 1]", "transposed K");
  const std::string xml = write("cam.xml", "<root><camera><image_width>400</image_width><image_height>400</image_height>"
                                           "<model><type>perspectiveProjWithoutDistortion</type><px>1000</px><py>1000</py>"
                                           "<u0>199.5</u0><uo>199.5</uo></model></camera></root>");
  expectOneLine(run("detect_object", obj + "--camera " + xml + " " + kTexture), 2,
                "camera.model.uo: unknown element (did you mean u0?)", "xml typo");
  const std::string detcfg = write("det.yaml", "match: {min_inliers: 8, min_inliers: 9}\n");
  expectOneLine(run("detect_object", obj + "--detector-config " + detcfg + " " + kTexture), 2,
                "det.yaml: match.min_inliers: given twice (lines 1 and 1)", "detector config");
  const std::string rig = write("rig.yaml", "left: " + kSource + "/config/cameras/bb2_left.yaml\nright: " + kSource +
                                                "/config/cameras/bb2_right.yaml\nright_in_left: {translation: [0.12, 0, 0], "
                                                "rotation_vector: [0, 0, 0]}\nbaseline: 0.12\n");
  expectOneLine(run("detect_object", obj + "--stereo " + rig + " --right " + kTexture + " " + kTexture), 2,
                "rig.yaml: baseline: unknown field", "rig");
  // stdout on a full disk: every JSON line would be lost.
  expectOneLine(run("detect_object", obj + kTexture, "/dev/full"), 3,
                "detect_object: cannot write to standard output: No space left on device", "/dev/full");
}

TEST(HostileEnonGrasp, BadOptionsFilesAndOutputsAreOneLineWithTheDocumentedCodes) {
  const std::string base = "--backend sim --enon " + kEnon + " --scenario ";
  expectOptionErrors("enon_grasp", base + kScenario + " --oracle",
                     {"--bogus", "--max-time nan", "--max-time 0", "--seed -1"}, 2);
  const auto scenarioCase = [&](const std::string& file, const std::string& needle) {
    expectOneLine(run("enon_grasp", base + file + " --oracle"), 2, needle, file);
  };
  scenarioCase(scenarioWith("blur", "  noise_sigma: 2.0", "  noise_sigma: 2.0\n  motion_blur_px: 1e10"),
               "camera.motion_blur_px: must be at most 256");
  scenarioCase(scenarioWith("rotaton", "grasp_frame: {translation: [0.0, 0.0, 0.035], rotation_vector",
                            "grasp_frame: {translation: [0.0, 0.0, 0.035], rotaton_vector"),
               "objects[0].grasp_frame.rotaton_vector: unknown field (did you mean rotation_vector?)");
  scenarioCase(scenarioWith("pose_rotaton", "pose: {translation: [1.30, 1.1, 0.82], rotation_vector",
                            "pose: {translation: [1.30, 1.1, 0.82], rotaton_vector"),
               "objects[0].pose.rotaton_vector: unknown field (did you mean rotation_vector?)");
  scenarioCase(scenarioWith("twice", "seed: 1\n", "seed: 1\nseed: 2\n"), "seed: given twice");
  scenarioCase(scenarioWith("duration", "max_duration_s: 120", "max_duration_s: 1e12"), "max_duration_s: must be in (0, 3600] s");
  scenarioCase(scenarioWith("texture", kSource + "/media/backgrounds/wall.png", kSource + "/README.md"), "not an image in a supported format");
  const auto enonCase = [&](const std::string& file, const std::string& needle) {
    expectOneLine(run("enon_grasp", "--backend sim --enon " + file + " --scenario " + kScenario + " --oracle"), 2,
                  needle, file);
  };
  enonCase(enonWith("period", "control_period_s: 0.02", "control_period_s: 1e-9"),
           "control_period_s: must be in [0.001, 1] s");
  enonCase(enonWith("watchdog", "watchdog_period_s: 0.2", "watchdog_period_s: 0.2\nwatchdog_periode_s: 0.5"),
           "watchdog_periode_s: unknown field (did you mean watchdog_period_s?)");
  enonCase(enonWith("joint", "name: shoulder_pitch,", "name: shoulder_pitch, thetaoffset_rad: 1,"),
           "arm.joints[0].thetaoffset_rad: unknown field (did you mean theta_offset_rad?)");
  const std::string fifo = fifoPath();
  expectOneLine(run("enon_grasp", base + fifo + " --oracle"), 2, "is a FIFO", "fifo");
  // The log folder below a regular file (exit 2, nothing started); the summary line of a
  // successful grasp on a full disk: 4, the output failed.
  const std::string file = write("plain_file_grasp", "x");
  expectOneLine(run("enon_grasp", base + kScenario + " --oracle --log " + file + "/sub"), 2, file + "/sub",
                "--log below a file");
  expectOneLine(run("enon_grasp", base + kScenario + " --oracle", "/dev/full"), 4,
                "cannot write to standard output", "/dev/full");
}

TEST(HostileSimEnonDemo, BadOptionsFilesAndOutputsAreOneLineWithTheDocumentedCodes) {
  const std::string base = "--enon " + kEnon + " --scenario " + kScenario;
  const std::string out = " --out " + (dir() / "enon_demo").string();
  expectOptionErrors("sim_enon_demo", base + out, {"--duration nan", "--png-every 0"}, 2);
  const std::string file = write("plain_file2", "x");
  expectOneLine(run("sim_enon_demo", base + " --out " + file + "/sub --duration 0.1"), 3, file + "/sub: cannot create folder",
                "--out below a file");
  // A 1e10 px motion blur: refused at load, never an exception from OpenCV at the first render.
  const std::string blur = scenarioWith("enon_blur", "  noise_sigma: 2.0", "  noise_sigma: 2.0\n  motion_blur_px: 1e10");
  expectOneLine(run("sim_enon_demo", "--enon " + kEnon + " --scenario " + blur + out), 2,
                "camera.motion_blur_px: must be at most 256", blur);
  const std::string bad = scenarioWith("enon_seed", "seed: 1", "seed: one");
  expectOneLine(run("sim_enon_demo", "--enon " + kEnon + " --scenario " + bad + out), 2, "seed: expected a number", bad);
  expectOneLine(run("sim_enon_demo", base + out + " --duration 0.1", "/dev/full"), 3, "cannot write to standard output",
                "/dev/full");
  EXPECT_EQ(run("sim_enon_demo", base + out + " --duration 0.1").status, 0);
}

TEST(HostileMakeReference, BadPhotosOptionsAndOutputsAreOneLine) {
  const std::string cam = " --camera " + kObjectCamera + " --corners 0,0,399,0,399,399,0,399 --size 0.2,0.2";
  expectOptionErrors("make_reference", "--image " + kTexture + cam + " --output " + (dir() / "ref/o.yaml").string(),
                     {"--bogus", "--size nan,0.2"}, 2);
  const std::vector<BadImage> bad = badImages();
  for (const BadImage& b : {bad[0], bad[1], bad[5]})  // bomb, truncated, FIFO (all: HostileDetectObject)
    expectOneLine(run("make_reference", "--image " + q(b.path) + cam + " --output " + (dir() / "ref/o.yaml").string()), 2,
                  b.path + ": cannot read image: " + b.problem, b.path);
  const std::string file = write("plain_file3", "x");
  expectOneLine(run("make_reference", "--image " + kTexture + cam + " --output " + file + "/o.yaml"), 3,
                file + "/o.yaml: cannot open for writing", "output below a file");
}

TEST(HostileRecordAndReplay, BadFramesAreSkippedWithOneLineEach) {
  // An image folder of 2 good frames and a bomb, a truncated PNG and a corrupt JPEG.
  const fs::path folder = dir() / "frames";
  fs::create_directories(folder);
  const cv::Mat frame = cv::imread(kTexture, cv::IMREAD_GRAYSCALE);
  cv::imwrite((folder / "a0.png").string(), frame);
  const std::string png = encodeImage(".png", frame), jpg = encodeImage(".jpg", frame);
  std::ofstream(folder / "a1.png", std::ios::binary) << pngDeclaring(20000, 20000);
  std::ofstream(folder / "a2.png", std::ios::binary) << png.substr(0, png.size() / 3);
  std::ofstream(folder / "a3.jpg", std::ios::binary) << corruptJpeg(jpg);
  cv::imwrite((folder / "a4.png").string(), frame);
  fs::remove_all(dir() / "rec");
  const AppRun r = run("record", "--source folder:" + folder.string() + " --camera " + kObjectCamera +
                                     " --output " + (dir() / "rec").string());
  EXPECT_EQ(r.status, 1) << r.err;
  for (const char* e : {"a1.png: PNG declares 20000x20000", "a2.png: truncated PNG", "a3.jpg: corrupt JPEG"})
    EXPECT_NE(r.err.find(e), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("libpng"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("record: 2 frames"), std::string::npos) << r.err;
  expectOptionErrors("record", "--source folder:" + folder.string() + " --output " + (dir() / "rec2").string(),
                     {"--seconds nan", "--png-compression 10"}, 2);
  const AppRun p = run("pose_replay", "--object " + kSource + "/config/objects/cereal_box.yaml --camera " + kObjectCamera +
                                          " --input " + folder.string() + " --output " + (dir() / "replay").string());
  EXPECT_EQ(p.status, 1) << p.err;
  for (const char* e : {"a1.png: PNG declares 20000x20000", "a2.png: truncated PNG", "a3.jpg: corrupt JPEG"})
    EXPECT_NE(p.err.find(e), std::string::npos) << p.err;
  EXPECT_EQ(p.err.find("libpng"), std::string::npos) << p.err;
  expectOptionErrors("pose_replay", "--object x --input y --output z", {"--matcher nonsense"}, 2);
  expectOneLine(run("pose_replay", "--object " + objectFile("typo_replay.yaml", kPose + "nmae: x\n") + " --camera " +
                                       kObjectCamera + " --input " + folder.string() + " --output " +
                                       (dir() / "replay2").string()),
                2, "typo_replay.yaml: nmae: unknown field (did you mean name?)", "object typo");
}

TEST(HostileOtherTools, ParseErrorsExit2AndBadFilesAreOneLine) {
  expectOptionErrors("make_media", "--out " + (dir() / "media").string(), {"--bogus"}, 2);
  const std::string file = write("plain_file4", "x");
  expectOneLine(run("make_media", "--out " + file + "/media"), 3, "cannot create folder", "make_media below a file");
  expectOptionErrors("sim_robot_node", "--scenario " + kScenario,
                     {"--camera-rate nan", "--duration inf"}, 2);
  const std::string obj = objectFile("typo_vc.yaml", kPose + "refrence_image: x\n");
  expectOneLine(run("vision_component", "--object " + obj), 2, "refrence_image: unknown field (did you mean reference_image?)",
                "vision_component object typo");
  expectOptionErrors("vision_component", "--object " + obj, {"--domain nan"}, 2);
  expectOneLine(run("sim_robot_node", "--enon " + kEnon + " --scenario " + fifoPath()), 2, "is a FIFO",
                "sim_robot_node fifo");
}
