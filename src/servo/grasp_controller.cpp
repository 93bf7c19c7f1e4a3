#include "servo/grasp_controller.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/error.h"

namespace refgrasp::servo {

using robot::ReturnType;

namespace {

bool weakEvidence(const TargetObservation& o) {
  // A consensus the matcher accepted that a later check refused, or an instance the pipeline
  // did not confirm: something like the target is there.
  return o.status == TargetStatus::kLost && o.detector_stats && o.detector_stats->candidates > 0;
}


bool finiteIn(double x, double lo, double hi) { return std::isfinite(x) && x >= lo && x <= hi; }

Pose along(double z_m) { return Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, 0, z_m)); }

std::string at(const char* what, Seconds t) {
  char buf[96];
  std::snprintf(buf, sizeof(buf), "%s at t=%.2f s", what, t);
  return buf;
}

}  // namespace

void GraspOptions::check() const {
  using refgrasp::check;
  search.check();
  belief.check();
  head.check();
  base.check();
  arm.check();
  const std::string o = "GraspOptions.";
  check(finiteIn(pregrasp_distance_m, 0.01, 1), o + "pregrasp_distance_m", "must be in [0.01, 1]");
  check(finiteIn(pregrasp_clearance_m, 0, 1), o + "pregrasp_clearance_m", "must be in [0, 1]");
  check(finiteIn(fixture_clearance_m, 0, 1), o + "fixture_clearance_m", "must be in [0, 1]");
  check(finiteIn(approach_arm_tolerance_rad, 1e-4, 1), o + "approach_arm_tolerance_rad",
        "must be in (0, 1]");
  check(finiteIn(arm_ready_distance_m, 0, 10), o + "arm_ready_distance_m", "must be in [0, 10]");
  check(finiteIn(arm_ready_tolerance_rad, 1e-4, 3.2), o + "arm_ready_tolerance_rad", "must be in [1e-4, 3.2]");
  check(finiteIn(arm_ready_speed_fraction, 0.01, 1), o + "arm_ready_speed_fraction",
        "must be in (0, 1]");
  check(finiteIn(align_position_tolerance_m, 1e-5, 0.1), o + "align_position_tolerance_m",
        "must be in (0, 0.1]");
  check(finiteIn(align_rotation_tolerance_rad, 1e-5, 0.5), o + "align_rotation_tolerance_rad",
        "must be in (0, 0.5]");
  check(finiteIn(grasp_speed_mps, 1e-3, 1), o + "grasp_speed_mps", "must be in (0, 1]");
  check(finiteIn(grasp_position_tolerance_m, 1e-5, 0.1), o + "grasp_position_tolerance_m",
        "must be in (0, 0.1]");
  check(finiteIn(grasp_rotation_tolerance_rad, 1e-5, 0.5), o + "grasp_rotation_tolerance_rad",
        "must be in (0, 0.5]");
  check(finiteIn(lift_m, 0, 0.5), o + "lift_m", "must be in [0, 0.5]");
  check(finiteIn(lift_speed_mps, 1e-3, 1), o + "lift_speed_mps", "must be in (0, 1]");
  check(finiteIn(hold_check_s, 0, 10), o + "hold_check_s", "must be in [0, 10]");
  check(finiteIn(frame_period_s, 0, 10), o + "frame_period_s", "must be in [0, 10]");
  check(finiteIn(estimate_smoothing, 0, 0.99), o + "estimate_smoothing", "must be in [0, 0.99]");
  check(finiteIn(max_estimate_age_s, 1e-3, 10), o + "max_estimate_age_s", "must be in (0, 10]");
  check(finiteIn(reacquire_timeout_s, 0, 60), o + "reacquire_timeout_s", "must be in [0, 60]");
  check(max_searches >= 1 && max_searches <= 100, o + "max_searches", "must be in [1, 100]");
  check(finiteIn(unreachable_patience_s, 0, 60), o + "unreachable_patience_s", "must be in [0, 60]");
  check(finiteIn(reestimate_stop_m, 0.3, 20) && finiteIn(reestimate_range_m, reestimate_stop_m + 0.1, 20),
        o + "reestimate_range_m", "must be in [reestimate_stop_m + 0.1, 20], reestimate_stop_m in [0.3, 20]");
  for (const auto& [name, v] : {std::pair<const char*, double>{"search_timeout_s", search_timeout_s},
                                {"approach_timeout_s", approach_timeout_s},
                                {"align_timeout_s", align_timeout_s},
                                {"grasp_timeout_s", grasp_timeout_s}})
    check(finiteIn(v, 0.1, 3600), o + name, "must be in [0.1, 3600]");
}

