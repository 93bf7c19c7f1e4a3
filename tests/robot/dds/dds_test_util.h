#pragma once
// DDS tests are loopback-only and private: every test process uses the shipped loopback Cyclone
// configuration, a domain id derived from its pid and ROS names with its pid in them (ctest runs
// test cases in parallel processes).
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <functional>
#include <string>
#include <thread>

namespace refgrasp::testing {

/// CYCLONEDDS_URI = config/dds/cyclonedds_loopback.xml (children inherit it). Call before the
/// first participant of the process.
inline void useLoopbackDds() {
  const std::string uri =
      "file://" + std::string(REFGRASP_SOURCE_DIR) + "/config/dds/cyclonedds_loopback.xml";
  ::setenv("CYCLONEDDS_URI", uri.c_str(), 1);
}

/// A DDS domain id for this process, in [1, 100]. Cyclone's ports for domain d are 7400 + 250 d
/// and a few dozen above: up to domain 101 they stay below Linux's ephemeral range (32768-60999),
/// where any process's outgoing socket may hold one and the participant then fails to bind it
/// ("address in use"). Two processes sharing a domain stay apart by namespace.
inline int privateDomain() { return 1 + static_cast<int>(::getpid() % 100); }

/// "/<base>_<pid>".
inline std::string privateNamespace(const std::string& base) {
  return "/" + base + "_" + std::to_string(::getpid());
}

inline std::string probePath() { return REFGRASP_PROBE_PATH; }

/// Polls `done` every 2 ms for up to timeout_s.
inline bool waitUntil(const std::function<bool()>& done, double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (!done()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return true;
}

}  // namespace refgrasp::testing
