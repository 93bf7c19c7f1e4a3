// The detect_object app: JSON lines, exit codes, one-line errors naming the file.
#include <gtest/gtest.h>

#include "common/temp_dir.h"
#include <sys/wait.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "robot/sim/synthetic_scene.h"
#include "core/camera.h"
#include "multiview_box.h"

using namespace refgrasp;
using namespace refgrasp::testing;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

const std::string kObject = std::string(REFGRASP_SOURCE_DIR) + "/config/objects/poster_concert.yaml";
const std::string kObject2 = std::string(REFGRASP_SOURCE_DIR) + "/config/objects/cereal_box.yaml";

fs::path dir() {
  return refgrasp::testing::tempDir("refgrasp_test_cli");
}

std::string readFile(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

struct CliRun {
  int status = -1;
  std::string out, err;
  std::vector<json> lines;
};

CliRun run(const std::string& args) {
  const fs::path out = dir() / "stdout.txt", err = dir() / "stderr.txt";
  const std::string cmd = std::string(REFGRASP_APP_DIR) + "/detect_object " + args + " > " +
                          out.string() + " 2> " + err.string();
  const int st = std::system(cmd.c_str());
  CliRun r;
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  r.out = readFile(out);
  r.err = readFile(err);
  std::istringstream lines(r.out);
  for (std::string l; std::getline(lines, l);)
    if (!l.empty() && l[0] == '{') r.lines.push_back(json::parse(l));
  return r;
}

class DetectObjectCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const cv::Mat tex = loadMedia("targets/poster_concert.png");
    const double h = 0.2 * tex.rows / tex.cols;
    SceneSpec spec;
    spec.cMo = Pose::fromRotationVector({0.3, -0.2, 0.1}, {0.03, -0.02, 0.6});
    spec.seed = 21;
    scene_ = renderTarget(sceneCamera(), tex, 0.2, h, spec);
    cv::imwrite((dir() / "scene.png").string(), scene_.image);
    cv::imwrite((dir() / "clutter.png").string(), clutterBackground(4242));
    cv::imwrite((dir() / "small.png").string(), cv::Mat(240, 320, CV_8UC1, cv::Scalar(128)));
    std::ofstream(dir() / "corrupt.png") << "not an image at all";
    std::ofstream(dir() / "bad.yaml") << "reference_image: [unclosed\n";
    saveCameraFile((dir() / "scene_cam.yaml").string(), sceneCamera(), "scene");
    // Stereo: right eye 12 cm to the right.
    const Pose lMr(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.12, 0, 0));
    SceneSpec right = spec;
    right.cMo = lMr.inverse() * spec.cMo;
    right.seed = 22;
    cv::imwrite((dir() / "right.png").string(), renderTarget(sceneCamera(), tex, 0.2, h, right).image);
    std::ofstream(dir() / "rig.yaml") << "left: scene_cam.yaml\nright: scene_cam.yaml\n"
                                         "right_in_left: {translation: [0.12, 0, 0], rotation_vector: [0, 0, 0]}\n";
  }
  static std::string path(const std::string& name) { return (dir() / name).string(); }
  static RenderedScene scene_;
};
RenderedScene DetectObjectCli::scene_;

}  // namespace

TEST_F(DetectObjectCli, HelpExplainsOptionsAndOutput) {
  const CliRun r = run("--help");
  EXPECT_EQ(r.status, 0);
  for (const char* s : {"--object", "--camera", "--matcher", "--pose", "--right", "--stereo",
                        "homography", "corners", "time_ms", "Exit status"})
    EXPECT_NE(r.out.find(s), std::string::npos) << s;
}

