#include "robot/watchdog.h"

#include <cmath>
#include <limits>

#include "core/error.h"

namespace refgrasp::robot {

Watchdog::Watchdog(Seconds timeout_s) : timeout_(timeout_s), last_feed_(0) {
  check(timeout_s > 0 && std::isfinite(timeout_s), "Watchdog", "timeout must be positive");
}

void Watchdog::feed(Seconds time) {
  last_feed_ = time;
  fed_ = true;
}

bool Watchdog::expired(Seconds time) const { return !fed_ || time - last_feed_ > timeout_; }

Seconds Watchdog::deadline() const {
  return fed_ ? last_feed_ + timeout_ : -std::numeric_limits<double>::infinity();
}

void Watchdog::reset() { fed_ = false; }

}  // namespace refgrasp::robot