const char* toString(GraspPhase p) {
  switch (p) {
    case GraspPhase::kSearch: return "search";
    case GraspPhase::kApproach: return "approach";
    case GraspPhase::kAlign: return "align";
    case GraspPhase::kGrasp: return "grasp";
    case GraspPhase::kDone: return "done";
    case GraspPhase::kFailed: return "failed";
  }
  return "?";
}

const char* toString(GraspSubStep s) {
  switch (s) {
    case GraspSubStep::kReach: return "reach";
    case GraspSubStep::kClose: return "close";
    case GraspSubStep::kLift: return "lift";
    case GraspSubStep::kHold: return "hold";
  }
  return "?";
}

GraspController::GraspController(robot::Robot& robot, TargetEstimator& estimator, const Pose& oMg,
                                 const ObjectExtent& object_o, const GraspOptions& options)
    : robot_(robot),
      est_(estimator),
      oMg_(oMg),
      centre_o_(object_o.centre()),
      opt_(options),
      plan_(robot.model(), robot.camera().rig().left, options.search),
      head_task_(robot.model().head, options.head),
      base_task_(options.base),
      arm_task_(robot.model().arm, options.arm) {
  opt_.check();
  if (!oMg.isFinite() || !object_o.min_o.allFinite() || !object_o.max_o.allFinite())
    throw std::invalid_argument("GraspController: oMg and the object's extent must be finite");
  pregrasp_m_ = std::max(opt_.pregrasp_distance_m, object_o.depthBehind(oMg) + opt_.pregrasp_clearance_m);
  if (opt_.belief_search) plan_.useBelief(opt_.room, opt_.belief);
}

GraspController::~GraspController() = default;

Pose GraspController::wMb() const { return robot_.state().wMb_odom; }

bool GraspController::baseMayAdvance(const Pose& wMb_now, double v_mps, std::string* blocker) const {
  if (!(v_mps > 0)) return true;
  const Eigen::Vector2d p = wMb_now.t.head<2>();
  const Eigen::Vector2d ahead = p + v_mps * robot_.model().control_period_s * wMb_now.R.col(0).head<2>().normalized();
  const double r = robot_.model().base.body_radius_m + opt_.fixture_clearance_m;
  for (const RoomFixture& f : opt_.room.fixtures) {
    const double d_ahead = f.footprint.distance(ahead);
    // Only motion that brings the body closer is held: a base already too near may back off.
    if (d_ahead < r && d_ahead < f.footprint.distance(p)) {
      if (blocker) *blocker = f.name;
      return false;
    }
  }
  return true;
}

Pose GraspController::clearOfFixtures(const Pose& wMb_goal) const {
  Pose out = wMb_goal;
  const Eigen::Vector2d back = -wMb_goal.R.col(0).head<2>().normalized();
  const double r = robot_.model().base.body_radius_m + opt_.fixture_clearance_m;
  for (int pass = 0; pass < 4; ++pass) {  // a goal between two fixtures settles in a few
    double deficit = 0;
    for (const RoomFixture& f : opt_.room.fixtures)
      deficit = std::max(deficit, r - f.footprint.distance(out.t.head<2>()));
    if (!(deficit > 0)) break;
    out.t.head<2>() += (deficit + 1e-3) * back;
  }
  return out;
}

bool GraspController::armBaseMayAdvance(const Pose& wMb_now, GraspIteration* it) {
  BaseCommand probe;
  probe.v_mps = opt_.arm.max_base_v_mps;  // the fastest the arm task drives the base
  guardBase(wMb_now, &probe, it);
  return probe.v_mps > 0;
}