TEST_F(DetectObjectCli, FindsTheObjectAndPrintsOneJsonLine) {
  const std::string cam = "--camera " + path("scene_cam.yaml");
  for (const std::string& opts : {cam, cam + " --matcher ratio --pose paper", cam + " --pose refined"}) {
    const CliRun r = run("--object " + kObject + " " + opts + " " + path("scene.png"));
    ASSERT_EQ(r.status, 0) << r.err;
    ASSERT_EQ(r.lines.size(), 1u) << r.out;
    const json& j = r.lines[0];
    EXPECT_EQ(j["image"], path("scene.png"));
    ASSERT_TRUE(j["found"].get<bool>()) << opts;
    EXPECT_EQ(j["homography"].size(), 9u);
    EXPECT_EQ(j["R"].size(), 9u);
    EXPECT_GE(j["inliers"].get<int>(), 12);
    for (const char* k : {"extract", "match", "pose", "total"}) EXPECT_GT(j["time_ms"][k].get<double>(), 0);
    const Eigen::Vector3d t(j["t"][0], j["t"][1], j["t"][2]);
    EXPECT_LT((t - scene_.cMo.t).norm(), 0.01 * scene_.cMo.t.norm()) << opts;
    for (int i = 0; i < 4; ++i) {
      const Eigen::Vector2d c(j["corners"][i][0], j["corners"][i][1]);
      EXPECT_LT((c - scene_.corners[i]).norm(), 3.0) << opts;
    }
    EXPECT_FALSE(j.contains("object"));
  }
}

TEST_F(DetectObjectCli, NotFoundAndSeveralObjects) {
  const CliRun r = run("--object " + kObject + " --object " + kObject2 + " --camera " +
                    path("scene_cam.yaml") + " " + path("clutter.png") +
                    " " + path("scene.png"));
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_EQ(r.lines.size(), 4u) << r.out;  // 2 images x 2 objects
  for (const json& j : r.lines) {
    ASSERT_TRUE(j.contains("object") && j.contains("instance"));
    const bool expect = j["image"] == path("scene.png") && j["object"] == "poster_concert";
    EXPECT_EQ(j["found"].get<bool>(), expect) << j.dump();
    if (!expect) {
      EXPECT_FALSE(j.contains("R") || j.contains("homography") || j.contains("corners"));
    }
  }
}

TEST_F(DetectObjectCli, StereoFusesBothEyes) {
  const CliRun r = run("--object " + kObject + " --stereo " + path("rig.yaml") + " --right " +
                    path("right.png") + " " + path("scene.png"));
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_EQ(r.lines.size(), 1u);
  EXPECT_EQ(r.lines[0]["eyes"], "both");
  const Eigen::Vector3d t(r.lines[0]["t"][0], r.lines[0]["t"][1], r.lines[0]["t"][2]);
  EXPECT_LT((t - scene_.cMo.t).norm(), 0.01 * scene_.cMo.t.norm());
}

