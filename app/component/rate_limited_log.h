#pragma once
// One warning per kind of problem per period: the first occurrence is logged at once, repeats
// within the period are counted and reported with the next line logged for that kind.
#include <chrono>
#include <functional>
#include <map>
#include <mutex>
#include <string>

namespace refgrasp::component {

class RateLimitedLog {
 public:
  using Sink = std::function<void(const std::string&)>;
  RateLimitedLog(Sink sink, double period_s) : sink_(std::move(sink)), period_s_(period_s) {}

  /// Logs `line` unless a line of the same `kind` was logged less than period_s ago.
  /// Thread-safe. Returns true when it logged.
  bool warn(const std::string& kind, const std::string& line) {
    std::string out;
    {
      std::lock_guard<std::mutex> lock(mu_);
      const double now = std::chrono::duration<double>(
                             std::chrono::steady_clock::now().time_since_epoch()).count();
      Entry& e = entries_[kind];
      if (e.logged && now - e.last < period_s_) {
        ++e.suppressed;
        return false;
      }
      out = line;
      if (e.suppressed > 0) out += " (" + std::to_string(e.suppressed) + " more since the last warning)";
      e.logged = true;
      e.last = now;
      e.suppressed = 0;
    }
    sink_(out);
    return true;
  }

 private:
  struct Entry {
    bool logged = false;
    double last = 0;
    long suppressed = 0;
  };
  Sink sink_;
  double period_s_;
  std::mutex mu_;
  std::map<std::string, Entry> entries_;
};

}  // namespace refgrasp::component
