#include "servo/search_plan.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "robot/kinematics.h"
#include "servo/grasp_geometry.h"

namespace refgrasp::servo {

namespace {

constexpr int kBins = 720;  // half-degree bins of the circle of directions
constexpr double kMinGainRad = 0.05;  // a look must show at least this much unseen
// A restart's hint (where a lost target was) outweighs everything else in the belief: the
// prior spreads over every surface, the hint's cells are a few of them.
constexpr double kHintBoost = 1000;

int binOf(double bearing) {
  const double a = std::remainder(bearing, 2 * M_PI) + M_PI;  // [0, 2 pi]
  return std::clamp(static_cast<int>(a / (2 * M_PI) * kBins), 0, kBins - 1);
}
double bearingOf(int bin) { return (bin + 0.5) * 2 * M_PI / kBins - M_PI; }

bool finiteIn(double x, double lo, double hi) { return std::isfinite(x) && x >= lo && x <= hi; }

}  // namespace

void SearchPlanOptions::check() const {
  using refgrasp::check;
  check(finiteIn(tilt_rad, -M_PI / 2, M_PI / 2), "SearchPlanOptions.tilt_rad", "must be in [-pi/2, pi/2]");
  check(finiteIn(edge_margin_rad, 0, 0.5), "SearchPlanOptions.edge_margin_rad", "must be in [0, 0.5]");
  check(finiteIn(settle_s, 0, 10), "SearchPlanOptions.settle_s", "must be in [0, 10]");
  check(finiteIn(head_tolerance_rad, 1e-6, 0.5), "SearchPlanOptions.head_tolerance_rad",
        "must be in (0, 0.5]");
  check(finiteIn(confirm_timeout_s, 0, 60), "SearchPlanOptions.confirm_timeout_s", "must be in [0, 60]");
  check(finiteIn(turn_speed_radps, 1e-3, 10), "SearchPlanOptions.turn_speed_radps", "must be > 0");
  check(finiteIn(heading_tolerance_rad, 1e-4, 0.5), "SearchPlanOptions.heading_tolerance_rad",
        "must be in (0, 0.5]");
  check(finiteIn(viewpoint_step_m, 0, 10), "SearchPlanOptions.viewpoint_step_m", "must be in [0, 10]");
  check(finiteIn(drive_speed_mps, 1e-3, 2), "SearchPlanOptions.drive_speed_mps", "must be > 0");
  check(max_viewpoints >= 0 && max_viewpoints <= 100, "SearchPlanOptions.max_viewpoints",
        "must be in [0, 100]");
}

const char* toString(SearchState s) {
  switch (s) {
    case SearchState::kPointHead: return "point_head";
    case SearchState::kSettle: return "settle";
    case SearchState::kLook: return "look";
    case SearchState::kTurnBase: return "turn_base";
    case SearchState::kMoveBase: return "move_base";
    case SearchState::kFound: return "found";
    case SearchState::kNotFound: return "not_found";
  }
  return "?";
}

SearchPlan::SearchPlan(const robot::EnonModel& model, const Intrinsics& camera,
                       const SearchPlanOptions& options)
    : head_(model.head), opt_(options), seen_(kBins, false), tilt_(options.tilt_rad) {
  opt_.check();
  const double hfov = 2 * std::atan2(0.5 * camera.width, camera.fx);
  half_fov_ = 0.5 * hfov;
  camera_ = camera;
  model_ = model;
  half_ = std::max(0.05, 0.5 * hfov - opt_.edge_margin_rad);
  const double lo = head_.pan.min_rad, hi = head_.pan.max_rad;
  const int n = std::max(1, static_cast<int>(std::ceil((hi - lo) / (2 * half_) - 1e-9)) + 1);
  for (int i = 0; i < n; ++i) grid_.push_back(n == 1 ? 0.5 * (lo + hi) : lo + (hi - lo) * i / (n - 1));
}

std::vector<double> SearchPlan::panGrid() const {
  // The order of a sweep that starts at pan 0 with nothing seen.
  SearchPlan copy = *this;
  std::fill(copy.seen_.begin(), copy.seen_.end(), false);
  std::vector<double> order;
  double pan = 0;
  while (copy.nextLook(0.0, pan)) {
    pan = copy.pan_target_;
    order.push_back(pan);
    copy.markSeen(pan);
  }
  return order;
}

bool SearchPlan::seen(double bearing) const { return seen_[static_cast<size_t>(binOf(bearing))]; }

void SearchPlan::markSeen(double bearing) {
  for (int b = 0; b < kBins; ++b)
    if (std::abs(std::remainder(bearingOf(b) - bearing, 2 * M_PI)) <= half_) seen_[static_cast<size_t>(b)] = true;
}

double SearchPlan::gain(double heading, double pan) const {
  int unseen = 0;
  for (int b = 0; b < kBins; ++b)
    if (!seen_[static_cast<size_t>(b)] &&
        std::abs(std::remainder(bearingOf(b) - heading - pan, 2 * M_PI)) <= half_)
      ++unseen;
  return unseen * 2 * M_PI / kBins;
}

double SearchPlan::coverage() const {
  return static_cast<double>(std::count(seen_.begin(), seen_.end(), true)) / kBins;
}

bool SearchPlan::nextLook(double heading, double pan_now) {
  double best = 0, best_dist = 1e9;
  bool any = false;
  for (const double p : grid_) {
    if (gain(heading, p) < kMinGainRad) continue;
    const double d = std::abs(p - pan_now);
    // Nearest first; on a tie the larger pan (left).
    if (!any || d < best_dist - 1e-9 || (std::abs(d - best_dist) <= 1e-9 && p > best)) {
      best = p;
      best_dist = d;
      any = true;
    }
  }
  if (any) pan_target_ = best;
  return any;
}

void SearchPlan::restart(const robot::RobotState& s, bool head_only,
                         const std::optional<Eigen::Vector2d>& hint_w) {
  std::fill(seen_.begin(), seen_.end(), false);
  start_heading_ = planarHeading(s.wMb_odom);
  viewpoint_ = 0;
  head_only_ = head_only;
  unconfirmed_ = false;
  move_dir_ = Eigen::Vector2d::Zero();
  state_ = SearchState::kPointHead;
  tilt_ = head_only ? s.tilt_rad : opt_.tilt_rad;
  end_reason_.clear();
  candidate_w_.reset();
  started_.reset();
  if (belief_ && !head_only) {
    belief_->reset(s.wMb_odom);
    if (hint_w) {
      belief_->candidate(*hint_w, kHintBoost);
      // The view it was lost from did not hold it: that view counts as a look already taken,
      // so the search looks again from a better one (closer, more frontal).
      belief_->miss(s.wMb_odom * robot::headCameraPose(head_, s.pan_rad, s.tilt_rad));
    }
    // Back to a lost target: from the viewpoint the belief picks, not from wherever the base
    // happens to see it again (where it was lost, at a grazing angle, too close).
    on_the_way_ = !hint_w;
    snapshot_ = belief_->snapshot();
    planNext(s);
    return;
  }
  snapshot_.reset();
  if (head_only) {
    pan_target_ = s.pan_rad;
  } else {
    nextLook(start_heading_, s.pan_rad);
  }
}

void SearchPlan::useBelief(const RoomMap& map, const BeliefSearchOptions& options) {
  std::vector<double> line;
  for (int k = 1; k <= opt_.max_viewpoints; ++k) line.push_back(k * opt_.viewpoint_step_m);
  belief_ = std::make_shared<BeliefSearch>(model_, camera_, map, options, line);
}

std::optional<SearchLook> SearchPlan::takeStartedLook() {
  std::optional<SearchLook> l = std::move(started_);
  started_.reset();
  return l;
}

void SearchPlan::planNext(const robot::RobotState& s) {
  if (belief_->done()) {
    state_ = SearchState::kNotFound;
    end_reason_ = "every place seen well enough";
    return;
  }
  planned_ = belief_->next(s.wMb_odom, s.pan_rad, opt_.drive_speed_mps, opt_.turn_speed_radps);
  if (!planned_.ok) {
    state_ = SearchState::kNotFound;
    end_reason_ = "no look can explain the belief left";
    return;
  }
  pan_target_ = planned_.pan_rad;
  tilt_ = planned_.tilt_rad;
  turn_target_ = planned_.heading_rad;
  waypoint_ = 0;
  state_ = planned_.path.empty() ? SearchState::kTurnBase : SearchState::kMoveBase;
}

bool SearchPlan::followPath(const robot::RobotState& s, SearchCommand* c) {
  const Eigen::Vector2d at = s.wMb_odom.t.head<2>();
  const double heading = planarHeading(s.wMb_odom);
  while (waypoint_ < planned_.path.size() && (planned_.path[waypoint_] - at).norm() < 0.05) ++waypoint_;
  if (waypoint_ >= planned_.path.size()) return true;
  const Eigen::Vector2d d = planned_.path[waypoint_] - at;
  const double err = std::remainder(std::atan2(d.y(), d.x()) - heading, 2 * M_PI);
  c->base_w_radps = std::clamp(2.0 * err, -opt_.turn_speed_radps, opt_.turn_speed_radps);
  // Turn in place towards the waypoint first: the path is free only along its straight lines.
  if (std::abs(err) < 0.15) {
    const bool last = waypoint_ + 1 == planned_.path.size();
    const double slow = last ? 2.0 * d.norm() : opt_.drive_speed_mps;
    c->base_v_mps = std::clamp(slow, 0.05, opt_.drive_speed_mps);
  }
  return false;
}

bool SearchPlan::holdOnTheWay(Seconds t, const robot::RobotState& s, TargetStatus observed,
                              const std::optional<Eigen::Vector2d>& candidate_w) {
  if (!on_the_way_) return false;
  if (observed == TargetStatus::kConfirmed) {
    state_ = SearchState::kFound;
    return true;
  }
  if (observed != TargetStatus::kUnconfirmed) return false;
  // A candidate: stop (the head too) and look at it as a look does (until confirmed or
  // confirm_timeout_s).
  pan_target_ = s.pan_rad;
  tilt_ = s.tilt_rad;
  state_ = SearchState::kLook;
  look_started_ = t;
  settle_until_ = t;
  unconfirmed_ = true;
  candidate_w_ = candidate_w;
  ++looks_;
  return true;
}

void SearchPlan::startTurnOrMove(const robot::RobotState& s) {
  if (head_only_) {
    state_ = SearchState::kNotFound;
    return;
  }
  const double heading = planarHeading(s.wMb_odom);
  std::vector<int> unseen;
  for (int b = 0; b < kBins; ++b)
    if (!seen_[static_cast<size_t>(b)]) unseen.push_back(b);
  const bool move_left = viewpoint_ < opt_.max_viewpoints && opt_.viewpoint_step_m > 0;
  if (unseen.size() * 2 * M_PI / kBins < kMinGainRad || (opt_.move_before_turning && move_left)) {
    if (!move_left) {
      state_ = SearchState::kNotFound;
      return;
    }
    // Nothing left to see from here (or a viewpoint comes first): drive to another one, along
    // the start heading.
    ++viewpoint_;
    turn_target_ = start_heading_;
    move_dir_ = Eigen::Vector2d(std::cos(start_heading_), std::sin(start_heading_));
    move_from_ = Eigen::Vector2d::Constant(std::nan(""));
    state_ = SearchState::kTurnBase;
    return;
  }
  // The smallest turn that brings the most unseen directions within the head's reach.
  const double lo = head_.pan.min_rad - half_, hi = head_.pan.max_rad + half_;
  double best_turn = 0;
  size_t best_count = 0;
  for (int k = 0; k <= 360; ++k) {
    const double turn = (k % 2 ? 1 : -1) * ((k + 1) / 2) * M_PI / 180;  // 0, +1, -1, +2 deg ...
    size_t count = 0;
    for (const int b : unseen) {
      const double rel = std::remainder(bearingOf(b) - heading - turn, 2 * M_PI);
      if (rel >= lo && rel <= hi) ++count;
    }
    if (count > best_count) {
      best_count = count;
      best_turn = turn;
      if (count == unseen.size()) break;
    }
  }
  turn_target_ = heading + best_turn;
  move_from_ = Eigen::Vector2d::Zero();
  move_dir_ = Eigen::Vector2d::Zero();
  state_ = SearchState::kTurnBase;
}

SearchCommand SearchPlan::decide(Seconds t, const robot::RobotState& s, TargetStatus observed,
                                 Seconds frame_stamp,
                                 const std::optional<Eigen::Vector2d>& candidate_w, bool weak) {
  SearchCommand c;
  const double heading = planarHeading(s.wMb_odom);
  switch (state_) {
    case SearchState::kPointHead:
      if (std::abs(s.pan_rad - pan_target_) < opt_.head_tolerance_rad &&
          std::abs(s.tilt_rad - tilt_) < opt_.head_tolerance_rad) {
        settle_until_ = t + opt_.settle_s;
        state_ = SearchState::kSettle;
      }
      break;
    case SearchState::kSettle:
      if (t >= settle_until_) {
        state_ = SearchState::kLook;
        look_started_ = t;
        unconfirmed_ = false;
        candidate_w_.reset();
        ++looks_;
        c.new_look = true;
        if (belief_ && !head_only_) {
          SearchLook l;
          l.index = looks_;
          l.start = t;
          const Pose wMc = s.wMb_odom * robot::headCameraPose(head_, s.pan_rad, s.tilt_rad);
          l.camera_w = wMc.t.head<2>();
          l.bearing_rad = heading + s.pan_rad;
          l.half_fov_rad = half_fov_;
          l.range_m = planned_.range_m;
          l.expected_gain = planned_.gain;
          started_ = l;
        }
      }
      break;
    case SearchState::kLook: {
      const bool fresh = observed != TargetStatus::kNone && frame_stamp >= settle_until_;
      if (fresh && observed == TargetStatus::kConfirmed) {
        state_ = SearchState::kFound;
        break;
      }
      // A candidate holds the look (frames that miss it included) until it is confirmed or
      // confirm_timeout_s has passed; the look ends on a frame without it, or on a period
      // without a frame once out of time: never in a period whose frame shows a candidate.
      if (fresh && observed == TargetStatus::kUnconfirmed) {
        unconfirmed_ = true;
        if (candidate_w) candidate_w_ = candidate_w;
        break;
      }
      // Weak evidence (a candidate refused by a check) keeps the look on more frames, as long
      // as a candidate would be held.
      if (fresh && weak && belief_ && !head_only_ && t - look_started_ <= opt_.confirm_timeout_s) break;
      const bool in_time = t - look_started_ <= opt_.confirm_timeout_s;
      if (fresh ? unconfirmed_ && in_time : !unconfirmed_ || in_time) break;
      if (belief_ && !head_only_) {
        on_the_way_ = true;
        belief_->miss(s.wMb_odom * robot::headCameraPose(head_, s.pan_rad, s.tilt_rad));
        if (candidate_w_) belief_->candidate(*candidate_w_);
        snapshot_ = belief_->snapshot();
        planNext(s);
        break;
      }
      markSeen(heading + pan_target_);
      if (nextLook(heading, pan_target_)) {
        state_ = SearchState::kPointHead;
      } else {
        startTurnOrMove(s);
      }
      break;
    }
    case SearchState::kTurnBase: {
      if (belief_ && !head_only_ && holdOnTheWay(t, s, observed, candidate_w)) break;
      const double err = std::remainder(turn_target_ - heading, 2 * M_PI);
      if (std::abs(err) > opt_.heading_tolerance_rad) {
        c.base_w_radps = std::clamp(2.0 * err, -opt_.turn_speed_radps, opt_.turn_speed_radps);
        break;
      }
      if (belief_ && !head_only_) {
        state_ = SearchState::kPointHead;
        break;
      }
      if (move_dir_.squaredNorm() > 0) {  // a viewpoint move follows
        move_from_ = s.wMb_odom.t.head<2>();
        state_ = SearchState::kMoveBase;
        break;
      }
      if (nextLook(heading, s.pan_rad)) {
        state_ = SearchState::kPointHead;
      } else {
        startTurnOrMove(s);
      }
      break;
    }
    case SearchState::kMoveBase: {
      if (belief_ && !head_only_) {
        if (holdOnTheWay(t, s, observed, candidate_w)) break;
        if (followPath(s, &c)) state_ = SearchState::kTurnBase;
        break;
      }
      const double done = (s.wMb_odom.t.head<2>() - move_from_).dot(move_dir_);
      const double left = opt_.viewpoint_step_m - done;
      if (left > 0.01) {
        c.base_v_mps = std::clamp(2.0 * left, 0.05, opt_.drive_speed_mps);
        // Hold the heading while driving.
        c.base_w_radps = std::clamp(2.0 * std::remainder(turn_target_ - heading, 2 * M_PI),
                                    -opt_.turn_speed_radps, opt_.turn_speed_radps);
        break;
      }
      std::fill(seen_.begin(), seen_.end(), false);
      move_dir_ = Eigen::Vector2d::Zero();
      nextLook(heading, s.pan_rad);
      state_ = SearchState::kPointHead;
      break;
    }
    case SearchState::kFound:
    case SearchState::kNotFound:
      break;
  }
  c.state = state_;
  c.pan_rad = pan_target_;
  c.tilt_rad = tilt_;
  c.look = state_ == SearchState::kLook;
  c.look_after = settle_until_;
  if (belief_ && !head_only_ && on_the_way_ &&
      (state_ == SearchState::kMoveBase || state_ == SearchState::kTurnBase)) {
    // On the way, frames are looked at too: a target seen while driving stops the base.
    c.look = true;
    c.look_after = t;
  }
  if (state_ == SearchState::kFound || state_ == SearchState::kNotFound) {
    c.base_v_mps = c.base_w_radps = 0;
    c.pan_rad = s.pan_rad;
    c.tilt_rad = s.tilt_rad;
  }
  return c;
}

}  // namespace refgrasp::servo
