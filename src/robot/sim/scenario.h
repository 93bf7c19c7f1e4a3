#pragma once
// Simulated worlds for the synthetic camera and the simulated enon, read from scenario YAML.
//
// World frame w: z up, origin on the floor, x forward from the robot's usual start.
// Object frames follow the planar-object convention of the object's front face (DEVELOPERS.md):
// origin at the centre of the front texture, x along its columns, y along its rows (down for an
// upright object), z into the object (away from a viewer of the front face). A box of size
// (x, y, z) = (width, height, depth) extends from z = 0 (front face) to z = depth. A cylinder
// (shape: cylinder) has its label's frame (core/cylinder.h): origin at the label's centre on the
// surface, y along the axis (down for an upright can), z into the object, the axis the line
// x = 0, z = radius; its side spans y in [-height/2, height/2].
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/pose.h"
#include "core/types.h"
#include "robot/sim/degrade.h"
#include "robot/sim/render.h"

namespace refgrasp::sim {

/// A solid part of an object, for collisions and grasping: a box (centre and axes oMs in the
/// object frame, half extents half_m along x_s, y_s, z_s) or a cylinder (centre and axes oMs,
/// its axis along z_s, half_m = (radius, radius, half height): the box that bounds it).
struct Solid {
  Pose oMs;
  Eigen::Vector3d half_m = Eigen::Vector3d::Zero();
  bool cylinder = false;
};

/// The solid of a scenario cylinder in its object frame (core/cylinder.h): axis z_s along y_o
/// through (0, 0, radius_m), spanning y_o in [-height_m/2, height_m/2].
Solid cylinderSolid(double radius_m, double height_m);

/// Mass of a scenario object without `mass_kg` (a filled cereal box is about 0.4 kg).
constexpr double kDefaultObjectMassKg = 0.3;

/// What a world object is: a scenario object (an item: grasped, pushed into), or a fixture of the
/// room that is never grasped: the table, the floor (the base stands on it), the walls.
enum class ObjectKind { kItem, kTable, kFloor, kWalls };

struct SimObject {
  std::string name;
  ObjectKind kind = ObjectKind::kItem;
  std::string definition;  ///< resolved path of the detector object YAML ("" for distractors)
  Pose wMo;                ///< object frame in the world
  Pose oMg;                ///< grasp frame in the object frame
  std::vector<TexturedPlane> faces;  ///< the cMp field of each face holds oMp (face in object frame)
  /// Labelled cylinders (a can); the cMo field of each holds its frame in the object frame (oMc;
  /// identity for a scenario cylinder, whose object frame is the label's: core/cylinder.h).
  std::vector<TexturedCylinder> cylinders;
  /// Solids the robot collides with and grips: a box object's box, a plane 1 mm thick behind its
  /// face, a cylinder object's cylinder, the table's block, the floor (a slab below z = 0) and
  /// the walls (slabs behind them).
  /// None: the object is never touched (it can still be grasped, with zero width).
  std::vector<Solid> solids;
  double mass_kg = kDefaultObjectMassKg;
  bool is_target = false;
};

struct World {
  std::vector<SimObject> objects;  ///< scenario objects first, then the table, floor and walls
  cv::Mat background;              ///< far backdrop where no plane is seen (may be empty)
};

/// Faults of the simulated robot, applied by the simulated enon (robot/sim_enon).
struct Faults {
  double command_latency_s = 0;        ///< commands take effect this much later
  double frame_drop_probability = 0;   ///< per stereo frame, in [0, 1]
  double frame_delay_s = 0;            ///< frames are delivered this much after exposure
  double odom_noise_m_per_m = 0;       ///< odometry translation noise (std) per metre travelled
  double odom_noise_rad_per_rad = 0;   ///< odometry heading noise (std) per radian turned
  std::string stuck_joint;             ///< joint name from config/enon.yaml ("" = none)
  double stuck_after_s = 0;            ///< the joint stops moving after this simulation time
};

struct Scenario {
  std::string path;
  uint64_t seed = 0;
  World world;
  double start_x_m = 0, start_y_m = 0, start_theta_rad = 0;  ///< robot base pose in the world
  Faults faults;
  Degradation camera;        ///< per-image degradations of the synthetic camera
  double exposure_s = 0.01;  ///< motion blur = image motion during the exposure
  double max_duration_s = 120;
};

/// Reads and validates a scenario YAML (format: config/scenarios/README.md). Textures and object
/// definitions are resolved relative to the scenario file. Throws ConfigError
/// "<file>: <field>: <problem>" (one line; fields like objects[1].pose.translation).
Scenario loadScenario(const std::string& path);

/// Planes of a box of `size_m` (x, y, z extents) centred on `centre` in the frame f, faces ordered
/// -x, +x, -y, +y, -z, +z. `rows` gives, per face, the frame-f direction of the texture rows.
std::vector<TexturedPlane> boxFaces(const Eigen::Vector3d& size_m, const Eigen::Vector3d& centre,
                                    const std::array<cv::Mat, 6>& textures,
                                    const std::array<Eigen::Vector3d, 6>& rows);

}  // namespace refgrasp::sim
