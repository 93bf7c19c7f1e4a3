#pragma once
// A child process for tests that run apps concurrently with the test (DDS peers): stdout and
// stderr go to files, wait() has a timeout, and the destructor kills what is still running.
#include <signal.h>
#include <sys/wait.h>
#include <fcntl.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace refgrasp::testing {

class Subprocess {
 public:
  /// Starts argv[0] (a path) with argv[1..]; output files are <dir>/<tag>.out and .err.
  Subprocess(const std::vector<std::string>& argv, const std::filesystem::path& dir,
             const std::string& tag)
      : out_(dir / (tag + ".out")), err_(dir / (tag + ".err")) {
    std::filesystem::create_directories(dir);
    pid_ = ::fork();
    if (pid_ == 0) {
      const int o = ::open(out_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      const int e = ::open(err_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      ::dup2(o, 1);
      ::dup2(e, 2);
      std::vector<char*> args;
      for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
      args.push_back(nullptr);
      ::execv(args[0], args.data());
      ::_exit(127);
    }
  }
  ~Subprocess() {
    if (running()) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  Subprocess(const Subprocess&) = delete;
  Subprocess& operator=(const Subprocess&) = delete;

  bool running() {
    if (done_) return false;
    int st = 0;
    const pid_t r = ::waitpid(pid_, &st, WNOHANG);
    if (r == pid_) finish(st);
    return !done_;
  }
  /// Exit code; -1 when it did not end within timeout_s, 128 + n when killed by signal n.
  int wait(double timeout_s) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (running()) {
      if (std::chrono::steady_clock::now() > end) return -1;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return code_;
  }
  void signal(int sig) {
    if (running()) ::kill(pid_, sig);
  }
  std::string out() const { return read(out_); }
  std::string err() const { return read(err_); }
  pid_t pid() const { return pid_; }

 private:
  void finish(int st) {
    done_ = true;
    code_ = WIFEXITED(st) ? WEXITSTATUS(st) : WIFSIGNALED(st) ? 128 + WTERMSIG(st) : -1;
  }
  static std::string read(const std::filesystem::path& p) {
    std::ifstream in(p);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
  std::filesystem::path out_, err_;
  pid_t pid_ = -1;
  bool done_ = false;
  int code_ = -1;
};

}  // namespace refgrasp::testing
