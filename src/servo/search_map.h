#pragma once
// What the search knows of the room and where it believes the target is, in the ODOMETRY frame
// w (x, y on the floor, z up; metres, radians). Shared by the search (servo/search_plan.h), the
// log and the video's top-down map.
//
// RoomMap: what a service robot knows of its room before it looks: the footprints of the fixed
// things in it (tables, shelves, walls) and which of them carry objects (their top surface
// heights). No map (empty) means an unknown room: the target may be anywhere within the search
// range, at table height, and the base moves only along the lines the search already uses.
//
// SearchBelief: a grid over the floor; p[r * cols + c] is the probability that the target stands
// on cell (c, r), whose centre is origin + ((c + 0.5) cell_m, (r + 0.5) cell_m). `height_m` is the
// height of the surface the target would stand on there. The cells' sum plus `elsewhere` is 1.
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/types.h"

namespace refgrasp::servo {

/// An axis-aligned footprint rotated by `yaw_rad` about its centre (odometry frame).
struct Footprint {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();  ///< m
  Eigen::Vector2d half_m = Eigen::Vector2d::Zero();  ///< half extents along its own x, y
  double yaw_rad = 0;
  /// True when (x, y) is inside the footprint grown by `margin_m` on every side.
  bool contains(const Eigen::Vector2d& p, double margin_m = 0) const;
  /// Distance (m) from (x, y) to the footprint; 0 inside it.
  double distance(const Eigen::Vector2d& p) const;
};

struct RoomFixture {
  std::string name;
  Footprint footprint;
  double height_m = 0;     ///< top surface above the floor (m)
  bool surface = false;    ///< objects stand on its top (a table, a shelf); walls are not
};

struct RoomMap {
  std::vector<RoomFixture> fixtures;
  /// The room's inside (the walls' inner faces); empty half_m: unbounded.
  Footprint inside;
  bool empty() const { return fixtures.empty() && inside.half_m.isZero(); }
};

struct SearchBelief {
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  ///< corner of cell (0, 0), m
  double cell_m = 0.2;
  int cols = 0, rows = 0;
  std::vector<float> p;         ///< per cell, row-major
  std::vector<float> height_m;  ///< per cell: surface height the target would stand on
  double elsewhere = 0;         ///< probability the target is in no cell (outside the range)
  Eigen::Vector2d centre(int c, int r) const {
    return origin + Eigen::Vector2d((c + 0.5) * cell_m, (r + 0.5) * cell_m);
  }
};

/// One look of the search, as the log and the video show it.
struct SearchLook {
  int index = 0;                   ///< 1, 2, ... in the run
  Seconds start = 0;               ///< when the head was told to go there
  Eigen::Vector2d camera_w = Eigen::Vector2d::Zero();  ///< camera position on the floor (m)
  double bearing_rad = 0;          ///< view direction (base heading + pan)
  double half_fov_rad = 0;         ///< half the horizontal field of view
  double range_m = 0;              ///< how far the look is expected to find the target
  double expected_gain = 0;        ///< belief mass it was expected to explain (0..1)
};

}  // namespace refgrasp::servo