void GraspController::guardBase(const Pose& wMb_now, BaseCommand* b, GraspIteration* it) {
  std::string blocker;
  if (baseMayAdvance(wMb_now, b->v_mps, &blocker)) return;
  b->v_mps = 0;
  if (blocker != guard_note_) {
    guard_note_ = blocker;
    char note[160];
    std::snprintf(note, sizeof note, "base held: its body would come within %.3f m of %s", opt_.fixture_clearance_m,
                  blocker.c_str());
    it->event = note;
  }
}

std::string GraspController::why() const {
  const std::string e = robot_.hardware().lastError();
  return e.empty() ? "" : ": " + e;
}

GraspStep GraspController::fail(GraspStep s, const std::string& error) {
  robot_.stop();
  error_ = error;
  if (!finished()) {
    report_.phases[toString(phase_)].time_s += std::max(0.0, last_t_ - phase_start_);
    report_.phases[toString(phase_)].outcome = "error";
    report_.failure = error;
    phase_ = GraspPhase::kFailed;
  }
  s.status = ReturnType::kError;
  s.error = error;
  s.it.phase = phase_;
  s.it.event = "error: " + error;
  s.it.command = robot_.lastCommand();
  return s;
}

void GraspController::stopMotion() {
  robot_.base().setVelocity(0, 0);
  robot_.head().setVelocity(0, 0);
  robot_.arm().setJointVelocity(Eigen::VectorXd::Zero(robot_.model().arm.dof()));
}

void GraspController::enter(GraspPhase p, Seconds t, const std::string& outcome,
                            GraspIteration* it) {
  PhaseReport& r = report_.phases[toString(phase_)];
  r.time_s += t - phase_start_;
  r.outcome = outcome;
  const GraspPhase phase_before = phase_;
  phase_ = p;
  guard_note_.clear();  // each phase notes where its base was held
  phase_start_ = t;
  detail_.clear();
  lost_since_.reset();
  unreachable_since_.reset();
  closer_ = false;
  it->event = std::string(toString(p)) + " (" + outcome + ")";
  report_.phases[toString(p)].outcome.clear();
  if (p == GraspPhase::kSearch) {
    ++report_.searches;
    // Look first where the head points (it was on the target when it was lost), with the head
    // only: the base stays where it is (next to the table, the arm out), it neither turns nor
    // drives blind.
    // With a belief and a loss in the approach (the arm not out yet), the search by belief
    // starts where the target was, the base free to move.
    const bool from_approach = phase_before == GraspPhase::kApproach && plan_.beliefMode() && wMo_;
    if (from_approach) {
      plan_.restart(robot_.state(), false, wMo_->t.head<2>());
    } else {
      plan_.restart(robot_.state(), /*head_only=*/true);
    }
    search_cmd_ = SearchCommand();
    est_.reset();
    wMo_.reset();
    belief_ = TargetStatus::kNone;
    goal_.reset();
  }
  if (p == GraspPhase::kApproach) base_task_.restart();
  if (p == GraspPhase::kGrasp) {
    grasp_step_ = GraspSubStep::kReach;
    step_started_ = t;
  }
}

void GraspController::finish(bool success, const std::string& outcome, const std::string& failure,
                             Seconds t, GraspIteration* it) {
  PhaseReport& r = report_.phases[toString(phase_)];
  r.time_s += t - phase_start_;
  r.outcome = outcome;
  it->event = std::string(toString(phase_)) + ": " + outcome;
  phase_ = success ? GraspPhase::kDone : GraspPhase::kFailed;
  phase_start_ = t;
  report_.success = success;
  report_.failure = failure;
  stopMotion();
}

void GraspController::abort(Seconds t, const std::string& outcome, const std::string& why) {
  if (finished()) return;
  GraspIteration it;
  finish(false, outcome, why, t, &it);
  robot_.stop();
}

