#pragma once
// Registers every robot backend this build has (target refgrasp_robot_backends, which links each
// backend library): "sim" (the simulated enon) and "dds" (a robot driver on the DDS bus). Apps
// call it once before robot::makeRobot (robot/backend.h).
namespace refgrasp::robot {

/// Idempotent.
void registerBuiltinBackends();

}  // namespace refgrasp::robot
