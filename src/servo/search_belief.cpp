#include "servo/search_belief.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>

#include "core/error.h"
#include "robot/kinematics.h"

namespace refgrasp::servo {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kBearings = 24;       // bearings tried per viewpoint (15 deg apart)
constexpr int kTilts = 3;           // tilts tried, evenly over [tilt_min, tilt_max]
constexpr double kSampleM = 0.05;   // segment and ray sampling step
constexpr double kTargetClearM = 0.15;  // the last part of a ray (the target's own surface) never occludes
constexpr int kFacings = BeliefSearch::kFacings;
/// Prior weight of facing direction `dir` for objects on furniture whose room side faces `room`
/// (zero: any facing): the way into the room most, sideways little, towards the wall never.
double facingPrior(const Eigen::Vector2d& dir, const Eigen::Vector2d& room) {
  if (room.isZero()) return 1;
  const double c = dir.dot(room);
  return c < -1e-9 ? 0 : c + 0.05;
}
Eigen::Vector2d facingDir(int k) {
  const double a = 2 * M_PI * k / kFacings;
  return {std::cos(a), std::sin(a)};
}

bool finiteIn(double x, double lo, double hi) { return std::isfinite(x) && x >= lo && x <= hi; }

Pose planar(const Eigen::Vector2d& xy, double heading) {
  return robot::PlanarPose{xy.x(), xy.y(), heading}.toPose();
}

double headingOf(const Pose& wMb) { return std::atan2(wMb.R(1, 0), wMb.R(0, 0)); }

}  // namespace

void BeliefSearchOptions::check() const {
  using refgrasp::check;
  const std::string w = "BeliefSearchOptions.";
  check(finiteIn(cell_m, 0.02, 2), w + "cell_m", "must be in [0.02, 2]");
  check(finiteIn(min_range_m, 0, 50) && finiteIn(unknown_range_m, min_range_m + cell_m, 50),
        w + "unknown_range_m", "must be in (min_range_m + cell_m, 50]");
  check(finiteIn(unknown_height_m, 0, 3), w + "unknown_height_m", "must be in [0, 3]");
  check(finiteIn(target_size_m, 1e-3, 5), w + "target_size_m", "must be in (0, 5]");
  check(finiteIn(target_above_m, 0, 2), w + "target_above_m", "must be in [0, 2]");
  check(finiteIn(detect_half_px, 0, 1e4), w + "detect_half_px", "must be in [0, 1e4]");
  check(finiteIn(detect_slope_px, 1e-3, 1e4), w + "detect_slope_px", "must be > 0");
  check(finiteIn(detect_max, 1e-3, 1), w + "detect_max", "must be in (0, 1]");
  check(finiteIn(image_margin_px, 0, 1000), w + "image_margin_px", "must be in [0, 1000]");
  check(finiteIn(max_look_px, 1, 1e4), w + "max_look_px", "must be in [1, 1e4]");
  check(finiteIn(max_view_range_m, 0.1, 100), w + "max_view_range_m", "must be in [0.1, 100]");
  check(finiteIn(viewpoint_spacing_m, 0.1, 5), w + "viewpoint_spacing_m", "must be in [0.1, 5]");
  check(finiteIn(clearance_m, 0, 2), w + "clearance_m", "must be in [0, 2]");
  check(finiteIn(candidate_boost, 1, 1e3), w + "candidate_boost", "must be in [1, 1000]");
  check(finiteIn(candidate_radius_m, 0, 5), w + "candidate_radius_m", "must be in [0, 5]");
  check(finiteIn(pan_margin_rad, 0, 1.5), w + "pan_margin_rad", "must be in [0, 1.5]");
  check(finiteIn(against_wall_m, 0, 100), w + "against_wall_m", "must be in [0, 100]");
  check(finiteIn(facing_full_rad, 0, M_PI) && finiteIn(facing_none_rad, facing_full_rad + 1e-3, M_PI),
        w + "facing_none_rad", "must satisfy 0 <= facing_full_rad < facing_none_rad <= pi");
  check(finiteIn(repeat_discount, 0, 1), w + "repeat_discount", "must be in [0, 1]");
  check(finiteIn(stop_mass, 0, 1), w + "stop_mass", "must be in [0, 1]");
  check(finiteIn(look_time_s, 0.01, 60), w + "look_time_s", "must be in [0.01, 60]");
  check(finiteIn(pan_speed_radps, 1e-3, 100), w + "pan_speed_radps", "must be > 0");
  check(finiteIn(tilt_min_rad, -1.5, 1.5) && finiteIn(tilt_max_rad, tilt_min_rad, 1.5),
        w + "tilt_max_rad", "tilts must satisfy -1.5 <= tilt_min_rad <= tilt_max_rad <= 1.5");
}

