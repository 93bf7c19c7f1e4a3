#pragma once
// The search's belief over where the target stands, and the choice of the next look from it
// (servo/search_plan.h follows the choice). Everything is in the ODOMETRY frame w (z up);
// metres, radians, seconds.
//
// Belief: over (floor cell, facing): where the target stands and which way its front faces
// (kFacings directions). With a room map the prior spreads evenly over the tops of its surfaces
// (tables, shelves); without one, over the floor between min_range_m and unknown_range_m of the
// start, at unknown_height_m; facings as against_wall_m says. A look that misses multiplies each
// state's mass by 1 - pd, pd the probability that the look would have detected a target standing
// and facing so: 0 outside the image, behind a fixture or seen from beyond facing_none_rad of
// its facing, else a logistic in the target's projected size (detect_half_px, detect_slope_px,
// at most detect_max: the detector's recall by size, docs/results.md), less what earlier looks
// from views as good already tried (repeat_discount). A look that saw an unconfirmed candidate which did not
// confirm multiplies the cells around it by candidate_boost: worth a closer look.
//
// Next look: from every viewpoint the base can reach (a grid over the free floor, or, without a
// map, the start heading's line), every bearing and tilt, the look with the most belief mass
// explained (sum of p x pd) per second it costs (drive, turn, pan, settle, look). The search is
// over when the mass left unexplained is below stop_mass of the prior (every place has been
// seen well enough), or no look can explain anything more.
#include <memory>
#include <utility>
#include <vector>

#include "core/camera.h"
#include "core/pose.h"
#include "robot/enon_model.h"
#include "servo/search_map.h"

namespace refgrasp::servo {

struct BeliefSearchOptions {
  double cell_m = 0.2;
  /// No map: the target may stand on the floor plan between these ranges from the start (m).
  double min_range_m = 0.5;
  double unknown_range_m = 5.0;
  double unknown_height_m = 0.72;  ///< no map: a table's height
  /// The target's size (m; the square root of its face's area): its projected size in px decides
  /// pd. The caller sets it from the object; the default is a small box face.
  double target_size_m = 0.18;
  double target_above_m = 0.08;    ///< target centre above the surface it stands on
  /// Recall by projected size: pd = detect_max / (1 + exp(-(w - detect_half_px) / detect_slope_px)),
  /// w = fx x target_size_m / depth (px). 50 % at 45 px and 90 % at ~75 px: single-frame
  /// detection on the realistic sets (docs/results.md, "size" bins: the square root of the
  /// projected area).
  double detect_half_px = 45;
  double detect_slope_px = 10;
  double detect_max = 0.95;
  double image_margin_px = 16;     ///< the target's centre this far inside the image
  double max_view_range_m = 8;     ///< cells further than this are not looked at
  /// Looks count only where the target would be at most this large (px; 65 px: an 18 cm face
  /// 1.35 m away, a 9 cm can 0.7 m away): a target found nearer leaves the approach no room to
  /// line the base up without turning it out of the head's reach.
  double max_look_px = 65;
  /// Viewpoints: a grid this fine over the free floor; free = further than the base's radius
  /// plus clearance_m from every fixture and wall.
  double viewpoint_spacing_m = 0.5;
  double clearance_m = 0.15;
  double candidate_boost = 4;      ///< unconfirmed candidate that did not confirm: its cells x this
  double candidate_radius_m = 0.4;
  /// A miss from a view no better than one already tried says little: a look counts with
  /// pd - repeat_discount x (what the earlier looks at that state would have found together, at
  /// least the best one's pd), at least 0. Frames of one viewpoint fail together (the same size,
  /// angle and blur), so a search that only repeats looks from afar learns little and moves
  /// closer instead; repeats of one view explain at most pd / repeat_discount in all.
  double repeat_discount = 0.7;
  /// A target facing direction d (its front's normal) is seen fully from within facing_full_rad
  /// of d, not at all beyond facing_none_rad (the detector reaches ~60 deg of obliquity, the
  /// oracle 69 deg). Objects on furniture that stands against a wall (a side within
  /// against_wall_m of it) face the room: their facings' prior is cos(angle to the way into the
  /// room) + 0.05, none towards the wall; on free-standing furniture (and without a map) every
  /// facing is as likely, so a search may have to walk round a table.
  double against_wall_m = 0.6;
  double facing_full_rad = 0.8;
  double facing_none_rad = 1.3;
  double stop_mass = 0.01;         ///< unexplained mass (of the prior) below which the search ends
  double look_time_s = 0.9;        ///< settle + the look's frames, the cost of every look
  double pan_speed_radps = 1.0;    ///< for the cost of moving the head
  /// Looks keep the head this far inside its pan limits (the base turns for the rest): a target
  /// found at the limit leaves the view as soon as the approach turns the base away from it.
  double pan_margin_rad = 0.5;
  double tilt_min_rad = 0.0, tilt_max_rad = 0.5;  ///< tilts tried (3 evenly)
  /// Throws std::invalid_argument "BeliefSearchOptions.<field>: <problem>".
  void check() const;
};

/// What the search does next: drive `path` (waypoints, the last one the viewpoint), turn the base
/// to `heading_rad`, point the head at (pan_rad, tilt_rad), look.
struct PlannedLook {
  bool ok = false;                       ///< false: no look explains anything more
  std::vector<Eigen::Vector2d> path;     ///< empty: look from where the base stands
  double heading_rad = 0, pan_rad = 0, tilt_rad = 0;
  double gain = 0;                       ///< belief mass it is expected to explain (normalised)
  double cost_s = 0;
  double range_m = 0;                    ///< gain-weighted distance of the cells it explains
};

class BeliefSearch {
 public:
  /// Directions a target may face (its front's normal), 45 deg apart: the belief is over
  /// (cell, facing), since a look sees a face only from within ~60 deg of its normal.
  static constexpr int kFacings = 8;

