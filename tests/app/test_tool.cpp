// tool::run, tool::parse, tool::StopOnError and tool::Finite (app/tool/tool.h), in process: every
// exception becomes one line and the tool's code, CLI11's parse errors the bad-input code (not
// CLI11's 104-114), a failed write to stdout the output code, and the robot stops first.
#include <gtest/gtest.h>
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
