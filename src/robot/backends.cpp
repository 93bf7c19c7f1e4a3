#include "robot/backends.h"

#include <mutex>

#include "robot/dds/dds_robot.h"
#include "robot/sim/sim_enon.h"

namespace refgrasp::robot {

void registerBuiltinBackends() {
  static std::once_flag once;
  std::call_once(once, [] {
    sim::registerSimBackend();
    dds::registerDdsBackend();
  });
}

}  // namespace refgrasp::robot
