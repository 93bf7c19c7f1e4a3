#pragma once
// What every refgrasp command-line tool does the same way (docs/errors.md):
//   tool::run()        one top-level handler: any exception becomes ONE line "<tool>: <problem>"
//                      on stderr and the tool's documented exit code; stdout is flushed and a
//                      failed write (a full disk, a closed pipe) is an error, never a silent loss;
//                      OpenCV's logger and FFmpeg's messages are silenced first.
//   tool::parse()      CLI11 parsing: --help exits 0, a parse error is one line and the
//                      "bad input" code (never CLI11's own 104-114).
//   tool::StopOnError  stops the robot when its scope is left by an exception, before the line.
//   tool::Finite       a numeric option check that refuses NaN and inf (CLI::Range lets NaN in).
//
// A tool's main is one line:  int main(int argc, char** argv) { return tool::run("x", argc, argv, body); }
#include <CLI/CLI.hpp>
#include <functional>
#include <opencv2/core.hpp>
#include <string>

namespace refgrasp::tool {

/// The shared exit codes; a tool lists in its --help which it uses.
constexpr int kOk = 0;
constexpr int kSomeInputsUnusable = 1;  ///< some inputs skipped with one line each, the rest done
constexpr int kBadInput = 2;            ///< bad options or files, nothing done
constexpr int kOutputFailed = 3;        ///< an output file or stdout could not be written

struct RunOptions {
  int bad_input = kBadInput;          ///< ConfigError, std::invalid_argument, option parse errors
  int output_failed = kOutputFailed;  ///< OutputError, a failed write to stdout
  int failure = kBadInput;            ///< any other exception (out of memory, OpenCV, ...)
};

/// Thrown to leave a tool's body with `code` (its message already printed).
struct Exit {
  int code;
};

/// Runs body(argc, argv) and returns the exit code (see the top of this file).
int run(const std::string& name, int argc, char** argv,
        const std::function<int(int, char**)>& body, const RunOptions& options = {});

/// app.parse(): --help/--version print and throw Exit{0}; an error throws std::invalid_argument
/// "<problem> (see --help)", which run() turns into the bad-input code.
void parse(CLI::App& app, int argc, char** argv);

/// Calls stop() when the enclosing scope is left by an exception (a robot gets zero velocity
/// before the error line). stop() must not throw; if it does, that is swallowed.
class StopOnError {
 public:
  explicit StopOnError(std::function<void()> stop);
  ~StopOnError();
  StopOnError(const StopOnError&) = delete;
  StopOnError& operator=(const StopOnError&) = delete;

 private:
  std::function<void()> stop_;
  int uncaught_;
};

/// CLI11 check: a finite number in [lo, hi].
CLI::Validator Finite(double lo, double hi);

/// Creates the folder (and its parents); throws OutputError "<dir>: cannot create folder: <why>".
void makeOutputDir(const std::string& dir);
/// Throws OutputError "<file>: write failed: <why>" unless the stream flushed cleanly.
void checkWritten(std::ostream& out, const std::string& file);
/// cv::imwrite, or OutputError "<file>: cannot write the image".
void writeImage(const std::string& path, const cv::Mat& image);

}  // namespace refgrasp::tool
