// tool::run, tool::parse, tool::StopOnError and tool::Finite (app/tool/tool.h), in process: every
// exception becomes one line and the tool's code, CLI11's parse errors the bad-input code (not
// CLI11's 104-114), a failed write to stdout the output code, and the robot stops first.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <vector>

#include "common/app_run.h"
#include "common/temp_dir.h"
#include "core/error.h"
#include "tool/tool.h"

using namespace refgrasp;

namespace {

struct Result {
  int code;
  std::string err;
};

// Runs tool::run("t", ...) on `body` with argv = {"t", args...}; stderr captured.
Result runTool(const std::function<int(int, char**)>& body, std::vector<std::string> args = {},
               const tool::RunOptions& o = {}) {
  args.insert(args.begin(), "t");
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  ::testing::internal::CaptureStderr();
  const int code = tool::run("t", static_cast<int>(argv.size()), argv.data(), body, o);
  return {code, ::testing::internal::GetCapturedStderr()};
}

template <class E>
std::function<int(int, char**)> throwing(E e) {
  return [e](int, char**) -> int { throw e; };
}

}  // namespace

TEST(ToolRun, EveryExceptionIsOneLineAndItsCode) {
  EXPECT_EQ(runTool([](int, char**) { return 1; }).code, 1);
  const Result c = runTool(throwing(ConfigError("cam.yaml", "fx", "must be positive")));
  EXPECT_EQ(c.code, 2);
  EXPECT_EQ(c.err, "t: cam.yaml: fx: must be positive\n");
  const Result o = runTool(throwing(OutputError("out/x.png", "cannot write the image")));
  EXPECT_EQ(o.code, 3);
  EXPECT_EQ(o.err, "t: out/x.png: cannot write the image\n");
  EXPECT_EQ(runTool(throwing(std::invalid_argument("SearchOptions.pan_step_rad: bad"))).code, 2);
  const Result m = runTool(throwing(std::bad_alloc()));
  EXPECT_EQ(m.err, "t: out of memory\n");
  // cv::Exception's what() spans lines and names OpenCV's source file: one line of ours instead.
  const Result cv = runTool([](int, char**) -> int {
    cv::Mat a(2, 2, CV_8UC1), b(3, 3, CV_8UC1);
    cv::Mat s = a + b;  // size mismatch
    return s.rows;
  });
  EXPECT_EQ(cv.code, 2);
  EXPECT_EQ(cv.err.rfind("t: OpenCV: ", 0), 0u) << cv.err;
  EXPECT_EQ(std::count(cv.err.begin(), cv.err.end(), '\n'), 1) << cv.err;
  const Result fs = runTool(throwing(std::filesystem::filesystem_error(
      "create_directories", "out/a", std::make_error_code(std::errc::not_a_directory))));
  EXPECT_EQ(fs.err, "t: out/a: Not a directory\n");
  EXPECT_EQ(runTool([](int, char**) -> int { throw 42; }).err, "t: unknown exception\n");
  EXPECT_EQ(runTool(throwing(tool::Exit{7})).code, 7);
  // A tool's own codes.
  tool::RunOptions codes;
  codes.bad_input = codes.failure = 4;
  codes.output_failed = 5;
  EXPECT_EQ(runTool(throwing(ConfigError("s.yaml", "x")), {}, codes).code, 4);
  EXPECT_EQ(runTool(throwing(OutputError("o", "x")), {}, codes).code, 5);
  EXPECT_EQ(runTool(throwing(std::runtime_error("x")), {}, codes).code, 4);
  // A message with newlines (from a hostile file) stays one line.
  EXPECT_EQ(runTool(throwing(std::runtime_error("a\nb"))).err, "t: a\\nb\n");
}

TEST(ToolRun, ParseErrorsAreTheBadInputCodeNotCli11s) {
  const auto body = [](int argc, char** argv) {
    CLI::App app{"test tool"};
    double x = 1;
    int n = 0;
    app.add_option("--x", x)->check(tool::Finite(0.5, 2));
    app.add_option("--n", n);
    tool::parse(app, argc, argv);
    return 0;
  };
  EXPECT_EQ(runTool(body, {"--x", "1.5", "--n", "3"}).code, 0);
  for (const std::vector<std::string>& args :
       std::vector<std::vector<std::string>>{{"--n", "abc"}, {"--bogus"}, {"--x"}, {"--x", "nan"},
                                             {"--x", "inf"}, {"--x", "1e-300"}, {"--x", "3"}, {"extra"}}) {
    const Result r = runTool(body, args);
    EXPECT_EQ(r.code, 2) << args[0];
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find("(see --help)"), std::string::npos) << r.err;
  }
  EXPECT_NE(runTool(body, {"--x", "nan"}).err.find("'nan' is not a finite number"), std::string::npos);
  EXPECT_NE(runTool(body, {"--x", "3"}).err.find("3 is outside [0.5, 2]"), std::string::npos);
  ::testing::internal::CaptureStdout();
  const Result help = runTool(body, {"--help"});
  const std::string out = ::testing::internal::GetCapturedStdout();
  EXPECT_EQ(help.code, 0);
  EXPECT_NE(out.find("test tool"), std::string::npos);
}

