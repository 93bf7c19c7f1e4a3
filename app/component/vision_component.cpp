#include "component/vision_component.h"

#include <atomic>
#include <cmath>
#include <cstdio>
#include <thread>

#include "component/detect_service.h"
#include "component/frame_input.h"
#include "component/rate_limited_log.h"
#include "component/shared_stats.h"
#include "component/worker.h"
#include "core/error.h"
#include "robot/dds/transport.h"

namespace refgrasp::component {

void VisionComponentOptions::check() const {
  dds::checkDomainAndNamespace(domain, ns, "VisionComponentOptions");
  if (track) tracking.check();
  refgrasp::check(std::isfinite(warning_period_s) && warning_period_s >= 0,
                  "VisionComponentOptions.warning_period_s", "must be >= 0");
}

namespace {

/// The longest a thread waits before it looks at the stop flag again (s); stop() also wakes
/// both threads at once, so this only bounds a missed wake-up.
constexpr double kPollPeriodS = 0.2;

/// The detector's object names in its order; throws std::invalid_argument when there is none
/// or, in stereo, one has no reference pose (stereo fuses 3D poses).
std::vector<std::string> checkedObjectNames(const detector::Detector& detector, bool stereo) {
  std::vector<std::string> names;
  for (int i = 0; i < detector.objectCount(); ++i) {
    if (stereo && !detector.object(i).hasPose())
      throw std::invalid_argument(detector.object(i).name + ": stereo needs a reference_pose (3D)");
    names.push_back(detector.object(i).name);
  }
  if (names.empty()) throw std::invalid_argument("the component needs at least one object");
  return names;
}

VisionComponent::WarningSink orStderr(VisionComponent::WarningSink warn) {
  if (warn) return warn;
  return [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); };
}

}  // namespace

/// The facade: wires the input, the detect service and the worker on one DDS participant, and
/// runs the two threads.
///   receive thread:  waits on the WaitSet (camera readers and service requests), takes the camera
///                    samples (the newest frame into the slot), then the requests, then expires
///                    the pending requests whose timeout has passed.
///   detector thread: takes the newest frame from the slot, processes and publishes it (worker),
///                    then hands its results to the service (latest results, waiting requests).
/// stop() sets the flag, wakes both threads and joins them; pending requests stay unanswered.
struct VisionComponent::Impl {
  Impl(detector::Detector detector, const VisionComponentOptions& options, WarningSink warn)
      : log(orStderr(std::move(warn)), options.warning_period_s),
        participant(options.domain),
        waitset(participant),
        object_names(checkedObjectNames(detector, options.stereo.has_value())),
        input(participant, waitset, options.ns, options.stereo.has_value(), stats, log),
        worker(std::move(detector), options, object_names, participant, input, stats, log),
        service(participant, waitset, options.ns, object_names, stats) {
    receive_thread = std::thread([this] { receiveLoop(); });
    detector_thread = std::thread([this] { detectorLoop(); });
  }

  void stop() {
    if (stopping.exchange(true)) return;
    waitset.wake();
    input.close();
    if (receive_thread.joinable()) receive_thread.join();
    if (detector_thread.joinable()) detector_thread.join();
  }

  void receiveLoop() {
    while (!stopping) {
      waitset.wait(service.waitTimeout(kPollPeriodS));
      if (stopping) break;
      input.takeSamples();
      service.takeRequests();
      service.expirePending();
    }
  }

  void detectorLoop() {
    while (!stopping) {
      std::optional<FrameJob> job = input.takeFrame(kPollPeriodS);
      if (!job) continue;
      const std::vector<ObjectResult> results = worker.process(*job, steadyNow());
      service.record(job->seq, results);
    }
  }

  RateLimitedLog log;  ///< shared by the input and the worker (thread-safe)
  dds::Participant participant;
  dds::WaitSet waitset;  ///< the receive thread's: the camera readers and the service's requests
  SharedStats stats;
  const std::vector<std::string> object_names;  ///< the detector's objects, in its order
  FrameInput input;
  Worker worker;
  DetectService service;
  std::atomic<bool> stopping{false};
  std::thread receive_thread, detector_thread;
};

VisionComponent::VisionComponent(detector::Detector detector, const VisionComponentOptions& options,
                                 WarningSink warn) {
  options.check();
  p_ = std::make_unique<Impl>(std::move(detector), options, std::move(warn));
}

VisionComponent::~VisionComponent() { stop(); }

void VisionComponent::stop() {
  if (p_) p_->stop();
}

ComponentStats VisionComponent::stats() const { return p_->stats.snapshot(); }

}  // namespace refgrasp::component
