#pragma once
// The detect service <ns>/detect (refgrasp_msgs/srv/Detect): keeps the latest result per object
// and answers requests. timeout_s = 0 is answered at once with the latest result; timeout_s > 0
// waits (as a pending request) for the result of the next frame received after the request, and
// is answered with a timeout error when none comes within timeout_s. An unknown object or a bad
// timeout_s is answered at once with an error.
//
// Threads: takeRequests(), expirePending() and waitTimeout() run on the receive thread (the
// facade's WaitSet loop); record() on the detector thread. Replies come from both, under one lock.
// Owns: the service server (its request reader attached to the facade's WaitSet), the latest
// results, the pending requests. Counts requests in the shared statistics and reads there the
// number of frames received (which frame answers a waiting request).
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "component/shared_stats.h"
#include "core/pose.h"
#include "robot/dds/service.h"
#include "robot/dds/transport.h"

namespace refgrasp::component {

/// The newest answer for one object.
struct ObjectResult {
  bool have = false;   ///< a frame has been processed
  bool found = false;
  Pose cMo;            ///< object in the camera's optical frame (stereo: the left one), when found
  std::string error;   ///< why the frame could not be used (then found = false)
};

class DetectService {
 public:
  /// Creates the server of <ns>/detect and attaches its requests to `waitset`. `object_names`
  /// in the detector's order (ObjectResult vectors use the same). Throws dds::DdsError.
  DetectService(dds::Participant& participant, dds::WaitSet& waitset, const std::string& ns,
                std::vector<std::string> object_names, SharedStats& stats);

  /// How long the receive thread may wait: longest_s, or less when a pending request expires sooner.
  double waitTimeout(double longest_s) const;
  /// Answers or queues the requests that came in.
  void takeRequests();
  /// Answers the pending requests whose deadline has passed with a timeout error.
  void expirePending();
  /// Stores the results of frame `seq` (one per object) and answers the requests waiting for them.
  void record(long seq, const std::vector<ObjectResult>& results);

 private:
  using Server = dds::ServiceServer<dds::msg::DetectRequest, dds::msg::DetectResponse>;
  struct Pending {
    Server::Incoming request;
    int object = -1;
    long after_seq = 0;   ///< answered by the result of a frame with a larger seq
    double deadline = 0;  ///< steady clock (s)
  };

  /// The object's index, -1 when unknown.
  int objectId(const std::string& name) const;
  void reply(const Server::Incoming& request, bool found, const Pose& cMo, const std::string& error);
  void replyWith(const Server::Incoming& request, const ObjectResult& result);

  const std::vector<std::string> object_names_;
  SharedStats& stats_;
  std::unique_ptr<Server> server_;
  std::mutex server_mutex_;  ///< the server's replies come from both threads
  mutable std::mutex results_mutex_;  ///< latest_results_, pending_
  std::vector<ObjectResult> latest_results_;
  std::vector<Pending> pending_;
};

}  // namespace refgrasp::component
