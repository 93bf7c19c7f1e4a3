#pragma once
// Running a built app (build/app/<name>) from a test: exit status, stdout and stderr.
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "common/temp_dir.h"

namespace refgrasp::testing {

struct AppRun {
  int status = -1;  ///< exit status, -1 when killed by a signal
  std::string out, err;
};

inline std::string readFile(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// Runs `<prefix> REFGRASP_APP_DIR/app args` through the shell (prefix: e.g. "prlimit --fsize=N").
inline AppRun runApp(const std::string& app, const std::string& args, const std::string& prefix = "") {
  const std::filesystem::path d = tempDir("refgrasp_test_app");
  const std::string cmd = prefix + (prefix.empty() ? "" : " ") + std::string(REFGRASP_APP_DIR) +
                          "/" + app + " " + args + " > " + (d / (app + "_out.txt")).string() +
                          " 2> " + (d / (app + "_err.txt")).string();
  const int st = std::system(cmd.c_str());
  return {WIFEXITED(st) ? WEXITSTATUS(st) : -1, readFile(d / (app + "_out.txt")),
          readFile(d / (app + "_err.txt"))};
}

}  // namespace refgrasp::testing
