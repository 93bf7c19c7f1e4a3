#pragma once
// ROS 2 services as rmw_cyclonedds puts them on DDS: service "/ns/srv" is a request topic
// "rq/ns/srvRequest" and a reply topic "rr/ns/srvReply" (types `<pkg>::srv::dds_::<Srv>_Request_`
// and `..._Response_`), both reliable, keep last 10, volatile. Every request and reply starts
// with the request header {uint64 guid; int64 seq;}: guid = the client's request-writer instance
// handle, seq = the client's request counter from 1; the server copies both into the reply and
// every client keeps the replies that carry its own guid. Clients put "clientid=<id>;" and servers
// "serviceid=<id>;" in the user data of their reader and writer, and a server answers once it has
// matched the reply reader of the client that asked (rmw_cyclonedds waits up to 100 ms for that).
//
// Req and Rep are generated structs whose first member is `msg::RequestHeader header`.
#include <atomic>
#include <chrono>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "robot/dds/transport.h"

namespace refgrasp::dds {

std::string ddsRequestTopicName(const std::string& ros_service);  ///< "rq" + name + "Request"
std::string ddsReplyTopicName(const std::string& ros_service);    ///< "rr" + name + "Reply"

/// rmw_cyclonedds' client/service id: participant GUID prefix + a per-process counter, as
/// "xx.xx...." hex bytes.
std::string makeClientServiceId(const Participant& pp);
/// The value of `key` in "k1=v1;k2=v2;" user data of a matched endpoint, "" when absent.
std::string userDataValue(const dds_qos_t* qos, const std::string& key);

/// QoS of both service topics (rmw_qos_profile_services_default).
inline QosProfile serviceQos() { return QosProfile::reliable(10); }

template <class Req, class Rep>
class ServiceServer {
 public:
  ServiceServer(const Participant& pp, const std::string& ros_service)
      : id_(makeClientServiceId(pp)),
        requests_(pp, ddsRequestTopicName(ros_service), serviceQos(), "serviceid=" + id_ + ";"),
        replies_(pp, ddsReplyTopicName(ros_service), serviceQos(), "serviceid=" + id_ + ";") {}

  /// A request and who sent it.
  struct Incoming {
    Sample<Req> request;
    dds_instance_handle_t writer = 0;  ///< the client's request writer (publication handle)
  };

  dds_entity_t requestCondition() const { return requests_.condition(); }
  const Reader<Req>& requestReader() const { return requests_; }
  const Writer<Rep>& replyWriter() const { return replies_; }

  std::vector<Incoming> take() {
    std::vector<Incoming> out;
    for (;;) {
      Sample<Req> s;
      void* ptr = s.get();
      dds_sample_info_t info;
      if (dds_take(requests_.handle(), &ptr, &info, 1, 1) != 1) break;
      if (info.valid_data) out.push_back({std::move(s), info.publication_handle});
    }
    return out;
  }

  /// Sends `rep` with the header of `in.request`. Waits up to 100 ms for the client's reply reader
  /// to match (as rmw_cyclonedds does) so the reply is not written before anyone can receive it.
  /// False on a DDS error or when the client's reader did not show up.
  bool reply(const Incoming& in, Rep rep) {
    rep.header = in.request->header;
    if (!clientReaderMatched(in.writer)) return false;
    return replies_.write(rep);
  }

 private:
  bool clientReaderMatched(dds_instance_handle_t request_writer) {
    dds_builtintopic_endpoint_t* wr =
        dds_get_matched_publication_data(requests_.handle(), request_writer);
    if (!wr) return true;  // gone already: the write is harmless
    const std::string cid = userDataValue(wr->qos, "clientid");
    dds_builtintopic_free_endpoint(wr);
    if (cid.empty() || known_clients_.count(cid)) return true;  // old clients carry no id
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(100);
    do {
      dds_instance_handle_t rds[64];
      const dds_return_t n = dds_get_matched_subscriptions(replies_.handle(), rds, 64);
      for (dds_return_t i = 0; i < n && i < 64; ++i) {
        dds_builtintopic_endpoint_t* rd = dds_get_matched_subscription_data(replies_.handle(), rds[i]);
        if (!rd) continue;
        const bool same = userDataValue(rd->qos, "clientid") == cid;
        dds_builtintopic_free_endpoint(rd);
        if (same) {
          known_clients_.insert(cid);
          return true;
        }
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    } while (std::chrono::steady_clock::now() < end);
    return false;
  }

  std::string id_;
  Reader<Req> requests_;
  Writer<Rep> replies_;
  std::set<std::string> known_clients_;
};

template <class Req, class Rep>
class ServiceClient {
 public:
  ServiceClient(const Participant& pp, const std::string& ros_service)
      : id_(makeClientServiceId(pp)),
        requests_(pp, ddsRequestTopicName(ros_service), serviceQos(), "clientid=" + id_ + ";"),
        replies_(pp, ddsReplyTopicName(ros_service), serviceQos(), "clientid=" + id_ + ";"),
        guid_(requests_.instanceHandle()) {}

  /// A server matched both topics (rmw_service_server_is_available).
  bool serviceAvailable() const { return requests_.matched() > 0 && replies_.matched() > 0; }
  bool waitForService(double timeout_s) const {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (!serviceAvailable()) {
      if (std::chrono::steady_clock::now() >= end) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return true;
  }

  /// Sends `req` with header {guid, ++seq}; returns seq (< 0 on a DDS error).
  int64_t send(Req req) {
    req.header.guid = guid_;
    req.header.seq = ++seq_;
    return requests_.write(req) ? req.header.seq : -1;
  }

  /// The reply to request `seq` of this client, waiting up to timeout_s; replies to other
  /// clients or to other requests are dropped.
  std::optional<Sample<Rep>> waitReply(int64_t seq, double timeout_s) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    for (;;) {
      for (auto& s : replies_.takeAll())
        if (s->header.guid == guid_ && s->header.seq == seq) return std::move(s);
      if (std::chrono::steady_clock::now() >= end) return std::nullopt;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }

  /// send + waitReply.
  std::optional<Sample<Rep>> call(Req req, double timeout_s) {
    const int64_t seq = send(req);
    if (seq < 0) return std::nullopt;
    return waitReply(seq, timeout_s);
  }

  uint64_t guid() const { return guid_; }

 private:
  std::string id_;
  Writer<Req> requests_;
  Reader<Rep> replies_;
  uint64_t guid_ = 0;
  int64_t seq_ = 0;
};

}  // namespace refgrasp::dds
