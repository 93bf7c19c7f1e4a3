// Hostile input to every tool, as a careless or hostile user would give it: each case
// ends with ONE line on stderr naming the file or option and the problem, and the exit code the
// tool documents; never a crash, a hang, a third-party message or CLI11's own codes (104-114).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <tuple>
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

// Runs `prefix app args` (prefix: "env VAR=value ...", "timeout ...") with stdout to `out` (a
// file, or /dev/full) and stderr captured; a tool still running after 120 s is stopped (124).
AppRun runWith(const std::string& prefix, const std::string& app, const std::string& args,
               const std::string& out = "") {
  const fs::path o = dir() / (app + "_stdout.txt"), e = dir() / (app + "_stderr.txt");
  const std::string cmd = prefix + " timeout -k 5 120 " + std::string(REFGRASP_APP_DIR) + "/" + app + " " + args +
                          " > " + (out.empty() ? o.string() : out) + " 2> " + e.string() + " < /dev/null";
  const int st = std::system(cmd.c_str());
  return {WIFEXITED(st) ? WEXITSTATUS(st) : -1, out.empty() ? readFile(o) : "", readFile(e)};
}

AppRun run(const std::string& app, const std::string& args, const std::string& out = "") {
  return runWith("", app, args, out);
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

// A several-view object (a box's faces) is an object with a pose like the others: enon_grasp
// grasps it (one view, table_single's cereal box, with the oracle); pose_replay detects it in
// every frame.
TEST(HostileSeveralViews, EnonGraspGraspsItAndPoseReplayDetectsIt) {
  // Named as the scenario's object: the simulator's ground truth (the oracle's) is by that name.
  const std::string box = write("box_views.yaml", "name: cereal_box\nviews:\n  - definition: " + kSource +
                                                      "/config/objects/cereal_box.yaml\n"
                                                      "    oMv: {translation: [0, 0, 0], rotation_vector: [0, 0, 0]}\n");
  const AppRun g = run("enon_grasp", "--backend sim --enon " + kEnon + " --scenario " +
                                         scenarioWith("views", "definition: " + kSource + "/config/objects/cereal_box.yaml",
                                                      "definition: " + box) +
                                         " --oracle");
  EXPECT_EQ(g.status, 0) << g.err;
  EXPECT_NE(g.out.find("\"success\":true"), std::string::npos) << g.out;
  const fs::path frames = dir() / "views_frames";
  fs::create_directories(frames);
  fs::copy_file(kTexture, frames / "000000.png", fs::copy_options::overwrite_existing);
  const AppRun r = run("pose_replay", "--object " + box + " --camera " + kObjectCamera + " --input " + frames.string() +
                                          " --output " + (dir() / "views_out").string() + " --no-track --frames");
  EXPECT_EQ(r.status, 0) << r.err;
  std::ifstream poses(dir() / "views_out" / "poses.jsonl");
  std::string line;
  ASSERT_TRUE(std::getline(poses, line));
  EXPECT_NE(line.find("\"views\":[\"cereal_box\"],\"view\":\"cereal_box\""), std::string::npos) << line;
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

// ---- The shared policy of app/tool/tool.h, class by class, on every tool it concerns. ----

namespace {

const std::string kCameraArgs = " --camera " + kObjectCamera + " --corners 0,0,399,0,399,399,0,399 --size 0.2,0.2";
const std::string kGraspBase = "--backend sim --enon " + kEnon + " --oracle --scenario ";

std::string copyOf(const std::string& from, const fs::path& to) {
  fs::create_directories(to.parent_path());
  fs::copy_file(from, to, fs::copy_options::overwrite_existing);
  return to.string();
}

// The loopback configuration, a private domain and namespace: DDS tests run in parallel.
std::string loopbackUri() { return "file://" + kSource + "/config/dds/cyclonedds_loopback.xml"; }
// A domain below the ephemeral port range, as dds_test_util.h's privateDomain().
std::string privateDomainArg() { return " --domain " + std::to_string(1 + ::getpid() % 100); }
std::string privateNs() { return "/hostile_" + std::to_string(::getpid()); }

// The DDS tools with the arguments that start them (enon_grasp on the dds backend).
struct DdsTool {
  std::string app, args;
};
std::vector<DdsTool> ddsTools() {
  return {{"vision_component", "--object " + kSource + "/config/objects/cereal_box.yaml --ns " + privateNs()},
          {"sim_robot_node", "--enon " + kEnon + " --scenario " + kScenario + " --ns " + privateNs()},
          {"enon_grasp", "--backend dds --enon " + kEnon + " --scenario " + kScenario + " --ns " + privateNs()}};
}

}  // namespace

TEST(HostileDataLoss, NoToolWritesOverOneOfItsInputsWhateverTheName) {
  const fs::path ph = dir() / "loss";
  fs::remove_all(ph);
  const std::string photo = copyOf(kTexture, ph / "box.png"), original = readFile(photo);
  // The default check picture (OUTPUT with .png) would be the photo.
  expectOneLine(run("make_reference", "--image " + photo + kCameraArgs + " --output " + (ph / "box.yaml").string()), 2,
                "--check " + photo + ": is the input --image " + photo, "default --check");
  EXPECT_FALSE(fs::exists(ph / "box.yaml"));
  // The same file by a symlink, a hard link, a path with "." and "..", or as the camera file.
  fs::create_symlink("box.png", ph / "link.png");
  fs::create_hard_link(photo, ph / "hard.png");
  const std::string camera = copyOf(kObjectCamera, ph / "cam.yaml");
  for (const auto& [args, needle] : std::vector<std::pair<std::string, std::string>>{
           {"--image " + (ph / "link.png").string() + kCameraArgs + " --output " + (ph / "o.yaml").string() +
                " --check " + photo, "--check " + photo + ": is the input --image"},
           {"--image " + (ph / "hard.png").string() + kCameraArgs + " --output " + (ph / "o.yaml").string() +
                " --check " + (ph / "." / "box.png").string(), ": is the input --image " + (ph / "hard.png").string()},
           {"--image " + photo + " --camera " + camera + " --corners 0,0,399,0,399,399,0,399 --size 0.2,0.2 --output " +
                (ph / "sub" / ".." / "cam.yaml").string(), ": is the input --camera " + camera},
           {"--image " + photo + kCameraArgs + " --output " + (ph / "o.yaml").string() + " --check " +
                (ph / "o.yaml").string(), "--check " + (ph / "o.yaml").string() + ": is also --output"}})
    expectOneLine(run("make_reference", args), 2, needle, args);
  EXPECT_EQ(readFile(photo), original);
  EXPECT_FALSE(fs::exists(ph / "o.yaml"));

  // Output folders that are or hold an input: pose_replay, record, sim_enon_demo, enon_grasp --log.
  const fs::path frames = ph / "frames";
  fs::create_directories(frames);
  cv::imwrite((frames / "a0.png").string(), cv::imread(kTexture, cv::IMREAD_GRAYSCALE));
  cv::imwrite((frames / "a1.png").string(), cv::imread(kTexture, cv::IMREAD_GRAYSCALE));
  expectOneLine(run("pose_replay", "--object " + kSource + "/config/objects/cereal_box.yaml --camera " + kObjectCamera +
                                       " --input " + frames.string() + " --output " + frames.string()),
                2, "--output " + frames.string() + ": is the input --input", "pose_replay into its input");
  EXPECT_FALSE(fs::exists(frames / "poses.jsonl"));
  expectOneLine(run("record", "--source folder:" + frames.string() + " --camera " + kObjectCamera + " --output " +
                                  frames.string()),
                2, "--output " + frames.string() + ": is the input --source", "record into its source");
  const std::string scenario = copyOf(kScenario, ph / "demo" / "state.csv");
  const std::string scenario_text = readFile(scenario);
  expectOneLine(run("sim_enon_demo", "--enon " + kEnon + " --scenario " + scenario + " --out " + (ph / "demo").string() +
                                         " --duration 0.1"),
                2, "--out " + (ph / "demo").string() + ": holds the input --scenario " + scenario, "sim_enon_demo");
  expectOneLine(run("enon_grasp", kGraspBase + scenario + " --log " + (ph / "demo").string()), 2,
                "--log " + (ph / "demo").string() + ": holds the input --scenario", "enon_grasp --log");
  expectOneLine(run("enon_grasp", kGraspBase + scenario + " --video " + scenario), 2,
                "--video " + scenario + ": is the input --scenario", "enon_grasp --video");
  expectOneLine(run("sim_robot_node", "--enon " + kEnon + " --scenario " + scenario + " --result " + scenario), 2,
                "--result " + scenario + ": is the input --scenario", "sim_robot_node --result");
  EXPECT_EQ(readFile(scenario), scenario_text);
  // enon_grasp: an object definition that the scenario names.
  const std::string target = objectFile("loss/target.yaml", kPose), target_text = readFile(target);
  const std::string named = scenarioWith("loss_named", "definition: " + kSource + "/config/objects/cereal_box.yaml",
                                         "definition: " + target);
  expectOneLine(run("enon_grasp", kGraspBase + named + " --video " + (ph / "." / "target.yaml").string()), 2,
                ": is the input the scenario's object " + target, "enon_grasp --video over the target's definition");
  EXPECT_EQ(readFile(target), target_text);
}

TEST(HostileNumbers, IntegerOptionsAreRangeCheckedNeverWrapped) {
  const std::string huge = "99999999999999999999999";  // > 2^64
  expectOneLine(run("enon_grasp", kGraspBase + kScenario + " --seed " + huge), 2,
                "--seed: " + huge + " is outside [0, 18446744073709551615]", "--seed");
  expectOneLine(run("enon_grasp", kGraspBase + kScenario + " --seed 18446744073709551616"), 2, "--seed", "--seed 2^64");
  expectOneLine(run("enon_grasp", kGraspBase + kScenario + " --seed 0x10"), 2, "--seed: '0x10' is not a whole number",
                "--seed hex");
  expectOneLine(run("enon_grasp", "--backend dds --enon " + kEnon + " --scenario " + kScenario + " --domain 233"), 2,
                "--domain: 233 is outside [0, 232]", "enon_grasp --domain");
  const std::string obj = "--object " + kSource + "/config/objects/cereal_box.yaml ";
  for (const std::string& o : std::vector<std::string>{"--max-features " + huge, "--max-instances 1.5", "--min-inliers 4294967300"})
    expectOneLine(run("detect_object", obj + o + " " + kTexture), 2, o.substr(0, o.find(' ')) + ": ", o);
  expectOneLine(run("make_reference", "--image " + kTexture + kCameraArgs + " --output " + (dir() / "num/o.yaml").string() +
                                          " --tag-id " + huge),
                2, "--tag-id: " + huge + " is outside", "--tag-id");
  // int64 --frames: CLI11 saturates it to 2^63-1 without an error.
  expectOneLine(run("record", "--source folder:" + kSource + "/media/targets --camera " + kObjectCamera + " --output " +
                                  (dir() / "num_rec").string() + " --frames " + huge),
                2, "--frames: " + huge + " is outside", "--frames");
  expectOneLine(run("sim_enon_demo", "--enon " + kEnon + " --scenario " + kScenario + " --out " +
                                         (dir() / "num_demo").string() + " --png-every " + huge),
                2, "--png-every: " + huge + " is outside", "--png-every");
  // An int option: CLI11 refuses what does not fit, dds::domainOrNamespaceProblem the range.
  for (const DdsTool& t : ddsTools())
    if (t.app != "enon_grasp")
      for (const char* d : {"4294967296", "233", "1.5"})
        expectOneLine(run(t.app, t.args + " --domain " + d), 2, "--domain", t.app + " --domain " + d);
}

TEST(HostileEnvironment, DomainIdAndCycloneUriAreCheckedByEveryDdsToolBeforeCyclone) {
  const fs::path d = dir() / "env";
  fs::create_directories(d / "folder.xml");
  const std::string fifo = (d / "config.fifo").string();
  if (!fs::exists(fifo)) ::mkfifo(fifo.c_str(), 0600);
  const std::string big = write("env/big.xml", std::string((5u << 20), ' '));
  const std::string missing = (d / "missing.xml").string();
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"ROS_DOMAIN_ID=abc", "ROS_DOMAIN_ID: 'abc' is not a domain id (an integer in [0, 232])"},
      {"ROS_DOMAIN_ID=233", "ROS_DOMAIN_ID: '233' is not a domain id"},
      {"ROS_DOMAIN_ID=-1", "ROS_DOMAIN_ID: '-1' is not a domain id"},
      {"CYCLONEDDS_URI=" + fifo, "CYCLONEDDS_URI: " + fifo + ": is a FIFO, not a regular file"},
      {"CYCLONEDDS_URI=file://" + fifo, "CYCLONEDDS_URI: " + fifo + ": is a FIFO"},
      {"CYCLONEDDS_URI=" + (d / "folder.xml").string(), "CYCLONEDDS_URI: " + (d / "folder.xml").string() + ": is a directory"},
      {"CYCLONEDDS_URI=file://" + missing, "CYCLONEDDS_URI: " + missing + ": file not found"},
      {"CYCLONEDDS_URI=file://" + big, "CYCLONEDDS_URI: " + big + ": is 5242880 bytes, more than the limit"},
      // A list: inline XML first (accepted as Cyclone reads it), then a missing file.
      {"CYCLONEDDS_URI='<CycloneDDS><Domain/></CycloneDDS>,file://" + missing + "'", "CYCLONEDDS_URI: " + missing},
  };
  for (const DdsTool& t : ddsTools())
    for (const auto& [env, needle] : bad)
      expectOneLine(runWith("env ROS_DOMAIN_ID=7 CYCLONEDDS_URI=" + loopbackUri() + " " + env, t.app, t.args), 2,
                    t.app + ": " + needle, t.app + " " + env);
  // enon_grasp checks the DDS environment only for a DDS backend.
  EXPECT_NE(runWith("env ROS_DOMAIN_ID=abc", "enon_grasp", kGraspBase + kScenario + " --max-time 0.1").status, 2);
}