BeliefSearch::BeliefSearch(const robot::EnonModel& model, const Intrinsics& camera,
                           const RoomMap& map, const BeliefSearchOptions& options,
                           std::vector<double> line_viewpoints)
    : model_(model), camera_(camera), map_(map), opt_(options),
      line_viewpoints_(std::move(line_viewpoints)) {
  opt_.check();
  camera_.check();
  camera_height_m_ = robot::headCameraPose(model_.head, 0, 0).t.z();
  body_radius_m_ = model_.base.body_radius_m;
}

bool BeliefSearch::free(const Eigen::Vector2d& xy) const {
  const double r = body_radius_m_ + opt_.clearance_m;
  if (!map_.inside.half_m.isZero() && !map_.inside.contains(xy, -r)) return false;
  for (const RoomFixture& f : map_.fixtures)
    if (f.footprint.contains(xy, r)) return false;
  return true;
}

bool BeliefSearch::freeSegment(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const {
  const double len = (b - a).norm();
  const int n = std::max(1, static_cast<int>(std::ceil(len / kSampleM)));
  // A base that starts where it should not (next to a table after a grasp attempt) may leave.
  bool leaving = !free(a);
  for (int k = 1; k <= n; ++k) {
    const bool ok = free(a + (b - a) * (static_cast<double>(k) / n));
    if (leaving && ok) leaving = false;
    if (!leaving && !ok) return false;
  }
  return !leaving;
}

bool BeliefSearch::occluded(const Eigen::Vector3d& from, const Eigen::Vector3d& to) const {
  const Eigen::Vector3d d = to - from;
  const double len = d.norm();
  if (len <= kTargetClearM) return false;
  const int n = static_cast<int>((len - kTargetClearM) / kSampleM);
  for (int k = 1; k <= n; ++k) {
    const Eigen::Vector3d p = from + d * (k * kSampleM / len);
    const Eigen::Vector2d xy = p.head<2>();
    if (!map_.inside.half_m.isZero() && !map_.inside.contains(xy)) return true;
    for (const RoomFixture& f : map_.fixtures)
      if (p.z() < f.height_m && f.footprint.contains(xy)) return true;
  }
  return false;
}

void BeliefSearch::reset(const Pose& wMb) {
  const Eigen::Vector2d start = wMb.t.head<2>();
  // Grid bounds: the room (or the fixtures' and the start's bounding box grown by 1 m); without
  // a map, the square around the start that holds unknown_range_m.
  Eigen::Vector2d lo, hi;
  if (map_.empty()) {
    lo = start.array() - opt_.unknown_range_m;
    hi = start.array() + opt_.unknown_range_m;
  } else {
    lo = hi = start;
    auto grow = [&](const Footprint& f) {
      const double r = f.half_m.norm();
      lo = lo.cwiseMin(f.centre - Eigen::Vector2d::Constant(r));
      hi = hi.cwiseMax(f.centre + Eigen::Vector2d::Constant(r));
    };
    for (const RoomFixture& f : map_.fixtures) grow(f.footprint);
    if (!map_.inside.half_m.isZero()) grow(map_.inside);
  }
  grid_ = SearchBelief();
  grid_.cell_m = opt_.cell_m;
  grid_.origin = lo;
  grid_.cols = std::max(1, static_cast<int>(std::ceil((hi.x() - lo.x()) / opt_.cell_m)));
  grid_.rows = std::max(1, static_cast<int>(std::ceil((hi.y() - lo.y()) / opt_.cell_m)));
  grid_.height_m.assign(static_cast<size_t>(grid_.cols * grid_.rows), 0.f);
  cell_index_.clear();
  prior_.clear();
  const bool surfaces = std::any_of(map_.fixtures.begin(), map_.fixtures.end(),
                                    [](const RoomFixture& f) { return f.surface; });
  for (int r = 0; r < grid_.rows; ++r)
    for (int c = 0; c < grid_.cols; ++c) {
      const Eigen::Vector2d x = grid_.centre(c, r);
      double h = -1;
      Eigen::Vector2d facing = Eigen::Vector2d::Zero();
      if (surfaces) {
        for (const RoomFixture& f : map_.fixtures)
          if (f.surface && f.footprint.contains(x, -0.25 * opt_.cell_m) && f.height_m > h) {
            h = f.height_m;
            facing = roomFacing(f.footprint);
          }
      } else {
        const double d = (x - start).norm();
        if (d >= opt_.min_range_m && d <= opt_.unknown_range_m &&
            (map_.inside.half_m.isZero() || map_.inside.contains(x, -opt_.cell_m)))
          h = opt_.unknown_height_m;
      }
      if (h < 0) continue;
      grid_.height_m[static_cast<size_t>(r * grid_.cols + c)] = static_cast<float>(h);
      cell_index_.push_back(r * grid_.cols + c);
      // Each cell holds the same prior, spread over its facings by facingPrior.
      double w[kFacings], sum = 0;
      for (int k = 0; k < kFacings; ++k) sum += w[k] = facingPrior(facingDir(k), facing);
      for (int k = 0; k < kFacings; ++k) prior_.push_back(w[k] / sum);
    }
  for (double& p : prior_) p /= static_cast<double>(cell_index_.size());
  mass_ = prior_;
  best_pd_.assign(prior_.size(), 0);
  prior_total_ = cell_index_.empty() ? 0 : 1;
  buildViewpoints(wMb);
}

void BeliefSearch::buildViewpoints(const Pose& wMb) {
  viewpoints_.clear();
  links_.clear();
  const Eigen::Vector2d start = wMb.t.head<2>();
  if (map_.empty()) {
    const double h = headingOf(wMb);
    for (const double d : line_viewpoints_)
      viewpoints_.push_back(start + d * Eigen::Vector2d(std::cos(h), std::sin(h)));
    return;
  }
  // A grid through the start, over the grid's bounds, on the free floor.
  const double s = opt_.viewpoint_spacing_m;
  const Eigen::Vector2d lo = grid_.origin;
  const Eigen::Vector2d hi = lo + Eigen::Vector2d(grid_.cols, grid_.rows) * grid_.cell_m;
  const int i0 = static_cast<int>(std::floor((lo.x() - start.x()) / s));
  const int i1 = static_cast<int>(std::ceil((hi.x() - start.x()) / s));
  const int j0 = static_cast<int>(std::floor((lo.y() - start.y()) / s));
  const int j1 = static_cast<int>(std::ceil((hi.y() - start.y()) / s));
  for (int i = i0; i <= i1; ++i)
    for (int j = j0; j <= j1; ++j) {
      const Eigen::Vector2d p = start + s * Eigen::Vector2d(i, j);
      if (free(p)) viewpoints_.push_back(p);
    }
  // Grid neighbours (8-connected) joined by a free straight line.
  links_.assign(viewpoints_.size(), {});
  for (size_t u = 0; u < viewpoints_.size(); ++u)
    for (size_t v = u + 1; v < viewpoints_.size(); ++v) {
      const double e = (viewpoints_[v] - viewpoints_[u]).norm();
      if (e > 1.5 * s || !freeSegment(viewpoints_[u], viewpoints_[v])) continue;
      links_[u].push_back({static_cast<int>(v), e});
      links_[v].push_back({static_cast<int>(u), e});
    }
}

Eigen::Vector2d BeliefSearch::roomFacing(const Footprint& f) const {
  if (map_.inside.half_m.isZero()) return Eigen::Vector2d::Zero();
  // The footprint's four side normals; the wall nearest to the side it stands against.
  const double c = std::cos(f.yaw_rad), s = std::sin(f.yaw_rad);
  const Eigen::Vector2d ax(c, s), ay(-s, c);
  const Footprint& in = map_.inside;
  const double ci = std::cos(in.yaw_rad), si = std::sin(in.yaw_rad);
  const Eigen::Vector2d ix(ci, si), iy(-si, ci);
  double nearest = 1e9;
  Eigen::Vector2d away = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& n : {ax, Eigen::Vector2d(-ax), ay, Eigen::Vector2d(-ay)}) {
    const double half = std::abs(n.dot(ax)) * f.half_m.x() + std::abs(n.dot(ay)) * f.half_m.y();
    const Eigen::Vector2d side = f.centre + half * n;  // middle of that side
    const Eigen::Vector2d d = side - in.centre;
    // Distance from that side to the wall it faces (the inside's boundary along n).
    const double reach = std::abs(n.dot(ix)) > std::abs(n.dot(iy))
                             ? in.half_m.x() - std::copysign(1.0, n.dot(ix)) * d.dot(ix)
                             : in.half_m.y() - std::copysign(1.0, n.dot(iy)) * d.dot(iy);
    if (reach < nearest) {
      nearest = reach;
      away = -n;
    }
  }
  return nearest <= opt_.against_wall_m ? away : Eigen::Vector2d::Zero();
}

