#pragma once
// Running a built app (build/app/<name>) with its wall time and peak memory, for the tests that
// feed it a memory bomb: the answer must come in bounded time and memory.
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

#include "common/app_run.h"

namespace refgrasp::testing {

struct BoundedRun {
  int status = -1;      ///< exit status, -1 when killed by a signal
  std::string err;      ///< stderr (stdout is discarded)
  double seconds = 0;   ///< wall time
  long max_rss_mb = 0;  ///< peak resident memory
};

inline BoundedRun runBounded(const std::string& app, const std::vector<std::string>& args) {
  const std::filesystem::path err = tempDir("refgrasp_test_app") / (app + "_bounded_err.txt");
  const std::string path = std::string(REFGRASP_APP_DIR) + "/" + app;
  std::vector<char*> argv{const_cast<char*>(path.c_str())};
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid == 0) {
    const int out = ::open("/dev/null", O_WRONLY), e = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (out < 0 || e < 0 || dup2(out, 1) < 0 || dup2(e, 2) < 0) _exit(127);
    execv(path.c_str(), argv.data());
    _exit(127);
  }
  BoundedRun r;
  int st = 0;
  rusage ru{};
  if (pid < 0 || wait4(pid, &st, 0, &ru) != pid) return r;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  r.max_rss_mb = ru.ru_maxrss / 1024;
  r.err = readFile(err);
  return r;
}

}  // namespace refgrasp::testing