TEST(HostileEnvironment, MaxImagePixelsIsCheckedByEveryToolThatReadsImages) {
  const std::string obj = kSource + "/config/objects/cereal_box.yaml";
  const std::vector<DdsTool> tools = {
      {"detect_object", "--object " + obj + " " + kTexture},
      {"make_reference", "--image " + kTexture + kCameraArgs + " --output " + (dir() / "px/o.yaml").string()},
      {"pose_replay", "--object " + obj + " --camera " + kObjectCamera + " --input " + kSource + "/media/targets --output " +
                          (dir() / "px_replay").string()},
      {"record", "--source folder:" + kSource + "/media/targets --camera " + kObjectCamera + " --output " +
                     (dir() / "px_rec").string()},
      {"sim_enon_demo", "--enon " + kEnon + " --scenario " + kScenario + " --out " + (dir() / "px_demo").string() +
                            " --duration 0.1"},
      {"enon_grasp", kGraspBase + kScenario + " --max-time 0.1"},
      {"sim_robot_node", "--enon " + kEnon + " --scenario " + kScenario + " --duration 0.1" + privateDomainArg()},
      {"vision_component", "--object " + obj + privateDomainArg()},
  };
  // Every malformed form on one tool, two on each of the others.
  for (const DdsTool& t : tools)
    for (const char* v : {"abc", "0", "-5", "12x", "99999999999999999999999"})
      if (t.app == "detect_object" || v[0] == 'a' || v[0] == '9')
        expectOneLine(runWith("env CYCLONEDDS_URI=" + loopbackUri() + " REFGRASP_MAX_IMAGE_PIXELS=" + std::string(v), t.app, t.args), 2,
                      t.app + ": REFGRASP_MAX_IMAGE_PIXELS: '" + std::string(v) + "' is not a pixel count", t.app + " " + v);
}

