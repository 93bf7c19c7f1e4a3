#pragma once
// Command watchdog: expired when no command was fed for longer than the timeout.
// Never fed counts as expired (nothing commanded means zero velocity).
#include "core/types.h"

namespace refgrasp::robot {

class Watchdog {
 public:
  /// \param timeout_s longest allowed gap between commands (> 0).
  explicit Watchdog(Seconds timeout_s);
  void feed(Seconds time);
  bool expired(Seconds time) const;
  /// Time at which the last command stops being valid (-inf when never fed).
  Seconds deadline() const;
  void reset();
  Seconds timeout() const { return timeout_; }

 private:
  Seconds timeout_;
  Seconds last_feed_;
  bool fed_ = false;
};

}  // namespace refgrasp::robot
