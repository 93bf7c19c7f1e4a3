// Replays, for every fuzz target (fuzz/targets.h), each input libFuzzer once found failing
// (fuzz/regressions/<target>/) and each seed, with the normal build: none may escape with
// anything but the clean one-line refusals, crash or hang.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "targets.h"

namespace fs = std::filesystem;
using refgrasp::fuzz::Target;

namespace {

std::string bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Every regular file under the target's regression folder and seed folders.
std::vector<fs::path> inputs(const Target& t) {
  const fs::path src = REFGRASP_SOURCE_DIR;
  std::vector<fs::path> dirs = {src / "fuzz/regressions" / t.name};
  for (const std::string& s : t.seeds) dirs.push_back(src / s);
  std::vector<fs::path> out;
  for (const fs::path& d : dirs) {
    if (!fs::is_directory(d)) continue;
    for (const auto& e : fs::recursive_directory_iterator(d))
      if (e.is_regular_file()) out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

TEST(FuzzRegressions, SavedFindingsAndSeedsAreRefusedCleanly) {
  for (const Target& t : refgrasp::fuzz::targets()) {
    SCOPED_TRACE(t.name);
    const std::vector<fs::path> files = inputs(t);
    EXPECT_GE(files.size(), 1u);
    for (const fs::path& f : files) EXPECT_EQ(refgrasp::fuzz::runChecked(t, bytes(f)), "") << f;
  }
}

// The seeds of the readers of recordings and stamps files are valid inputs: each is read without
// any error (a refused seed would start the fuzzer from nothing).
TEST(FuzzRegressions, TheRecordingAndStampsSeedsAreReadWithoutError) {
  const fs::path src = REFGRASP_SOURCE_DIR;
  for (const char* name : {"recording_index", "recording_json", "stamps"}) {
    const Target* t = refgrasp::fuzz::findTarget(name);
    ASSERT_NE(t, nullptr) << name;
    size_t seeds = 0;
    for (const auto& e : fs::directory_iterator(src / "fuzz/seeds" / name)) {
      ++seeds;
      std::string error;
      try {
        t->run(bytes(e.path()));
      } catch (const std::exception& x) {
        error = x.what();
      }
      EXPECT_EQ(error, "") << e.path();
    }
    EXPECT_GE(seeds, 2u) << name;
  }
}