TEST(HostileStartup, ADdsRobotThatNeverAnswersIsOneLineAndASignalEndsTheWaitAtOnce) {
  const std::string env = "env CYCLONEDDS_URI=" + loopbackUri();
  const std::string args = "--backend dds --enon " + kEnon + " --scenario " + kScenario + " --ns " + privateNs() +
                           privateDomainArg();
  // No robot driver: the backend's own line, alone (not followed by "could not start the robot").
  const AppRun r = runWith(env, "enon_grasp", args);
  expectOneLine(r, 3, "enon_grasp: dds robot: no " + privateNs() + "/joint_states on domain", "no robot");
  // SIGTERM and SIGINT during the wait for the robot's first state (5 s; the signal comes after
  // 2.5 s, when a loaded machine has surely loaded the tool): one line, 128 + signal, at once.
  for (const auto& [sig, code, name] : {std::tuple<const char*, int, const char*>{"TERM", 143, "SIGTERM"},
                                        {"INT", 130, "SIGINT"}}) {
    const auto t0 = std::chrono::steady_clock::now();
    const AppRun s = runWith(env + " timeout --preserve-status -k 10 -s " + std::string(sig) + " 2.5", "enon_grasp", args);
    const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    expectOneLine(s, code, std::string("enon_grasp: interrupted by ") + name + " during start-up", name);
    EXPECT_LT(took, 4.5) << name;
  }
}

