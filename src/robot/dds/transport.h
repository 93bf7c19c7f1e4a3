#pragma once
// A thin C++ layer over Eclipse Cyclone DDS's C API (Debian packages no C++ binding) that puts
// data on the wire exactly as a ROS 2 node on rmw_cyclonedds (Humble, Jazzy) does, so that one
// talks to refgrasp with no bridge:
//   - topic names: ROS topic "/ns/name" is DDS topic "rt/ns/name" (services: robot/dds/service.h);
//   - type names: `<pkg>::msg::dds_::<Name>_` (robot/dds/messages.h), matched by NAME: the types
//     carry no XTypes type information, as rmw_cyclonedds' do not;
//   - XCDR1 data representation (plain CDR, encapsulation CDR_LE), final extensibility;
//   - QoS as ROS's profiles: sensor data = best effort, keep last; the rest reliable, volatile;
//     autodispose off.
// The Cyclone configuration comes from CYCLONEDDS_URI (config/dds/cyclonedds_loopback.xml for
// loopback-only runs and large images). Construction throws DdsError (start-up); inside loops,
// write() and the take functions return a status and never throw.
#include <dds/dds.h>

#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "robot/dds/messages.h"

namespace refgrasp::dds {

class DdsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// rc when rc >= 0, else throws DdsError("<what>: <Cyclone's text for rc>").
dds_return_t checkRc(dds_return_t rc, const std::string& what);

// ---- ROS 2 names --------------------------------------------------------------------------------

/// Empty when `name` is a valid fully-qualified ROS 2 name ("/a/b_2": starts with '/', tokens of
/// [A-Za-z0-9_] not starting with a digit, no "//", no trailing '/'; "/" alone for a namespace),
/// else the problem.
std::string rosNameProblem(const std::string& name, bool is_namespace = false);
/// "/refgrasp" + "image_raw" -> "/refgrasp/image_raw"; "/" + "x" -> "/x".
std::string joinRosName(const std::string& ns, const std::string& relative);
/// For command lines: "--domain: 300 not in [0, 232]" or "--ns: <problem>", empty when both are fine.
std::string domainOrNamespaceProblem(int domain, const std::string& ns);
/// Throws std::invalid_argument "<options>.domain: ..." / "<options>.ns: ..." (Options::check()).
void checkDomainAndNamespace(int domain, const std::string& ns, const std::string& options);
/// rmw_cyclonedds: "rt" + ROS topic.
std::string ddsTopicName(const std::string& ros_topic);

/// Highest valid DDS domain id (the default RTPS port mapping stops at 232).
constexpr int kMaxDomainId = 232;

// ---- QoS ------------------------------------------------------------------------------------------

enum class Reliability { kBestEffort, kReliable };

/// The part of a ROS 2 QoS profile refgrasp uses (durability is always volatile).
struct QosProfile {
  Reliability reliability = Reliability::kReliable;
  int depth = 10;  ///< keep last
  /// rmw_qos_profile_sensor_data with depth 1: images (only the newest frame matters).
  static QosProfile sensorData() { return {Reliability::kBestEffort, 1}; }
  /// rmw_qos_profile_default: poses, detections, robot state and commands.
  static QosProfile reliable(int depth = 10) { return {Reliability::kReliable, depth}; }
};

/// A dds_qos_t for readers and writers: the profile, XCDR1, autodispose off, optional user data.
dds_qos_t* makeQos(const QosProfile& profile, const std::string& user_data = "");

// ---- entities ------------------------------------------------------------------------------------

/// A domain participant. The domain id must be in [0, 232] (the RTPS port mapping's range).
class Participant {
 public:
  explicit Participant(int domain_id);
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;
  dds_entity_t handle() const { return pp_; }
  int domain() const { return domain_; }

 private:
  dds_entity_t pp_ = 0;
  int domain_ = 0;
};

/// A received sample in memory this process owns: Cyclone allocates its strings and sequences
/// while deserialising; the destructor frees them.
template <class T>
class Sample {
 public:
  Sample() { std::memset(&v_, 0, sizeof v_); }
  ~Sample() { release(); }
  Sample(const Sample&) = delete;
  Sample& operator=(const Sample&) = delete;
  Sample(Sample&& o) noexcept {
    std::memcpy(&v_, &o.v_, sizeof v_);
    std::memset(&o.v_, 0, sizeof o.v_);
  }
  Sample& operator=(Sample&& o) noexcept {
    if (this != &o) {
      release();
      std::memcpy(&v_, &o.v_, sizeof v_);
      std::memset(&o.v_, 0, sizeof o.v_);
    }
    return *this;
  }
  T& operator*() { return v_; }
  const T& operator*() const { return v_; }
  T* operator->() { return &v_; }
  const T* operator->() const { return &v_; }
  T* get() { return &v_; }

