#pragma once
// The fuzz targets: one per configuration parser, one for image decoding and one per
// line-oriented or JSON file a tool reads (a recording's index.jsonl and recording.json, an image
// folder's stamps file). Each takes the bytes of one input file; a parser may refuse it with
// ConfigError or std::invalid_argument (the one-line errors the tools print), anything else
// escaping is a finding: another exception, a crash, a hang or a memory bomb (libFuzzer's
// -timeout and -rss_limit_mb).
//
// The same targets run in two builds: fuzz/fuzz_main.cpp makes one libFuzzer binary per target
// (clang, -fsanitize=fuzzer,address,undefined; scripts/fuzz.sh), and ctest replays every saved
// input of fuzz/regressions/<target>/ and the seeds with the normal build (tests/fuzz/).
#include <string>
#include <vector>

namespace refgrasp::fuzz {

struct Target {
  std::string name;
  /// Parses one input; throws only what a tool turns into its one-line error.
  void (*run)(const std::string& bytes);
  /// Seed folders (relative to the source tree), read recursively by libFuzzer.
  std::vector<std::string> seeds;
};

const std::vector<Target>& targets();
/// nullptr for an unknown name.
const Target* findTarget(const std::string& name);

/// Runs `target` on `bytes`: returns "" when it passed (parsed or refused cleanly), else what
/// escaped (for the regression test; libFuzzer lets it escape instead).
std::string runChecked(const Target& target, const std::string& bytes);

}  // namespace refgrasp::fuzz