TEST(HostileStartup, ASignalMidRunStopsTheRobotAndIsOneLine) {
  // A vision run in a room world takes over 15 s of CPU (table_single's whole run can end within
  // 2.5 s on an idle machine): SIGINT after 2.5 s finds it running (or, on a loaded machine,
  // still starting): one line, 130, the robot stopped by the controller.
  const auto t0 = std::chrono::steady_clock::now();
  const AppRun r = runWith("timeout --preserve-status -k 10 -s INT 2.5", "enon_grasp",
                           "--backend sim --enon " + kEnon + " --scenario " + kSource +
                               "/config/scenarios/room_cookie_behind.yaml");
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  expectOneLine(r, 130, "enon_grasp: interrupted by SIGINT", "SIGINT mid-run");
  EXPECT_LT(took, 4.5);
}

TEST(HostileLibraryMessages, CycloneLibpngAndFfmpegNeverPrintTheirOwnLines) {
  // Cyclone DDS: an unknown element in the configuration; our line names it, alone.
  const std::string xml = "'<CycloneDDS><Domain><General><NoSuchSetting/></General></Domain></CycloneDDS>'";
  for (const DdsTool& t : ddsTools())
    expectOneLine(runWith("env CYCLONEDDS_URI=" + xml, t.app, t.args + privateDomainArg()), 3,
                  "(Cyclone DDS: config: //CycloneDDS/Domain/General: NoSuchSetting: unknown element", t.app);
  // libpng on a full disk: a PNG output that is /dev/full.
  const fs::path d = dir() / "full";
  fs::remove_all(d);
  fs::create_directories(d / "media" / "targets");
  fs::create_directories(d / "demo");
  fs::create_symlink("/dev/full", d / "full.png");
  fs::create_symlink("/dev/full", d / "media" / "targets" / "poster_concert.png");
  fs::create_symlink("/dev/full", d / "demo" / "frame_00000_left.png");
  const std::string nospace = "cannot write the image: No space left on device";
  expectOneLine(run("make_reference", "--image " + kTexture + kCameraArgs + " --output " + (d / "o.yaml").string() +
                                          " --check " + (d / "full.png").string()),
                3, (d / "full.png").string() + ": " + nospace, "make_reference");
  expectOneLine(run("make_media", "--out " + (d / "media").string()), 3, "poster_concert.png: " + nospace, "make_media");
  expectOneLine(run("sim_enon_demo", "--enon " + kEnon + " --scenario " + kScenario + " --out " + (d / "demo").string() +
                                         " --duration 0.1"),
                3, "frame_00000_left.png: " + nospace, "sim_enon_demo");
  // FFmpeg: a video in a folder that does not exist is that, not a missing encoder.
  expectOneLine(run("enon_grasp", kGraspBase + kScenario + " --video " + (d / "nowhere" / "v.mp4").string()), 2,
                "--video " + (d / "nowhere" / "v.mp4").string() + ": folder " + (d / "nowhere").string() +
                    " does not exist",
                "enon_grasp --video");
}
