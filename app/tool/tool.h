#pragma once
// What every refgrasp command-line tool does the same way (docs/errors.md):
//   tool::run()        one top-level handler: any exception becomes ONE line "<tool>: <problem>"
//                      on stderr and the tool's documented exit code; stdout is flushed and a
//                      failed write (a full disk, a closed pipe) is an error, never a silent loss;
//                      OpenCV's logger, FFmpeg's and Cyclone DDS's messages are silenced first.
//   tool::parse()      CLI11 parsing: --help exits 0, a parse error is one line and the
//                      "bad input" code (never CLI11's own 104-114).
//   tool::StopOnError  stops the robot when its scope is left by an exception, before the line.
//   tool::Finite       a numeric option check that refuses NaN and inf (CLI::Range lets NaN in).
//   tool::Integer      an integer option check: decimal, in range, never wrapped (CLI11 parses
//                      an unsigned or 64-bit option past its range without an error).
//   tool::Paths        outputs checked against inputs before anything is written: a tool never
//                      writes over one of its own inputs, whatever the names (links included).
//   tool::checkDdsEnvironment   ROS_DOMAIN_ID and CYCLONEDDS_URI checked before Cyclone sees them.
//   tool::exitOnSignal / flagOnSignal   start-up that SIGINT/SIGTERM interrupt at once.
// tool::parse() also checks REFGRASP_MAX_IMAGE_PIXELS (every tool).
//
// A tool's main is one line:  int main(int argc, char** argv) { return tool::run("x", argc, argv, body); }
#include <CLI/CLI.hpp>
#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

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

/// Exit status of a tool interrupted by SIGINT/SIGTERM during its start-up (the shell's
/// convention: 128 + the signal number, 130 for SIGINT, 143 for SIGTERM).
int interruptedCode(int signal_number);

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

/// CLI11 check: a whole decimal number (optional sign) in [lo, hi]; a value beyond 64 bits is
/// "out of range", never wrapped or saturated.
CLI::Validator Integer(int64_t lo, int64_t hi);
/// As Integer, for unsigned 64-bit options (seeds): [0, hi].
CLI::Validator Unsigned(uint64_t hi = UINT64_MAX);

/// The inputs and outputs of one run, checked before anything is written: an output that is an
/// input (the same path once normalised, or the same file by device and inode: symlinks and hard
/// links included), an output folder that is or holds an input, or two outputs that are one file.
class Paths {
 public:
  /// `option` names the path in the error ("--image"); an empty path is ignored.
  void input(const std::string& option, const std::string& path);
  /// An input given as a frame source spec (robot/sources.h: "kind:PATH,PATH" or a path).
  void inputSpec(const std::string& option, const std::string& spec);
  void output(const std::string& option, const std::string& path);
  /// A folder the tool writes into (created, its files replaced).
  void outputFolder(const std::string& option, const std::string& path);
  /// Throws std::invalid_argument "<option> <path>: is the input <option> <path> (it would be
  /// overwritten)" (or "holds the input", "is also <option>") on the first clash.
  void check() const;

 private:
  struct Entry {
    std::string option, path;
    bool folder = false;
  };
  std::vector<Entry> inputs_, outputs_;
};

/// The DDS environment, checked before the first participant: ROS_DOMAIN_ID (unset or empty: 0;
/// else an integer in [0, 232], as ROS 2 allows) and CYCLONEDDS_URI (inline XML "<...>" and
/// comma-separated file entries, plain or file://, as Cyclone reads them: each file entry must
/// be a readable regular file of at most 4 MiB, so a FIFO cannot block the start-up). Returns the
/// domain of ROS_DOMAIN_ID; throws std::invalid_argument "<VARIABLE>: <problem>".
int checkDdsEnvironment();
/// "" when CYCLONEDDS_URI's value `uri` is acceptable, else the problem (checkDdsEnvironment).
std::string cycloneUriProblem(const std::string& uri);
/// The first error Cyclone DDS logged in this run ("" if none): its logger is silenced by run().
std::string ddsError();
/// `message`, followed by " (Cyclone DDS: <its first error>)" when it logged one: the cause of a
/// participant or endpoint that could not be created.
std::string withDdsError(const std::string& message);
/// REFGRASP_MAX_IMAGE_PIXELS unset, empty or a whole number in [1, 2^62]; else std::invalid_argument.
void checkImageEnvironment();

/// From now on SIGINT/SIGTERM end the tool at once: one line "<tool>: interrupted by SIGTERM
/// during start-up" and interruptedCode(signal). For start-up phases that may block (a DDS
/// participant, waiting for a robot's first state) before anything was commanded.
void exitOnSignal();
/// From now on SIGINT/SIGTERM only set interruptedBy(): for loops that stop the robot first.
void flagOnSignal();
/// The signal received since flagOnSignal(), else 0.
int interruptedBy();

/// "" when a file can be created at `path` (its folder exists and is writable), else the problem:
/// "folder <dir> does not exist", "<dir> is not a folder", "folder <dir> is not writable". For
/// outputs written late (a video, a result at exit) whose library would blame something else.
std::string outputFileProblem(const std::string& path);

/// Creates the folder (and its parents); throws OutputError "<dir>: cannot create folder: <why>".
void makeOutputDir(const std::string& dir);
/// Throws OutputError "<file>: write failed: <why>" unless the stream flushed cleanly.
void checkWritten(std::ostream& out, const std::string& file);
/// Encodes the image in memory (the format from the extension) and writes it; OutputError
/// "<file>: cannot write the image: <why>" (a missing folder, a full disk: never libpng's own
/// message, which its encoder prints when it writes to a file itself).
void writeImage(const std::string& path, const cv::Mat& image, const std::vector<int>& params = {});

}  // namespace refgrasp::tool
