#pragma once
// The one-line refusal (std::invalid_argument) a call throws, or "(accepted)".
#include <functional>
#include <stdexcept>
#include <string>

namespace refgrasp::testing {

inline std::string refusal(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(accepted)";
}

}  // namespace refgrasp::testing