TEST(ToolRun, TheRobotIsStoppedBeforeTheErrorLine) {
  std::vector<std::string> events;
  const Result r = runTool([&](int, char**) -> int {
    const tool::StopOnError guard([&] { events.push_back("stop"); });
    events.push_back("work");
    throw ConfigError("enon.yaml", "late failure");
  });
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(events, (std::vector<std::string>{"work", "stop"}));
  // A scope left normally does not stop.
  events.clear();
  runTool([&](int, char**) {
    const tool::StopOnError guard([&] { events.push_back("stop"); });
    return 0;
  });
  EXPECT_TRUE(events.empty());
}

TEST(ToolRun, AFailedWriteToStdoutIsAnErrorNotASilentLoss) {
  // In a child: stdout is /dev/full (every write fails with ENOSPC).
  const std::filesystem::path err = refgrasp::testing::tempDir("refgrasp_test_tool") / "err.txt";
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::freopen("/dev/full", "w", stdout);
    std::freopen(err.c_str(), "w", stderr);
    char name[] = "t";
    char* argv[] = {name, nullptr};
    const int code = tool::run("t", 1, argv, [](int, char**) {
      for (int i = 0; i < 3; ++i) std::printf("{\"line\": %d}\n", i);
      return 0;
    });
    ::_exit(code);
  }
  int st = 0;
  ::waitpid(pid, &st, 0);
  ASSERT_TRUE(WIFEXITED(st));
  EXPECT_EQ(WEXITSTATUS(st), 3);
  EXPECT_EQ(refgrasp::testing::readFile(err), "t: cannot write to standard output: No space left on device\n");
}

TEST(ToolRun, OutputFoldersAndFilesThatCannotBeWrittenAreOutputErrors) {
  const std::filesystem::path d = refgrasp::testing::tempDir("refgrasp_test_tool");
  std::ofstream(d / "plain") << "x";
  try {
    tool::makeOutputDir((d / "plain" / "sub").string());
    FAIL();
  } catch (const OutputError& e) {
    EXPECT_EQ(std::string(e.what()), (d / "plain" / "sub").string() + ": cannot create folder: Not a directory");
  }
  std::ofstream full("/dev/full");
  full << std::string(100000, 'x');
  EXPECT_THROW(tool::checkWritten(full, "/dev/full"), OutputError);
  EXPECT_THROW(tool::writeImage((d / "plain" / "x.png").string(), cv::Mat(4, 4, CV_8UC1)), OutputError);
}

TEST(ToolInteger, ValuesPast64BitsAndNonDecimalsAreRefusedNeverWrapped) {
  uint64_t seed = 0;
  int64_t frames = 0;
  int tag = 0;
  const auto body = [&](int argc, char** argv) {
    CLI::App app{"test tool"};
    app.add_option("--seed", seed)->check(tool::Unsigned());
    app.add_option("--frames", frames)->check(tool::Integer(0, INT64_MAX));
    app.add_option("--tag", tag)->check(tool::Integer(-1, 232));
    tool::parse(app, argc, argv);
    return 0;
  };
  EXPECT_EQ(runTool(body, {"--seed", "18446744073709551615", "--frames", "9223372036854775807", "--tag", "-1"}).code, 0);
  EXPECT_EQ(seed, UINT64_MAX);
  EXPECT_EQ(frames, INT64_MAX);
  EXPECT_EQ(tag, -1);
  EXPECT_EQ(runTool(body, {"--tag", "+232"}).code, 0);
  EXPECT_EQ(tag, 232);
  for (const auto& [args, needle] : std::vector<std::pair<std::vector<std::string>, std::string>>{
           {{"--seed", "18446744073709551616"}, "--seed: 18446744073709551616 is outside [0, 18446744073709551615]"},
           {{"--seed", "99999999999999999999999"}, "is outside [0, 18446744073709551615]"},
           {{"--seed", "-1"}, "--seed: -1 is outside"},
           {{"--frames", "9223372036854775808"}, "--frames: 9223372036854775808 is outside [0, 9223372036854775807]"},
           {{"--tag", "-2"}, "--tag: -2 is outside [-1, 232]"},
           {{"--tag", "233"}, "is outside [-1, 232]"},
           {{"--tag", "1.5"}, "'1.5' is not a whole number"},
           {{"--tag", "1e2"}, "'1e2' is not a whole number"},
           {{"--tag", "0x10"}, "'0x10' is not a whole number"},
           {{"--tag", "-"}, "'-' is not a whole number"}}) {
    const Result r = runTool(body, args);
    EXPECT_EQ(r.code, 2) << args[1];
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
  }
}

