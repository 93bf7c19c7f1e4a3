#pragma once
// What the robot knows of its room before it searches, read from a scenario: the footprints of
// its tables (surfaces objects stand on) and the inside of its walls (servo/search_map.h). The
// objects on the tables are not in it: the search is for one of them. Frames: the scenario's
// world frame, which is the simulated enon's odometry frame (odometry starts at the scenario's
// robot_start). Metres, radians.
#include "robot/sim/scenario.h"
#include "servo/grasp_controller.h"
#include "servo/grasp_geometry.h"
#include "servo/search_map.h"

namespace refgrasp::grasp_app {

/// The scenario's tables (each a surface at its top's height) and walls (the room's inside; no
/// walls: unbounded). Empty when the scenario has neither.
servo::RoomMap roomMapOf(const sim::Scenario& scenario);

/// The size the search expects of the target (m): the square root of the product of its
/// extent's two longer sides (a plane's face, a box's largest face, a can's side as seen), the
/// measure of the detector's recall by size (docs/results.md: size_px is the square root of the
/// projected area).
double targetSizeOf(const servo::ObjectExtent& extent);

/// `options` as enon_grasp runs them on `scenario`: the room map from it unless options.room
/// has one, and the search's target size from the object's extent.
servo::GraspOptions withRoom(servo::GraspOptions options, const sim::Scenario& scenario,
                             const servo::ObjectExtent& extent);

}  // namespace refgrasp::grasp_app
