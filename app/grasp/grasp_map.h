#pragma once
// The top-down map panel of enon_grasp's video (simulated runs): the room (floor, walls), the
// tables, the objects (the target outlined), the search's belief as a heat map, the looks taken
// (each a field-of-view wedge from the camera's position), the robot's path and the robot now.
//
// Frames: the map is drawn in the simulator's world frame w (x, y on the floor, metres; image x
// to the right along +x, image y up along +y). The search's belief and looks are in the
// ODOMETRY frame; odom_in_world places that frame in w. The simulated enon's odometry starts at
// the true start pose expressed in w (SimEnon: base_odom = base_true at construction), so for it
// odom_in_world is the identity; odometry noise makes the two drift apart during a run, and the
// map then shows belief and looks where the robot believed they were.
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

#include "robot/kinematics.h"
#include "robot/sim/scenario.h"
#include "servo/search_map.h"

namespace refgrasp::grasp_app {

/// What the map shows besides the world, at one instant.
struct MapFrame {
  std::vector<Eigen::Vector2d> path_w;   ///< true base positions so far (world, m)
  robot::PlanarPose base_w;              ///< true base pose now (world)
  double base_radius_m = 0.25;           ///< drawn footprint of the base
  std::vector<servo::SearchLook> looks;  ///< looks started so far (odometry frame), oldest first
  const servo::SearchBelief* belief = nullptr;  ///< latest belief (odometry frame), may be null
};

class TopDownMap {
 public:
  /// Fits the room of `world` (its floor; without a floor, its objects with a 1 m margin) into
  /// a `size` image with 0.3 m around it. Fixed things (floor, walls, tables) are drawn once here.
  TopDownMap(const sim::World& world, const robot::PlanarPose& odom_in_world, cv::Size size = {640, 480});

  /// Image pixel (x right, y down; pixel centres at integers) of a world floor point.
  cv::Point2d pixel(const Eigen::Vector2d& p_w) const;
  /// A point of the odometry frame in the world frame.
  Eigen::Vector2d odomToWorld(const Eigen::Vector2d& p_odom) const;
  double pixelsPerMetre() const { return scale_; }

  /// The panel (BGR): the fixed layer, the belief, the objects of `world_now` (where they are
  /// now: a held object moves with the hand), the looks, the path and the robot.
  cv::Mat draw(const sim::World& world_now, const MapFrame& f) const;

  /// Colour of a belief cell holding `fraction` of the largest cell's probability (0..1):
  /// dark purple to yellow (the inferno colour map).
  static cv::Vec3b heatColour(double fraction);
  /// Opacity of a cell over the floor and tables: kHeatAlpha for the largest cell, down to 15 %
  /// of it for the smallest, so a belief spread thin leaves the room readable.
  static double heatAlpha(double fraction);
  static constexpr double kHeatAlpha = 0.6;

 private:
  void drawBelief(cv::Mat& img, const servo::SearchBelief& b) const;
  void drawLooks(cv::Mat& img, const std::vector<servo::SearchLook>& looks) const;
  std::vector<cv::Point> polygon(const std::vector<Eigen::Vector2d>& pts_w) const;

  robot::PlanarPose odom_in_world_;
  cv::Size size_;
  double scale_ = 1;               ///< pixels per metre
  Eigen::Vector2d centre_w_;       ///< world point at the image centre
  cv::Mat fixed_;                  ///< floor, walls, tables
};

/// Footprint of a world object's solids on the floor (world, m): the convex hull of each
/// solid's outline seen from above, one polygon per solid.
std::vector<std::vector<Eigen::Vector2d>> footprints(const sim::SimObject& o);

}  // namespace refgrasp::grasp_app