GraspStep GraspController::step(Seconds t, Seconds dt) {
  GraspStep s;
  s.it.t = t;
  s.it.phase = phase_;
  if (!error_.empty()) {  // stopped for good after an error
    robot_.stop();
    s.status = ReturnType::kError;
    s.error = error_;
    s.it.command = robot_.lastCommand();
    return s;
  }
  if (finished()) {
    robot_.stop();
    s.it.command = robot_.lastCommand();
    return s;
  }
  try {
    last_t_ = t;
    if (robot_.read(t, dt) != ReturnType::kOk) return fail(s, at("robot read failed", t) + why());
    s.it.state = robot_.state();
    if (!started_) {
      started_ = true;
      phase_start_ = t;
      ++report_.searches;
      plan_.restart(robot_.state());
      report_.phases[toString(phase_)];
    }
    // Frames are grabbed only when they will be looked at (a simulated camera renders on grab).
    const bool target_phase = phase_ == GraspPhase::kApproach || phase_ == GraspPhase::kAlign ||
                              (phase_ == GraspPhase::kGrasp && grasp_step_ == GraspSubStep::kReach);
    const bool search_look = phase_ == GraspPhase::kSearch && search_cmd_.look;
    const std::string problem = observe(t, search_look || target_phase,
                                        search_look ? search_cmd_.look_after : -1e300, &s.it);
    if (!problem.empty()) return fail(s, problem);

    switch (phase_) {
      case GraspPhase::kSearch: decideSearch(t, &s.it); break;
      case GraspPhase::kApproach: decideApproach(t, &s.it); break;
      case GraspPhase::kAlign: decideAlign(t, &s.it); break;
      case GraspPhase::kGrasp: decideGrasp(t, &s.it); break;
      case GraspPhase::kDone:
      case GraspPhase::kFailed: stopMotion(); break;
    }
    // An unconfirmed target never moves the robot; a lost one stops it, except that the
    // search moves on to its next look (the target is not there).
    if (s.it.observed == TargetStatus::kUnconfirmed ||
        (s.it.observed == TargetStatus::kLost && phase_ != GraspPhase::kSearch))
      stopMotion();
    if (robot_.write(t, dt) != ReturnType::kOk) return fail(s, at("robot write failed", t) + why());
    s.it.command = robot_.lastCommand();
    s.it.phase = phase_;
    s.it.detail = detail_;
    s.it.wMo = wMo_;
    return s;
  } catch (const std::exception& e) {
    return fail(s, std::string("exception: ") + e.what());
  } catch (...) {
    return fail(s, "unknown exception");
  }
}

std::string GraspController::observe(Seconds t, bool want, Seconds look_after,
                                     GraspIteration* it) {
  if (!want) return {};
  if (t + 1e-9 >= next_grab_) {
    std::optional<robot::StereoFrame> frame;
    if (robot_.camera().grab(t, &frame) != ReturnType::kOk) return at("camera failed", t);
    if (frame) {
      it->truth = frame->truth;
      it->grabbed_index = frame->index;
    }
    if (frame && frame->stamp >= look_after) {
      next_grab_ = t + opt_.frame_period_s;
      const robot::CaptureState& c = frame->capture;
      const Pose wMc = (c.wMb_odom ? *c.wMb_odom : wMb()) * (c.bMc ? *c.bMc : robot_.camera().bMc());
      std::optional<Pose> prior;
      if (wMo_) prior = wMc.inverse() * *wMo_;
      TargetObservation obs = est_.observe(*frame, robot_.camera().rig(), prior);
      // A frame the estimator cannot use (wrong size, no ground truth for the oracle) is a
      // device or set-up fault, not a target out of view.
      if (!obs.error.empty()) return "frame " + std::to_string(frame->index) + ": " + obs.error;
      if ((obs.status == TargetStatus::kConfirmed || obs.status == TargetStatus::kUnconfirmed) &&
          (!obs.cMo || !obs.cMo->isFinite()))
        obs.status = TargetStatus::kLost;  // "seen" without a usable pose is not seen
      it->observed = obs.status;
      it->frame = std::move(*frame);
      candidate_w_.reset();
      if (obs.status == TargetStatus::kUnconfirmed) candidate_w_ = (wMc * *obs.cMo).t.head<2>();
      if (obs.status == TargetStatus::kConfirmed) {
        const Pose wMo = wMc * *obs.cMo;
        const double a = opt_.estimate_smoothing;
        wMo_ = (wMo_ && a > 0) ? interpolate(*wMo_, wMo, 1 - a) : wMo;
        confirmed_stamp_ = it->frame->stamp;
      }
      if (obs.status != TargetStatus::kNone) belief_ = obs.status;
      it->observation = std::move(obs);
    }
  }
  // A target no frame has confirmed for too long is lost.
  if (belief_ == TargetStatus::kConfirmed && t - confirmed_stamp_ > opt_.max_estimate_age_s) {
    belief_ = TargetStatus::kLost;
    char buf[80];
    std::snprintf(buf, sizeof(buf), "no confirmed frame for %.2f s", t - confirmed_stamp_);
    it->event = buf;
  }
  return {};
}