double BeliefSearch::facingFactor(int facing, const Eigen::Vector2d& to_camera) const {
  if (to_camera.squaredNorm() < 1e-12) return 1;
  const double cosa = facingDir(facing).dot(to_camera.normalized());
  const double lo = std::cos(opt_.facing_none_rad), hi = std::cos(opt_.facing_full_rad);
  return std::clamp((cosa - lo) / (hi - lo), 0.0, 1.0);
}

Eigen::Vector3d BeliefSearch::targetAt(int cell) const {
  const int g = cell_index_[static_cast<size_t>(cell)];
  const Eigen::Vector2d xy = grid_.centre(g % grid_.cols, g / grid_.cols);
  return {xy.x(), xy.y(), grid_.height_m[static_cast<size_t>(g)] + opt_.target_above_m};
}

double BeliefSearch::unoccludedPd(const Pose& cMw, int cell, double* depth) const {
  const Eigen::Vector3d P = targetAt(cell);
  const Eigen::Vector3d X = cMw * P;
  if (X.z() < 0.2 || X.norm() > opt_.max_view_range_m) return 0;
  const double u = camera_.fx * X.x() / X.z() + camera_.cx, v = camera_.fy * X.y() / X.z() + camera_.cy;
  const double m = opt_.image_margin_px;
  if (u < m || v < m || u > camera_.width - m || v > camera_.height - m) return 0;
  if (depth) *depth = X.z();
  const double w = camera_.fx * opt_.target_size_m / X.z();
  if (w > opt_.max_look_px) return 0;
  return opt_.detect_max / (1 + std::exp(-(w - opt_.detect_half_px) / opt_.detect_slope_px));
}