TEST(ToolPaths, AnOutputThatIsAnInputIsRefusedWhateverTheName) {
  namespace fs = std::filesystem;
  const fs::path d = refgrasp::testing::tempDir("refgrasp_test_tool_paths");
  fs::create_directories(d / "in");
  std::ofstream(d / "in" / "photo.png") << "x";
  fs::remove(d / "link.png");
  fs::remove(d / "hard.png");
  fs::create_symlink(d / "in" / "photo.png", d / "link.png");
  fs::create_hard_link(d / "in" / "photo.png", d / "hard.png");
  const std::string photo = (d / "in" / "photo.png").string();
  const auto problem = [&](const std::function<void(tool::Paths&)>& add) -> std::string {
    tool::Paths p;
    p.input("--image", photo);
    add(p);
    try {
      p.check();
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_EQ(problem([&](tool::Paths& p) { p.output("--check", photo); }),
            "--check " + photo + ": is the input --image " + photo + " (it would be overwritten)");
  for (const fs::path& same : {d / "in" / "." / "photo.png", d / "in" / ".." / "in" / "photo.png", d / "link.png",
                               d / "hard.png"})
    EXPECT_NE(problem([&](tool::Paths& p) { p.output("--check", same.string()); }).find("is the input --image"),
              std::string::npos)
        << same;
  // A relative name for the same file.
  const fs::path cwd = fs::current_path();
  fs::current_path(d);
  EXPECT_NE(problem([&](tool::Paths& p) { p.output("--check", "in/photo.png"); }), "");
  fs::current_path(cwd);
  // Folders: the input's own folder or one above it.
  EXPECT_NE(problem([&](tool::Paths& p) { p.outputFolder("--out", (d / "in").string()); }).find("holds the input"),
            std::string::npos);
  EXPECT_NE(problem([&](tool::Paths& p) { p.outputFolder("--out", d.string() + "/"); }), "");
  EXPECT_NE(problem([&](tool::Paths& p) { p.inputSpec("--input", "folder:" + (d / "in").string());
                                          p.outputFolder("--out", (d / "in").string()); }), "");
  // Two outputs that are one file.
  EXPECT_NE(problem([&](tool::Paths& p) { p.output("--a", (d / "o.yaml").string()); p.output("--b", (d / "." / "o.yaml").string()); })
                .find("--b " + (d / "." / "o.yaml").string() + ": is also --a"),
            std::string::npos);
  // Distinct files, a new folder beside the input, empty paths: accepted.
  EXPECT_EQ(problem([&](tool::Paths& p) {
              p.output("--check", (d / "in" / "photo_check.png").string());
              p.outputFolder("--out", (d / "in2").string());
              p.output("--video", "");
              p.input("--camera", "");
            }),
            "");
}

TEST(ToolEnvironment, DomainIdCycloneUriAndPixelLimitAreCheckedBeforeUse) {
  namespace fs = std::filesystem;
  const fs::path d = refgrasp::testing::tempDir("refgrasp_test_tool_env");
  const auto domain = [](const char* v) -> std::string {
    ::setenv("ROS_DOMAIN_ID", v, 1);
    try {
      return std::to_string(tool::checkDdsEnvironment());
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
  };
  ::unsetenv("CYCLONEDDS_URI");
  EXPECT_EQ(domain(""), "0");
  EXPECT_EQ(domain("232"), "232");
  EXPECT_EQ(domain("abc"), "ROS_DOMAIN_ID: 'abc' is not a domain id (an integer in [0, 232])");
  for (const char* bad : {"233", "-1", "7x", "4294967303", "99999999999999999999999", " 7"})
    EXPECT_NE(domain(bad).find("is not a domain id"), std::string::npos) << bad;
  ::unsetenv("ROS_DOMAIN_ID");

  const std::string good = std::string(REFGRASP_SOURCE_DIR) + "/config/dds/cyclonedds_loopback.xml";
  fs::create_directories(d / "dir.xml");
  const std::string fifo = (d / "c.fifo").string();
  if (!fs::exists(fifo)) ::mkfifo(fifo.c_str(), 0600);
  std::ofstream(d / "big.xml") << std::string((4u << 20) + 1, ' ');
  for (const std::string& ok : {good, "file://" + good, " ,file://" + good + ", " + good,
                                std::string("<CycloneDDS><Domain><General/></Domain></CycloneDDS>"),
                                "<CycloneDDS><Domain Id=\"any\"/></CycloneDDS>,file://" + good,
                                std::string("<!-- a, b --><CycloneDDS/>"), std::string("")})
    EXPECT_EQ(tool::cycloneUriProblem(ok), "") << ok;
  // Cyclone opens an entry up to its comma as is: a space before the comma is part of the name.
  EXPECT_EQ(tool::cycloneUriProblem(good + " ,"), good + " : file not found");
  EXPECT_EQ(tool::cycloneUriProblem(fifo), fifo + ": is a FIFO, not a regular file");
  EXPECT_EQ(tool::cycloneUriProblem("file://" + fifo), fifo + ": is a FIFO, not a regular file");
  EXPECT_NE(tool::cycloneUriProblem((d / "dir.xml").string()).find("is a directory"), std::string::npos);
  EXPECT_NE(tool::cycloneUriProblem("file://" + (d / "missing.xml").string()).find("missing.xml: file not found"),
            std::string::npos);
  EXPECT_NE(tool::cycloneUriProblem((d / "big.xml").string()).find("more than the limit"), std::string::npos);
  EXPECT_NE(tool::cycloneUriProblem("<CycloneDDS/>,file://" + good + "," + fifo).find(fifo), std::string::npos);
  if (::geteuid() != 0) {  // root reads any file
    std::ofstream(d / "locked.xml") << "<CycloneDDS/>";
    fs::permissions(d / "locked.xml", fs::perms::none);
    EXPECT_NE(tool::cycloneUriProblem((d / "locked.xml").string()).find("cannot be read"), std::string::npos);
  }
  ::setenv("CYCLONEDDS_URI", ("file://" + fifo).c_str(), 1);
  EXPECT_EQ(domain(""), "CYCLONEDDS_URI: " + fifo + ": is a FIFO, not a regular file");
  ::unsetenv("CYCLONEDDS_URI");

  for (const char* bad : {"abc", "0", "-1", "1e6", "99999999999999999999999"}) {
    ::setenv("REFGRASP_MAX_IMAGE_PIXELS", bad, 1);
    EXPECT_THROW(tool::checkImageEnvironment(), std::invalid_argument) << bad;
  }
  ::setenv("REFGRASP_MAX_IMAGE_PIXELS", "150", 1);
  EXPECT_NO_THROW(tool::checkImageEnvironment());
  ::unsetenv("REFGRASP_MAX_IMAGE_PIXELS");
}

TEST(ToolWriteImage, AFullDiskIsOneLineOfOursNotLibpngs) {
  namespace fs = std::filesystem;
  const fs::path d = refgrasp::testing::tempDir("refgrasp_test_tool_full");
  fs::remove(d / "full.png");
  fs::create_symlink("/dev/full", d / "full.png");
  const Result r = runTool([&](int, char**) {
    tool::writeImage((d / "full.png").string(), cv::Mat(8, 8, CV_8UC1, cv::Scalar(7)));
    return 0;
  });
  EXPECT_EQ(r.code, 3);
  EXPECT_EQ(r.err, "t: " + (d / "full.png").string() + ": cannot write the image: No space left on device\n");
  EXPECT_NE(runTool([&](int, char**) {
              tool::writeImage((d / "no_extension").string(), cv::Mat(8, 8, CV_8UC1));
              return 0;
            }).err.find("no encoder for ''"),
            std::string::npos);
  EXPECT_EQ(tool::outputFileProblem((d / "nowhere" / "v.mp4").string()), "folder " + (d / "nowhere").string() + " does not exist");
  EXPECT_EQ(tool::outputFileProblem((d / "full.png" / "v.mp4").string()), (d / "full.png").string() + " is not a folder");
  EXPECT_EQ(tool::outputFileProblem((d / "v.mp4").string()), "");
}
