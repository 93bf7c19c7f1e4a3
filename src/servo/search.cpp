#include "servo/search.h"

#include <cmath>
#include <stdexcept>

#include "core/error.h"

namespace refgrasp::servo {

using robot::ReturnType;

void SearchOptions::check() const {
  refgrasp::check(std::isfinite(tilt_rad), "SearchOptions.tilt_rad", "must be finite");
  refgrasp::check(std::isfinite(pan_step_rad) && pan_step_rad >= 0.01 && pan_step_rad <= M_PI,
                  "SearchOptions.pan_step_rad", "must be in [0.01, pi]");
  refgrasp::check(std::isfinite(settle_s) && settle_s >= 0 && settle_s <= 10,
                  "SearchOptions.settle_s", "must be in [0, 10]");
  refgrasp::check(std::isfinite(head_tolerance_rad) && head_tolerance_rad > 0,
                  "SearchOptions.head_tolerance_rad", "must be > 0");
  refgrasp::check(std::isfinite(turn_rad) && turn_rad > 0 && turn_rad <= 2 * M_PI,
                  "SearchOptions.turn_rad", "must be in (0, 2 pi]");
  refgrasp::check(std::isfinite(turn_speed_radps) && turn_speed_radps > 0,
                  "SearchOptions.turn_speed_radps", "must be > 0");
}

const char* toString(SearchPhase p) {
  switch (p) {
    case SearchPhase::kPointHead: return "point_head";
    case SearchPhase::kSettle: return "settle";
    case SearchPhase::kLook: return "look";
    case SearchPhase::kTurnBase: return "turn_base";
    case SearchPhase::kFound: return "found";
    case SearchPhase::kError: return "error";
  }
  return "?";
}

namespace {
double heading(const Pose& wMb) { return std::atan2(wMb.R(1, 0), wMb.R(0, 0)); }
}  // namespace

SearchController::SearchController(robot::Robot& robot, const detector::Detector& detector,
                                   int object, const SearchOptions& options)
    : robot_(robot), detector_(detector), object_(object), opt_(options) {
  opt_.check();
  if (object < 0 || object >= detector.objectCount())
    throw std::invalid_argument("SearchController: unknown object id " + std::to_string(object));
  // Head positions to try from the current base heading: straight, then alternately left/right.
  const robot::HeadModel& h = robot.model().head;
  pans_.push_back(0.0);
  for (double p = opt_.pan_step_rad; p <= h.pan.max_rad + 1e-9; p += opt_.pan_step_rad) {
    pans_.push_back(p);
    if (-p >= h.pan.min_rad) pans_.push_back(-p);
  }
}

SearchStep SearchController::fail(SearchStep s, const std::string& error) {
  robot_.stop();
  phase_ = SearchPhase::kError;
  s.status = ReturnType::kError;
  s.error = error_ = error;
  s.phase = phase_;
  return s;
}

SearchStep SearchController::step(Seconds t, Seconds dt) {
  SearchStep s;
  s.phase = phase_;
  if (phase_ == SearchPhase::kFound || phase_ == SearchPhase::kError) {  // done: hold still
    robot_.stop();
    if (phase_ == SearchPhase::kError) {
      s.status = ReturnType::kError;
      s.error = error_;
    }
    return s;
  }
  try {
    char where[64];
    std::snprintf(where, sizeof(where), " at t=%.2f s", t);
    if (robot_.read(t, dt) != ReturnType::kOk) return fail(s, std::string("robot read failed") + where);
    s = decide(t, s);
    if (s.status != ReturnType::kOk) return s;
    if (phase_ == SearchPhase::kFound) {
      robot_.stop();
      return s;
    }
    if (robot_.write(t, dt) != ReturnType::kOk) return fail(s, std::string("robot write failed") + where);
    return s;
  } catch (const std::exception& e) {
    return fail(s, std::string("exception: ") + e.what());
  } catch (...) {
    return fail(s, "unknown exception");
  }
}

SearchStep SearchController::decide(Seconds t, SearchStep s) {
  std::optional<robot::StereoFrame> frame;
  if (robot_.camera().grab(t, &frame) != ReturnType::kOk) {
    char buf[64];
    std::snprintf(buf, sizeof(buf), "camera failed at t=%.2f s", t);
    return fail(s, buf);
  }
  const robot::RobotState& st = robot_.state();
  robot_.base().setVelocity(0, 0);
  robot_.head().setPosition(pans_[pan_index_], opt_.tilt_rad);

  switch (phase_) {
    case SearchPhase::kPointHead:
      if (std::abs(st.pan_rad - pans_[pan_index_]) < opt_.head_tolerance_rad &&
          std::abs(st.tilt_rad - opt_.tilt_rad) < opt_.head_tolerance_rad) {
        settle_until_ = t + opt_.settle_s;
        phase_ = SearchPhase::kSettle;
      }
      break;
    case SearchPhase::kSettle:
      if (t >= settle_until_) phase_ = SearchPhase::kLook;
      break;
    case SearchPhase::kLook: {
      if (!frame || frame->stamp < settle_until_) break;  // wait for a frame taken after settling
      const detector::StereoDetectionResult r =
          detector_.detectStereo(frame->left, frame->right, robot_.camera().rig(),
                                 frame->frameStamp());
      if (!r.ok) return fail(s, "frame " + std::to_string(frame->index) + ": " + r.error);
      SearchLook look;
      look.number = ++looks_;
      look.t = t;
      look.frame = *frame;
      look.detection = r.objects.at(static_cast<size_t>(object_));
      look.extract_ms = r.left.time_ms.extract + r.right.time_ms.extract;
      look.total_ms = r.left.time_ms.total + r.right.time_ms.total;
      if (look.found()) {
        phase_ = SearchPhase::kFound;
      } else if (++pan_index_ >= pans_.size()) {
        pan_index_ = 0;
        turn_start_theta_ = heading(st.wMb_odom);
        phase_ = SearchPhase::kTurnBase;
      } else {
        phase_ = SearchPhase::kPointHead;
      }
      s.look = std::move(look);
      break;
    }
    case SearchPhase::kTurnBase: {
      const double turned = std::remainder(heading(st.wMb_odom) - turn_start_theta_, 2 * M_PI);
      if (std::abs(turned) >= opt_.turn_rad) {
        phase_ = SearchPhase::kPointHead;
      } else {
        robot_.base().setVelocity(0, opt_.turn_speed_radps);
      }
      break;
    }
    case SearchPhase::kFound:
    case SearchPhase::kError:
      break;
  }
  s.phase = phase_;
  return s;
}

}  // namespace refgrasp::servo