double BeliefSearch::sizePd(const Pose& wMc, int cell) const {
  const double pd = unoccludedPd(wMc.inverse(), cell);
  return pd > 0 && occluded(wMc.t, targetAt(cell)) ? 0 : pd;
}

double BeliefSearch::detectProbability(const Pose& wMc, int cell) const {
  const double pd = sizePd(wMc, cell);
  if (pd <= 0) return 0;
  const Eigen::Vector2d to_camera = wMc.t.head<2>() - targetAt(cell).head<2>();
  double seen = 0, all = 0;
  for (int k = 0; k < kFacings; ++k) {
    const double p = prior_[static_cast<size_t>(cell * kFacings + k)];
    seen += p * facingFactor(k, to_camera);
    all += p;
  }
  return pd * seen / all;
}

double BeliefSearch::novelPd(size_t state, double pd) const {
  return std::max(0.0, pd - opt_.repeat_discount * best_pd_[state]);
}

void BeliefSearch::miss(const Pose& wMc) {
  for (int i = 0; i < cells(); ++i) {
    const double pd = sizePd(wMc, i);
    if (pd <= 0) continue;
    const Eigen::Vector2d to_camera = wMc.t.head<2>() - targetAt(i).head<2>();
    for (int k = 0; k < kFacings; ++k) {
      const size_t j = static_cast<size_t>(i * kFacings + k);
      const double p = pd * facingFactor(k, to_camera);
      const double novel = novelPd(j, p);
      mass_[j] *= 1 - novel;
      // What the looks so far would have found together: a view repeated adds its novel part
      // only, so repeats stop adding once they reach pd / repeat_discount.
      best_pd_[j] = std::max(p, 1 - (1 - best_pd_[j]) * (1 - novel));
    }
  }
}