TEST_F(DetectObjectCli, BadInputGivesOneLineErrorsAndExitCodes) {
  // Unreadable images: error naming the file, the readable image still processed, exit 1.
  const std::string cam = " --camera " + path("scene_cam.yaml") + " ";
  CliRun r = run("--object " + kObject + cam + path("missing.png") + " " + path("corrupt.png") + " " +
              path("scene.png"));
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(r.lines.size(), 1u);
  EXPECT_NE(r.err.find(path("missing.png") + ": cannot read image"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(path("corrupt.png") + ": cannot read image"), std::string::npos) << r.err;
  // Image size different from the camera's: --camera, and the default (the object's reference
  // camera, whose size is the reference image's).
  r = run("--object " + kObject + cam + path("small.png"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find(path("small.png") + ": image size 320x240 differs from the camera's 640x480"),
            std::string::npos) << r.err;
  r = run("--object " + kObject + " " + path("scene.png"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find(path("scene.png") + ": image size 640x480 differs"), std::string::npos) << r.err;
  // Bad object file, missing object file, bad camera: exit 2, one line naming the file.
  for (const std::string& bad : {path("bad.yaml"), path("nothere.yaml")}) {
    r = run("--object " + bad + " " + path("scene.png"));
    EXPECT_EQ(r.status, 2);
    EXPECT_NE(r.err.find(bad), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  r = run("--object " + kObject + " --camera " + path("bad.yaml") + " " + path("scene.png"));
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find(path("bad.yaml")), std::string::npos) << r.err;
  // Bad option values and inconsistent stereo options.
  EXPECT_NE(run("--object " + kObject + " --matcher fast " + path("scene.png")).status, 0);
  EXPECT_EQ(run("--object " + kObject + " --right " + path("right.png") + " " + path("scene.png")).status, 2);
  EXPECT_NE(run(path("scene.png")).status, 0);  // --object is required
}

// docs/tools/detect_object.md: `detect_object --object OBJ.yaml [...] IMAGE...`: the repeatable
// --object takes one file, so the images after it are images; options and images in any order,
// --opt=value too.
TEST_F(DetectObjectCli, ImagesAndOptionsInAnyOrder) {
  const std::string cam = path("scene_cam.yaml"), scene = path("scene.png"), clutter = path("clutter.png");
  const std::vector<std::string> orders = {
      "--camera " + cam + " --object " + kObject + " " + scene + " " + clutter,
      scene + " --camera " + cam + " --object " + kObject + " " + clutter,
      scene + " " + clutter + " --object " + kObject + " --camera " + cam,
      "--object=" + kObject + " --camera=" + cam + " " + scene + " " + clutter,
  };
  for (const std::string& args : orders) {
    const CliRun r = run(args);
    ASSERT_EQ(r.status, 0) << args << "\n" << r.err;
    ASSERT_EQ(r.lines.size(), 2u) << args << "\n" << r.out;
    EXPECT_EQ(r.lines[0]["image"], scene) << args;
    EXPECT_TRUE(r.lines[0]["found"].get<bool>()) << args;
    EXPECT_EQ(r.lines[1]["image"], clutter) << args;
    EXPECT_FALSE(r.lines[1]["found"].get<bool>()) << args;
  }
  // Several objects between the images, three images (one twice).
  const CliRun r = run("--object " + kObject + " " + clutter + " --object=" + kObject2 + " " + scene +
                       " --camera " + cam + " " + scene);
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_EQ(r.lines.size(), 6u) << r.out;  // 3 images x 2 objects
  const std::vector<std::string> expect_images = {clutter, clutter, scene, scene, scene, scene};
  for (size_t i = 0; i < r.lines.size(); ++i) {
    EXPECT_EQ(r.lines[i]["image"], expect_images[i]) << i;
    EXPECT_EQ(r.lines[i]["object"], i % 2 ? "cereal_box" : "poster_concert") << i;
    EXPECT_EQ(r.lines[i]["found"].get<bool>(), i >= 2 && i % 2 == 0) << i;
  }
  // Stereo: the right image after --right, the left one anywhere.
  const CliRun s = run(scene + " --right " + path("right.png") + " --object " + kObject + " --stereo " +
                       path("rig.yaml"));
  ASSERT_EQ(s.status, 0) << s.err;
  ASSERT_EQ(s.lines.size(), 1u) << s.out;
  EXPECT_EQ(s.lines[0]["eyes"], "both");
}

TEST_F(DetectObjectCli, DetectorConfigFileAndCommandLineOverrides) {
  const std::string args = " --object " + kObject + " --camera " + path("scene_cam.yaml") + " " + path("scene.png");
  std::ofstream(dir() / "two.yaml") << "match:\n  max_instances: 2  # lines then carry object and instance\n";
  CliRun r = run("--detector-config " + path("two.yaml") + args);
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_EQ(r.lines.size(), 1u) << r.out;
  EXPECT_TRUE(r.lines[0]["found"].get<bool>());
  EXPECT_EQ(r.lines[0]["object"], "poster_concert");  // tagged: the file's max_instances is 2
  // The command line overrides the file.
  r = run("--detector-config " + path("two.yaml") + " --max-instances 1" + args);
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_EQ(r.lines.size(), 1u);
  EXPECT_FALSE(r.lines[0].contains("object"));
  // The shipped file is the defaults: the same line as without it (timings aside).
  r = run("--detector-config " + std::string(REFGRASP_SOURCE_DIR) + "/config/detector.yaml" + args);
  CliRun plain = run(args);
  ASSERT_EQ(r.lines.size(), 1u);
  ASSERT_EQ(plain.lines.size(), 1u);
  r.lines[0].erase("time_ms");
  plain.lines[0].erase("time_ms");
  EXPECT_EQ(r.lines[0], plain.lines[0]);
  // A bad file: exit 2, one line naming the file and the field.
  std::ofstream(dir() / "typo.yaml") << "match: {min_inlirs: 5}\n";
  r = run("--detector-config " + path("typo.yaml") + args);
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "detect_object: " + path("typo.yaml") + ": match.min_inlirs: unknown field (did you mean min_inliers?)\n");
  EXPECT_TRUE(r.lines.empty());
}

namespace {

// The field names of a JSON line, in order.
std::vector<std::string> keys(const std::string& line) {
  std::vector<std::string> out;
  const nlohmann::ordered_json j = nlohmann::ordered_json::parse(line);
  for (const auto& [k, v] : j.items()) out.push_back(k);
  return out;
}

TEST_F(DetectObjectCli, ASeveralViewObjectsLineNamesItsViewsAsDocumented) {
  const TestBox box;
  const fs::path d = dir() / "box";
  fs::create_directories(d);
  const std::string def = box.writeDefinitions(d, "parcel");
  // Turned 40 deg and seen from above: its front, right side and top may show.
  const Pose cMo = lookAtBox(40 * M_PI / 180, 25 * M_PI / 180, 0.8);
  cv::imwrite((d / "box.png").string(), renderScene(sceneCamera(), box.placed(cMo), 31));
  const CliRun r = run(path("clutter.png") + " --object " + def + " " + (d / "box.png").string() + " --camera " +
                       path("scene_cam.yaml") + " --max-features 0");
  ASSERT_EQ(r.status, 0) << r.err;
  std::vector<std::string> lines;
  std::istringstream in(r.out);
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  ASSERT_EQ(lines.size(), 2u) << r.out;
  EXPECT_EQ(keys(lines[0]), (std::vector<std::string>{"image", "found", "time_ms"}));
  EXPECT_EQ(keys(lines[1]), (std::vector<std::string>{"image", "found", "homography", "corners", "R", "t", "inliers",
                                                      "views", "view", "time_ms"}));
  const json& j = r.lines[1];
  EXPECT_FALSE(r.lines[0]["found"].get<bool>());
  ASSERT_TRUE(j["found"].get<bool>());
  ASSERT_GE(j["views"].size(), 1u);
  EXPECT_EQ(j["view"], j["views"][0]);
  for (const auto& v : j["views"]) EXPECT_TRUE(v == "front" || v == "right" || v == "top") << v;
  // R, t: the box's frame in the camera frame (row-major R).
  const Eigen::Vector3d t(j["t"][0], j["t"][1], j["t"][2]);
  Eigen::Matrix3d R;
  for (int i = 0; i < 9; ++i) R(i / 3, i % 3) = j["R"][i];
  EXPECT_LT((t - cMo.t).norm(), 0.02 * cMo.t.norm());
  EXPECT_LT(rotationError(Pose(R, t), cMo), 3 * M_PI / 180);
  // homography and corners: those of the named view (its reference px -> image px).
  const auto face = std::find_if(box.defined.begin(), box.defined.end(), [&](const auto& f) { return f.second == j["view"]; });
  ASSERT_NE(face, box.defined.end());
  const auto truth = sim::projectPlaneCorners(sceneCamera(), box.placed(cMo)[static_cast<size_t>(face->first)]);
  for (int i = 0; i < 4; ++i)
    EXPECT_LT((Eigen::Vector2d(j["corners"][i][0], j["corners"][i][1]) - truth[static_cast<size_t>(i)]).norm(), 3.0) << i;
}

}  // namespace
