#include "robot/backends.h"

#include <mutex>

#include "robot/sim/sim_enon.h"

namespace refgrasp::robot {

void registerBuiltinBackends() {
  static std::once_flag once;
  std::call_once(once, [] { sim::registerSimBackend(); });
}

}  // namespace refgrasp::robot
