#pragma once
// Status values of the hardware abstraction, shared by robot and camera interfaces
// (ros2_control's return_type and lifecycle states).
namespace refgrasp::robot {

/// What a HAL call returns inside the loop (never an exception). kDeactivate: the device asks to
/// be deactivated (e.g. an offline frame source has no frame left).
enum class ReturnType { kOk, kError, kDeactivate };
enum class Lifecycle { kUnconfigured, kInactive, kActive };
const char* toString(ReturnType r);

}  // namespace refgrasp::robot
