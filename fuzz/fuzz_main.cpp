// libFuzzer entry point of one target (REFGRASP_FUZZ_TARGET, see fuzz/targets.h). ConfigError
// and std::invalid_argument are the clean refusals; any other exception escapes to libFuzzer,
// which reports it (with the input) as a finding.
#include <cstddef>
#include <cstdint>
#include <exception>
#include <stdexcept>

#include "core/error.h"
#include "targets.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const refgrasp::fuzz::Target* target = refgrasp::fuzz::findTarget(REFGRASP_FUZZ_TARGET);
  if (!target) std::terminate();
  try {
    target->run(std::string(reinterpret_cast<const char*>(data), size));
  } catch (const refgrasp::ConfigError&) {
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