bool GraspController::targetUsable(Seconds t, GraspIteration* it) {
  it->target_driven = true;
  if (belief_ == TargetStatus::kConfirmed && wMo_) {
    if (lost_since_) it->event = "target confirmed again";
    lost_since_.reset();
    it->confirmed = true;
    return true;
  }
  stopMotion();
  if (!lost_since_) {
    lost_since_ = t;
    if (it->event.empty()) it->event = std::string("target ") + toString(belief_);
  }
  detail_ = "reacquire";
  if (t - *lost_since_ >= opt_.reacquire_timeout_s) {
    if (report_.searches >= opt_.max_searches) {
      finish(false, "lost", at("target lost, no search left", t), t, it);
    } else {
      enter(GraspPhase::kSearch, t, "lost", it);
    }
  }
  return false;
}

void GraspController::pointHead(const Pose& wMb_now, double base_v_mps, double base_w_radps) {
  robot::clipBaseVelocity(robot_.model().base, &base_v_mps, &base_w_radps);  // as the HAL will
  const Pose bMc = robot_.camera().bMc();
  const Eigen::Vector3d cP = (wMb_now * bMc).inverse() * (*wMo_ * centre_o_);
  const robot::RobotState& s = robot_.state();
  const HeadCommand h = head_task_.compute(cP, s.pan_rad, s.tilt_rad,
                                           baseTwistAt(bMc, base_v_mps, base_w_radps));
  robot_.head().setVelocity(h.pan_radps, h.tilt_radps);
}

void GraspController::decideSearch(Seconds t, GraspIteration* it) {
  const Seconds stamp = it->frame ? it->frame->stamp : -1e300;
  search_cmd_ = plan_.decide(t, robot_.state(), it->observed, stamp,
                             it->observed == TargetStatus::kUnconfirmed ? candidate_w_ : std::nullopt,
                             weakEvidence(it->observation));
  it->belief = plan_.belief();
  it->look_started = plan_.takeStartedLook();
  if (search_cmd_.new_look) est_.reset();  // another direction: nothing carried over
  detail_ = toString(search_cmd_.state);
  robot_.head().setPosition(search_cmd_.pan_rad, search_cmd_.tilt_rad);
  robot_.base().setVelocity(search_cmd_.base_v_mps, search_cmd_.base_w_radps);
  robot_.arm().setJointVelocity(Eigen::VectorXd::Zero(robot_.model().arm.dof()));
  if (search_cmd_.state == SearchState::kFound && wMo_) {
    stopMotion();
    enter(GraspPhase::kApproach, t, "found", it);
  } else if (search_cmd_.state == SearchState::kNotFound) {
    const std::string& why_not = plan_.endReason();
    const std::string what = "target not found" + (why_not.empty() ? "" : " (" + why_not + ")");
    finish(false, "not_found", at(what.c_str(), t), t, it);
  } else if (t - phase_start_ > opt_.search_timeout_s) {
    finish(false, "timeout", at("search timed out", t), t, it);
  }
}