 private:
  void release() {
    dds_sample_free(&v_, MessageType<T>::descriptor(), DDS_FREE_CONTENTS);
    std::memset(&v_, 0, sizeof v_);
  }
  T v_;
};

/// What the type-independent part of a reader or writer needs.
class Endpoint {
 public:
  ~Endpoint();
  Endpoint(const Endpoint&) = delete;
  Endpoint& operator=(const Endpoint&) = delete;
  dds_entity_t handle() const { return ent_; }
  const std::string& topicName() const { return topic_name_; }
  /// Number of remote (or local) endpoints currently matched.
  int matched() const;
  /// Waits (polling discovery) until at least `count` endpoints match; false on timeout.
  bool waitForMatch(int count, double timeout_s) const;

 protected:
  Endpoint(const Participant& pp, const dds_topic_descriptor_t* desc, const std::string& topic,
           const QosProfile& qos, const std::string& user_data, bool writer);
  dds_entity_t topic_ = 0, ent_ = 0;
  bool writer_ = false;
  std::string topic_name_;
};

template <class T>
class Writer : public Endpoint {
 public:
  Writer(const Participant& pp, const std::string& dds_topic, const QosProfile& qos,
         const std::string& user_data = "")
      : Endpoint(pp, MessageType<T>::descriptor(), dds_topic, qos, user_data, true) {}
  /// Serialises and sends; false on a DDS error (never throws).
  bool write(const T& sample) const { return dds_write(ent_, &sample) >= 0; }
  /// The writer's instance handle (rmw_cyclonedds's request header guid for clients).
  dds_instance_handle_t instanceHandle() const {
    dds_instance_handle_t ih = 0;
    dds_get_instance_handle(ent_, &ih);
    return ih;
  }
};

template <class T>
class Reader : public Endpoint {
 public:
  Reader(const Participant& pp, const std::string& dds_topic, const QosProfile& qos,
         const std::string& user_data = "")
      : Endpoint(pp, MessageType<T>::descriptor(), dds_topic, qos, user_data, false) {
    cond_ = dds_create_readcondition(ent_, DDS_ANY_STATE);
    checkRc(cond_, "read condition on " + dds_topic);
  }
  /// Condition that triggers when samples are available (for WaitSet).
  dds_entity_t condition() const { return cond_; }

  /// Takes every available sample, oldest first (invalid samples, i.e. disposals, are skipped).
  /// source_ns, when given, receives each sample's source timestamp in the same order: the
  /// writer's clock when it wrote the sample (ns since the Unix epoch, as dds_time()).
  std::vector<Sample<T>> takeAll(std::vector<int64_t>* source_ns = nullptr) const {
    std::vector<Sample<T>> out;
    if (source_ns) source_ns->clear();
    constexpr int kBatch = 16;
    for (;;) {
      Sample<T> batch[kBatch];
      void* ptrs[kBatch];
      dds_sample_info_t info[kBatch];
      for (int i = 0; i < kBatch; ++i) ptrs[i] = batch[i].get();
      const dds_return_t n = dds_take(ent_, ptrs, info, kBatch, kBatch);
      if (n <= 0) break;
      for (int i = 0; i < n; ++i) {
        if (!info[i].valid_data) continue;
        out.push_back(std::move(batch[i]));
        if (source_ns) source_ns->push_back(info[i].source_timestamp);
      }
      if (n < kBatch) break;
    }
    return out;
  }

  /// Takes everything available and keeps the newest sample in *newest; returns how many valid
  /// samples were taken (0: none, *newest untouched).
  int takeNewest(Sample<T>* newest) const {
    std::vector<Sample<T>> all = takeAll();
    if (all.empty()) return 0;
    *newest = std::move(all.back());
    return static_cast<int>(all.size());
  }

 private:
  dds_entity_t cond_ = 0;
};

/// Waits on reader conditions and a guard condition that wake() triggers.
class WaitSet {
 public:
  explicit WaitSet(const Participant& pp);
  ~WaitSet();
  WaitSet(const WaitSet&) = delete;
  WaitSet& operator=(const WaitSet&) = delete;
  /// \param tag returned by wait() when `condition` triggers (must not be 0).
  void attach(dds_entity_t condition, intptr_t tag);
  /// Up to timeout_s (< 0: forever); the tags of the conditions that triggered (wake(): 0 is
  /// included and the guard is reset).
  std::vector<intptr_t> wait(double timeout_s);
  /// Makes a concurrent or the next wait() return at once. Thread-safe.
  void wake();

 private:
  dds_entity_t ws_ = 0, guard_ = 0;
};

/// Time in nanoseconds as DDS durations use it; negative timeout = infinite.
dds_duration_t toDdsDuration(double seconds);

}  // namespace refgrasp::dds
