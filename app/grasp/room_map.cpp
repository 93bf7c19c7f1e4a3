#include "grasp/room_map.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace refgrasp::grasp_app {

servo::RoomMap roomMapOf(const sim::Scenario& scenario) {
  servo::RoomMap map;
  bool walls = false;
  servo::Footprint floor;
  for (const sim::SimObject& o : scenario.world.objects) {
    if (o.kind == sim::ObjectKind::kWalls) walls = true;
    if (o.kind == sim::ObjectKind::kFloor && !o.faces.empty()) {
      floor.centre = o.wMo.t.head<2>();
      floor.half_m = Eigen::Vector2d(o.faces[0].width_m, o.faces[0].height_m) / 2;
    }
    if (o.kind != sim::ObjectKind::kTable || o.solids.empty()) continue;
    // A table's frame is the centre of its top, z up; its block is its first solid.
    servo::RoomFixture f;
    f.name = o.name;
    f.surface = true;
    f.height_m = o.wMo.t.z();
    const Pose wMs = o.wMo * o.solids[0].oMs;
    f.footprint.centre = wMs.t.head<2>();
    f.footprint.half_m = o.solids[0].half_m.head<2>();
    f.footprint.yaw_rad = std::atan2(wMs.R(1, 0), wMs.R(0, 0));
    map.fixtures.push_back(f);
  }
  if (walls) map.inside = floor;
  return map;
}

double targetSizeOf(const servo::ObjectExtent& extent) {
  std::array<double, 3> e;
  for (int i = 0; i < 3; ++i) e[static_cast<size_t>(i)] = std::abs(extent.max_o[i] - extent.min_o[i]);
  std::sort(e.begin(), e.end());
  return std::sqrt(e[1] * e[2]);
}

servo::GraspOptions withRoom(servo::GraspOptions options, const sim::Scenario& scenario,
                             const servo::ObjectExtent& extent) {
  if (options.room.empty()) options.room = roomMapOf(scenario);
  options.belief.target_size_m = targetSizeOf(extent);
  return options;
}

}  // namespace refgrasp::grasp_app