void GraspController::decideApproach(Seconds t, GraspIteration* it) {
  if (t - phase_start_ > opt_.approach_timeout_s) {
    finish(false, "timeout", at("approach timed out", t), t, it);
    return;
  }
  if (!targetUsable(t, it)) return;
  const Pose wMg = *wMo_ * oMg_;
  const Pose wMed = wMg * along(-pregrasp_m_);
  BaseGoal g = baseGoalFor(arm_task_.kinematics(), wMed, goal_ ? goal_->reach.q : Eigen::VectorXd());
  g.wMb = clearOfFixtures(g.wMb);
  const Pose wMb_now = wMb();
  if (g.reach.ok) {
    unreachable_since_.reset();
    goal_ = std::move(g);
  } else if (!goal_ && (closer_ || (wMo_->t - wMb_now.t).head<2>().norm() > opt_.reestimate_range_m)) {
    // Too far to judge: closer, the target's centre ahead at reestimate_stop_m, arm still.
    const Eigen::Vector3d bP = wMb_now.inverse() * (*wMo_ * centre_o_);
    BaseCommand b = base_task_.compute(bP, bP, opt_.reestimate_stop_m);
    closer_ = std::abs(b.depth_error_m) > opt_.base.waypoint_tolerance_m;
    if (closer_) {
      guardBase(wMb_now, &b, it);
      unreachable_since_.reset();
      robot_.arm().setJointVelocity(Eigen::VectorXd::Zero(robot_.model().arm.dof()));
      robot_.base().setVelocity(b.v_mps, b.w_radps);
      pointHead(wMb_now, b.v_mps, b.w_radps);
      detail_ = "closer";
      return;
    }
  }
  if (!g.reach.ok) {
    if (!unreachable_since_) unreachable_since_ = t;
    if (t - *unreachable_since_ >= opt_.unreachable_patience_s) {
      finish(false, "unreachable", at("no arm configuration reaches the pre-grasp pose", t), t, it);
      return;
    }
    if (!goal_) {  // nothing reachable yet: hold still and look again
      stopMotion();
      detail_ = "unreachable";
      return;
    }
  }
  BaseCommand b = base_task_.approach(wMb_now, goal_->wMb, Eigen::Vector3d(*wMo_ * centre_o_));
  detail_ = toString(b.stage);
  // The arm goes to its reaching configuration meanwhile (joint space, capped speed).
  const robot::RobotState& s = robot_.state();
  const robot::ArmModel& arm = robot_.model().arm;
  Eigen::VectorXd qdot(arm.dof());
  double worst = 0;
  for (int i = 0; i < arm.dof(); ++i) {
    const double cap = opt_.arm_ready_speed_fraction * arm.joints[static_cast<size_t>(i)].limits.max_speed_radps;
    const double err = goal_->reach.q[i] - s.arm_q_rad[i];
    qdot[i] = std::clamp(3.0 * err, -cap, cap);
    worst = std::max(worst, std::abs(err));
  }
  robot_.arm().setJointVelocity(qdot);
  // Near the goal the base waits (turning only) for the arm.
  if (worst > opt_.arm_ready_tolerance_rad && b.v_mps > 0 &&
      (goal_->wMb.t - wMb_now.t).head<2>().norm() < opt_.arm_ready_distance_m) {
    b.v_mps = 0;
    detail_ = "arm_ready";
  }
  guardBase(wMb_now, &b, it);
  robot_.base().setVelocity(b.v_mps, b.w_radps);
  pointHead(wMb_now, b.v_mps, b.w_radps);
  it->error_position_m = b.points.position_error_m;
  it->error_rotation_rad = std::abs(b.points.heading_error_rad);
  it->distance_m = translationError(wMb_now * robot_.arm().bMe(), wMg);
  if (b.stage == ApproachStage::kDone && worst < opt_.approach_arm_tolerance_rad) {
    enter(GraspPhase::kAlign, t, "converged", it);
  }
}