void BeliefSearch::candidate(const Eigen::Vector2d& xy, double boost) {
  const double k = boost > 0 ? boost : opt_.candidate_boost;
  for (int i = 0; i < cells(); ++i) {
    if ((targetAt(i).head<2>() - xy).norm() > opt_.candidate_radius_m) continue;
    for (int f = 0; f < kFacings; ++f) {
      const size_t j = static_cast<size_t>(i * kFacings + f);
      mass_[j] *= k;
      best_pd_[j] = 0;  // a candidate there is news: earlier misses do not discount the next look
    }
  }
}

double BeliefSearch::unexplained() const {
  if (prior_total_ <= 0) return 0;
  double s = 0;
  for (const double m : mass_) s += m;
  return s / prior_total_;
}

std::shared_ptr<const SearchBelief> BeliefSearch::snapshot() const {
  auto b = std::make_shared<SearchBelief>(grid_);
  b->p.assign(static_cast<size_t>(grid_.cols * grid_.rows), 0.f);
  double s = 0;
  for (const double m : mass_) s += m;
  if (s > 0)
    for (size_t j = 0; j < mass_.size(); ++j)
      b->p[static_cast<size_t>(cell_index_[j / kFacings])] += static_cast<float>(mass_[j] / s);
  return b;
}

void BeliefSearch::distances(const Eigen::Vector2d& from, std::vector<double>* dist,
                             std::vector<int>* prev) const {
  const size_t n = viewpoints_.size();
  dist->assign(n, kInf);
  prev->assign(n, -1);
  if (map_.empty()) {  // the start heading's line: driven as today, no fixtures known
    for (size_t v = 0; v < n; ++v) (*dist)[v] = (viewpoints_[v] - from).norm();
    return;
  }
  const double reach = 1.5 * opt_.viewpoint_spacing_m;
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> open;
  for (size_t v = 0; v < n; ++v) {
    const double d = (viewpoints_[v] - from).norm();
    if (d <= reach && freeSegment(from, viewpoints_[v])) {
      (*dist)[v] = d;
      open.push({d, static_cast<int>(v)});
    }
  }
  while (!open.empty()) {
    const auto [d, u] = open.top();
    open.pop();
    if (d > (*dist)[static_cast<size_t>(u)]) continue;
    for (const auto& [v, e] : links_[static_cast<size_t>(u)]) {
      if (d + e >= (*dist)[static_cast<size_t>(v)]) continue;
      (*dist)[static_cast<size_t>(v)] = d + e;
      (*prev)[static_cast<size_t>(v)] = u;
      open.push({d + e, v});
    }
  }
}

std::vector<Eigen::Vector2d> BeliefSearch::pathTo(const Eigen::Vector2d& from, int v) const {
  std::vector<double> dist;
  std::vector<int> prev;
  distances(from, &dist, &prev);
  if (v < 0 || static_cast<size_t>(v) >= viewpoints_.size() || !std::isfinite(dist[static_cast<size_t>(v)]))
    return {};
  std::vector<Eigen::Vector2d> chain;
  for (int u = v; u >= 0; u = prev[static_cast<size_t>(u)]) chain.push_back(viewpoints_[static_cast<size_t>(u)]);
  std::reverse(chain.begin(), chain.end());
  if (map_.empty()) return chain;
  // Shortcut: from each point, straight to the furthest later point the line reaches freely.
  std::vector<Eigen::Vector2d> path;
  Eigen::Vector2d at = from;
  size_t i = 0;
  while (i < chain.size()) {
    size_t j = chain.size() - 1;
    while (j > i && !freeSegment(at, chain[j])) --j;
    path.push_back(chain[j]);
    at = chain[j];
    i = j + 1;
  }
  return path;
}