  /// \param camera left camera intrinsics; \param map in the odometry frame (may be empty);
  /// \param line_viewpoints without a map: viewpoints along the start heading at these
  /// distances (m) besides the start. Throws std::invalid_argument for bad options.
  BeliefSearch(const robot::EnonModel& model, const Intrinsics& camera, const RoomMap& map,
               const BeliefSearchOptions& options, std::vector<double> line_viewpoints = {});

  /// The prior, the base at wMb (odometry).
  void reset(const Pose& wMb);
  /// A look from the left camera at wMc (odometry) that did not confirm the target.
  void miss(const Pose& wMc);
  /// An unconfirmed candidate at xy (odometry) did not confirm: the cells around it x `boost`
  /// (0: candidate_boost).
  void candidate(const Eigen::Vector2d& xy, double boost = 0);
  /// The look that explains the most per second from the base at wMb, head at pan_now.
  PlannedLook next(const Pose& wMb, double pan_now, double drive_speed_mps,
                   double turn_speed_radps) const;
  /// Unexplained mass as a fraction of the prior (1 at the start).
  double unexplained() const;
  bool done() const { return unexplained() < opt_.stop_mass; }
  /// pd of a target standing on listed cell `cell` (0 .. cells() - 1), seen from the left camera
  /// at wMc, its facing as the prior has it.
  double detectProbability(const Pose& wMc, int cell) const;
  /// The belief now, normalised (for the log and the video).
  std::shared_ptr<const SearchBelief> snapshot() const;
  const SearchBelief& grid() const { return grid_; }
  int cells() const { return static_cast<int>(cell_index_.size()); }
  const RoomMap& map() const { return map_; }
  /// True when a base at xy is clear of every fixture and wall (the map; always without one).
  bool free(const Eigen::Vector2d& xy) const;
  /// True when the straight segment a-b is free (sampled every 5 cm).
  bool freeSegment(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;
  /// Shortest path over the viewpoint grid from `from` to viewpoint v (empty if unreachable;
  /// waypoints after `from`, shortcut where the straight line is free).
  std::vector<Eigen::Vector2d> pathTo(const Eigen::Vector2d& from, int v) const;
  const std::vector<Eigen::Vector2d>& viewpoints() const { return viewpoints_; }

 private:
  /// The direction objects on `f` face (away from the wall it stands against), or zero.
  Eigen::Vector2d roomFacing(const Footprint& f) const;
  /// 1 when a camera in direction `to_camera` from a target facing direction `facing` (of
  /// kFacings) sees its face, falling to 0 (facing_full_rad .. facing_none_rad).
  double facingFactor(int facing, const Eigen::Vector2d& to_camera) const;
  /// pd of a look from wMc at listed cell `cell` for a target facing the camera (occlusion in).
  double sizePd(const Pose& wMc, int cell) const;
  /// The target's centre if it stood on listed cell `cell` (odometry, m).
  Eigen::Vector3d targetAt(int cell) const;
  /// pd of a look from the camera at cMw^-1 at listed cell `cell` for a target facing the
  /// camera, occlusion aside; `depth`: the target's depth in the camera (m) when in view.
  double unoccludedPd(const Pose& cMw, int cell, double* depth = nullptr) const;
  /// What a look with probability pd adds at state `state` (cell x kFacings + facing) after the
  /// looks so far.
  double novelPd(size_t state, double pd) const;
  bool occluded(const Eigen::Vector3d& from, const Eigen::Vector3d& to) const;
  void buildViewpoints(const Pose& wMb);
  /// Path lengths (m) from `from` to every viewpoint (infinity when unreachable) and the
  /// predecessor of each (-1: straight from `from`).
  void distances(const Eigen::Vector2d& from, std::vector<double>* dist, std::vector<int>* prev) const;

  robot::EnonModel model_;
  Intrinsics camera_;
  RoomMap map_;
  BeliefSearchOptions opt_;
  std::vector<double> line_viewpoints_;
  SearchBelief grid_;              ///< geometry and heights; p unused
  std::vector<int> cell_index_;    ///< grid cells that can hold the target
  /// Per state (listed cell x kFacings + facing): prior, unexplained mass, and what the looks so
  /// far would have found together (at least the best one's pd).
  std::vector<double> prior_, mass_, best_pd_;
  double prior_total_ = 0;
  std::vector<Eigen::Vector2d> viewpoints_;
  std::vector<std::vector<std::pair<int, double>>> links_;  ///< per viewpoint: (neighbour, m)
  double camera_height_m_ = 1.2;
  double body_radius_m_ = 0.25;
};

}  // namespace refgrasp::servo
