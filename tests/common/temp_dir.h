#pragma once
// A scratch directory private to this test process: ctest runs test cases of one suite in
// parallel processes, so fixed paths would race.
#include <unistd.h>

#include <filesystem>
#include <string>

namespace refgrasp::testing {

inline std::filesystem::path tempDir(const std::string& name) {
  const std::filesystem::path d =
      std::filesystem::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
  std::filesystem::create_directories(d);
  return d;
}

}  // namespace refgrasp::testing