PlannedLook BeliefSearch::next(const Pose& wMb, double pan_now, double drive_speed_mps,
                               double turn_speed_radps) const {
  PlannedLook best;
  double total = 0;
  for (const double m : mass_) total += m;
  if (total <= 0) return best;
  const Eigen::Vector2d from = wMb.t.head<2>();
  const double heading_now = headingOf(wMb);
  std::vector<double> dist;
  std::vector<int> prev;
  distances(from, &dist, &prev);
  // Where the search may look from: here (index -1) and every reachable viewpoint.
  std::vector<int> stands = {-1};
  for (size_t v = 0; v < viewpoints_.size(); ++v)
    if (std::isfinite(dist[v]) && (viewpoints_[v] - from).norm() > 0.5 * opt_.viewpoint_spacing_m)
      stands.push_back(static_cast<int>(v));
  const robot::JointLimits& pan = model_.head.pan;
  double best_utility = 0;
  int best_stand = -1;
  for (const int v : stands) {
    const Eigen::Vector2d at = v < 0 ? from : viewpoints_[static_cast<size_t>(v)];
    double arrive = heading_now, travel_s = 0;
    if (v >= 0) {
      const int p = prev[static_cast<size_t>(v)];
      const Eigen::Vector2d before = p < 0 ? from : viewpoints_[static_cast<size_t>(p)];
      const Eigen::Vector2d first = (p < 0 ? at : viewpoints_[static_cast<size_t>(p)]) - from;
      arrive = std::atan2(at.y() - before.y(), at.x() - before.x());
      travel_s = dist[static_cast<size_t>(v)] / drive_speed_mps +
                 (std::abs(std::remainder(std::atan2(first.y(), first.x()) - heading_now, 2 * M_PI)) +
                  std::abs(std::remainder(arrive - std::atan2(first.y(), first.x()), 2 * M_PI))) /
                     turn_speed_radps;
    }
    // Cells this stand can see at all (fixtures, walls), from the camera's height.
    const Eigen::Vector3d eye(at.x(), at.y(), camera_height_m_);
    std::vector<int> visible;
    for (int i = 0; i < cells(); ++i) {
      double m = 0;
      for (int k = 0; k < kFacings; ++k) m += mass_[static_cast<size_t>(i * kFacings + k)];
      if (m <= 0) continue;
      const Eigen::Vector3d P = targetAt(i);
      if ((P.head<2>() - at).norm() > opt_.max_view_range_m) continue;
      if (!occluded(eye, P)) visible.push_back(i);
    }
    if (visible.empty()) continue;
    for (int b = 0; b < kBearings; ++b) {
      const double bearing = -M_PI + 2 * M_PI * b / kBearings;
      const double rel = std::remainder(bearing - arrive, 2 * M_PI);
      const double pan_rad = std::clamp(rel, pan.min_rad + opt_.pan_margin_rad, pan.max_rad - opt_.pan_margin_rad);
      const double heading = bearing - pan_rad;
      const double turn_s = std::abs(std::remainder(heading - arrive, 2 * M_PI)) / turn_speed_radps;
      const double pan_s = std::max(0.0, std::abs(pan_rad - pan_now) / opt_.pan_speed_radps - travel_s);
      const double cost = travel_s + turn_s + pan_s + opt_.look_time_s;
      for (int k = 0; k < kTilts; ++k) {
        const double tilt = opt_.tilt_min_rad + (opt_.tilt_max_rad - opt_.tilt_min_rad) * k / (kTilts - 1);
        const Pose wMc = planar(at, heading) * robot::headCameraPose(model_.head, pan_rad, tilt);
        const Pose cMw = wMc.inverse();
        double gain = 0, range = 0;
        for (const int i : visible) {  // occlusion from the stand's eye, computed once above
          double depth = 0;
          const double pd = unoccludedPd(cMw, i, &depth);
          if (pd <= 0) continue;
          const Eigen::Vector2d to_camera = wMc.t.head<2>() - targetAt(i).head<2>();
          for (int k = 0; k < kFacings; ++k) {
            const size_t j = static_cast<size_t>(i * kFacings + k);
            if (mass_[j] <= 0) continue;
            const double g = mass_[j] * novelPd(j, pd * facingFactor(k, to_camera));
            gain += g;
            range += g * depth;
          }
        }
        gain /= total;
        const double utility = gain / cost;
        if (gain > 1e-6 && utility > best_utility) {
          best_utility = utility;
          best_stand = v;
          best.ok = true;
          best.heading_rad = heading;
          best.pan_rad = pan_rad;
          best.tilt_rad = tilt;
          best.gain = gain;
          best.cost_s = cost;
          best.range_m = range / (gain * total);
        }
      }
    }
  }
  if (best.ok && best_stand >= 0) best.path = pathTo(from, best_stand);
  return best;
}

}  // namespace refgrasp::servo
