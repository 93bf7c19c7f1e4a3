#include "component/detect_service.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace refgrasp::component {

namespace msg = dds::msg;

namespace {

/// Moves the items for which `is_due` holds out of `items` (in order) and returns them.
template <class Item, class Predicate>
std::vector<Item> removeDue(std::vector<Item>& items, Predicate is_due) {
  std::vector<Item> due;
  for (auto it = items.begin(); it != items.end();) {
    if (is_due(*it)) {
      due.push_back(std::move(*it));
      it = items.erase(it);
    } else {
      ++it;
    }
  }
  return due;
}

}  // namespace

DetectService::DetectService(dds::Participant& participant, dds::WaitSet& waitset, const std::string& ns,
                             std::vector<std::string> object_names, SharedStats& stats)
    : object_names_(std::move(object_names)), stats_(stats), latest_results_(object_names_.size()) {
  server_ = std::make_unique<Server>(participant, dds::joinRosName(ns, "detect"));
  waitset.attach(server_->requestCondition(), 5);  // WaitSet tag 5 (the readers of FrameInput have 1-4)
}

double DetectService::waitTimeout(double longest_s) const {
  double timeout_s = longest_s;
  std::lock_guard<std::mutex> lock(results_mutex_);
  for (const Pending& pending : pending_)
    timeout_s = std::min(timeout_s, std::max(0.0, pending.deadline - steadyNow()));
  return timeout_s;
}

int DetectService::objectId(const std::string& name) const {
  for (size_t i = 0; i < object_names_.size(); ++i)
    if (object_names_[i] == name) return static_cast<int>(i);
  return -1;
}

void DetectService::reply(const Server::Incoming& request, bool found, const Pose& cMo,
                          const std::string& error) {
  msg::DetectResponse response{};
  response.found = found;
  if (found) {
    for (int i = 0; i < 9; ++i) response.rotation[i] = cMo.R(i / 3, i % 3);
    for (int i = 0; i < 3; ++i) response.translation[i] = cMo.t[i];
  }
  response.error = const_cast<char*>(error.c_str());
  std::lock_guard<std::mutex> lock(server_mutex_);
  server_->reply(request, response);
}

void DetectService::replyWith(const Server::Incoming& request, const ObjectResult& result) {
  if (!result.have) reply(request, false, Pose(), "no frame received yet");
  else reply(request, result.found, result.cMo, result.error);
}

void DetectService::takeRequests() {
  std::vector<Server::Incoming> requests;
  {
    std::lock_guard<std::mutex> lock(server_mutex_);
    requests = server_->take();
  }
  for (auto& request : requests) {
    {
      std::lock_guard<std::mutex> lock(stats_.mutex);
      ++stats_.counts.requests;
    }
    const std::string name = request.request->object_name ? request.request->object_name : "";
    const double timeout_s = request.request->timeout_s;
    const int object = objectId(name);
    if (object < 0) {
      reply(request, false, Pose(), "unknown object '" + name + "'");
      continue;
    }
    if (!std::isfinite(timeout_s) || timeout_s < 0) {
      reply(request, false, Pose(), "timeout_s must be a finite number >= 0");
      continue;
    }
    std::unique_lock<std::mutex> lock(results_mutex_);
    if (timeout_s == 0) {
      const ObjectResult latest = latest_results_[static_cast<size_t>(object)];
      lock.unlock();
      replyWith(request, latest);
      continue;
    }
    Pending pending{std::move(request), object, 0, steadyNow() + timeout_s};
    {
      std::lock_guard<std::mutex> stats_lock(stats_.mutex);
      pending.after_seq = stats_.counts.received;
    }
    pending_.push_back(std::move(pending));
  }
}

void DetectService::expirePending() {
  std::vector<Pending> expired;
  {
    std::lock_guard<std::mutex> lock(results_mutex_);
    const double now = steadyNow();
    expired = removeDue(pending_, [now](const Pending& pending) { return pending.deadline <= now; });
  }
  for (Pending& pending : expired) {
    char line[96];
    std::snprintf(line, sizeof line, "timeout: no new frame's result within %.3g s",
                  pending.request.request->timeout_s);
    reply(pending.request, false, Pose(), line);
  }
}

void DetectService::record(long seq, const std::vector<ObjectResult>& results) {
  std::vector<Pending> ready;
  {
    std::lock_guard<std::mutex> lock(results_mutex_);
    latest_results_ = results;
    ready = removeDue(pending_, [seq](const Pending& pending) { return seq > pending.after_seq; });
  }
  for (Pending& pending : ready) replyWith(pending.request, results[static_cast<size_t>(pending.object)]);
}

}  // namespace refgrasp::component