void GraspController::decideAlign(Seconds t, GraspIteration* it) {
  if (t - phase_start_ > opt_.align_timeout_s) {
    finish(false, "timeout", at("align timed out", t), t, it);
    return;
  }
  if (!targetUsable(t, it)) return;
  const Pose wMb_now = wMb();
  const Pose wMg = *wMo_ * oMg_;
  const Pose bMed = wMb_now.inverse() * wMg * along(-pregrasp_m_);
  const ArmCommand c = arm_task_.compute(robot_.state().arm_q_rad, bMed, armBaseMayAdvance(wMb_now, it));
  robot_.arm().setJointVelocity(c.qdot_radps);
  robot_.base().setVelocity(c.base_v_mps, c.base_w_radps);
  pointHead(wMb_now, c.base_v_mps, c.base_w_radps);
  detail_ = "servo";
  it->bMe_desired = bMed;
  it->error_position_m = c.position_error_m();
  it->error_rotation_rad = c.rotation_error_rad();
  it->distance_m = translationError(wMb_now * robot_.arm().bMe(), wMg);
  if (c.position_error_m() < opt_.align_position_tolerance_m &&
      c.rotation_error_rad() < opt_.align_rotation_tolerance_rad) {
    stopMotion();
    enter(GraspPhase::kGrasp, t, "converged", it);
  }
}

void GraspController::decideGrasp(Seconds t, GraspIteration* it) {
  if (t - phase_start_ > opt_.grasp_timeout_s) {
    finish(false, "timeout", at("grasp timed out", t), t, it);
    return;
  }
  const robot::RobotState& s = robot_.state();
  detail_ = toString(grasp_step_);
  if (grasp_step_ == GraspSubStep::kReach) {
    if (!targetUsable(t, it)) return;
    detail_ = toString(grasp_step_);
    const Pose wMb_now = wMb();
    const Pose wMg = *wMo_ * oMg_;
    // e* slides from the pre-grasp pose to g along z_g: a straight line at grasp_speed_mps.
    const double d = std::max(0.0, pregrasp_m_ - opt_.grasp_speed_mps * (t - step_started_));
    const Pose bMed = wMb_now.inverse() * wMg * along(-d);
    const ArmCommand c = arm_task_.compute(s.arm_q_rad, bMed, opt_.final_approach_base && armBaseMayAdvance(wMb_now, it));
    robot_.arm().setJointVelocity(c.qdot_radps);
    robot_.base().setVelocity(c.base_v_mps, c.base_w_radps);
    pointHead(wMb_now, c.base_v_mps, c.base_w_radps);
    it->bMe_desired = bMed;
    const Pose wMe = wMb_now * robot_.arm().bMe();
    it->distance_m = translationError(wMe, wMg);
    it->error_position_m = c.position_error_m();
    it->error_rotation_rad = c.rotation_error_rad();
    if (d == 0 && c.position_error_m() < opt_.grasp_position_tolerance_m &&
        c.rotation_error_rad() < opt_.grasp_rotation_tolerance_rad) {
      report_.close_position_error_m = translationError(wMe, wMg);
      report_.close_rotation_error_rad = rotationError(wMe, wMg);
      stopMotion();
      robot_.gripper().close();
      grasp_step_ = GraspSubStep::kClose;
      step_started_ = t;
      it->event = "closing";
    }
    return;
  }
  stopMotion();
  if (grasp_step_ == GraspSubStep::kClose) {
    if (s.gripper == robot::GripperPhase::kHolding) {
      grasp_step_ = GraspSubStep::kLift;
      step_started_ = t;
      lift_start_bMe_ = robot_.arm().bMe();
      it->event = "holding";
    } else if (s.gripper == robot::GripperPhase::kClosedEmpty) {
      finish(false, "missed", at("the gripper closed on nothing", t), t, it);
    }
    return;
  }
  if (s.gripper != robot::GripperPhase::kHolding) {
    finish(false, "dropped", at("the object slipped out of the gripper", t), t, it);
    return;
  }
  if (grasp_step_ == GraspSubStep::kLift) {
    const double lifted = robot_.arm().bMe().t.z() - lift_start_bMe_.t.z();
    if (lifted < opt_.lift_m) {
      Twist up;
      up.v.z() = opt_.lift_speed_mps;
      robot_.arm().setVelocity(robot::ArmFrame::kBase, up);
    } else {
      grasp_step_ = GraspSubStep::kHold;
      step_started_ = t;
    }
    it->error_position_m = std::max(0.0, opt_.lift_m - lifted);
    return;
  }
  if (t - step_started_ >= opt_.hold_check_s) finish(true, "holding", "", t, it);
}

}  // namespace refgrasp::servo
