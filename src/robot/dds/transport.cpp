#include "robot/dds/transport.h"

#include <chrono>
#include <cctype>
#include <cmath>
#include <thread>

#include "core/error.h"

namespace refgrasp::dds {

dds_return_t checkRc(dds_return_t rc, const std::string& what) {
  if (rc < 0) throw DdsError(what + ": " + dds_strretcode(rc));
  return rc;
}

std::string rosNameProblem(const std::string& name, bool is_namespace) {
  if (name.empty()) return "empty name";
  if (name[0] != '/') return "'" + name + "' is not fully qualified (must start with '/')";
  if (name == "/") return is_namespace ? "" : "'/' is not a topic name";
  if (name.back() == '/') return "'" + name + "' ends with '/'";
  size_t start = 1;
  while (start <= name.size()) {
    size_t end = name.find('/', start);
    if (end == std::string::npos) end = name.size();
    const std::string token = name.substr(start, end - start);
    if (token.empty()) return "'" + name + "' contains '//'";
    if (std::isdigit(static_cast<unsigned char>(token[0])))
      return "'" + name + "': token '" + token + "' starts with a digit";
    for (char c : token)
      if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_'))
        return "'" + name + "': character '" + std::string(1, c) +
               "' not allowed (letters, digits, '_' and '/')";
    if (token.find("__") != std::string::npos) return "'" + name + "' contains '__'";
    start = end + 1;
  }
  return "";
}

std::string joinRosName(const std::string& ns, const std::string& relative) {
  if (ns.empty() || ns == "/") return "/" + relative;
  return ns + "/" + relative;
}

std::string domainOrNamespaceProblem(int domain, const std::string& ns) {
  if (domain < 0 || domain > kMaxDomainId)
    return "--domain: " + std::to_string(domain) + " not in [0, " + std::to_string(kMaxDomainId) + "]";
  const std::string p = rosNameProblem(ns, true);
  return p.empty() ? "" : "--ns: " + p;
}

void checkDomainAndNamespace(int domain, const std::string& ns, const std::string& options) {
  refgrasp::check(domain >= 0 && domain <= kMaxDomainId, options + ".domain",
                  "must be in [0, " + std::to_string(kMaxDomainId) + "]");
  const std::string p = rosNameProblem(ns, true);
  refgrasp::check(p.empty(), options + ".ns", p);
}

std::string ddsTopicName(const std::string& ros_topic) { return "rt" + ros_topic; }

dds_duration_t toDdsDuration(double seconds) {
  if (seconds < 0 || !std::isfinite(seconds)) return DDS_INFINITY;
  return static_cast<dds_duration_t>(std::llround(seconds * 1e9));
}

dds_qos_t* makeQos(const QosProfile& p, const std::string& user_data) {
  dds_qos_t* q = dds_create_qos();
  if (p.reliability == Reliability::kReliable)
    dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_INFINITY);
  else
    dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, p.depth > 0 ? p.depth : 1);
  dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
  dds_qset_writer_data_lifecycle(q, false);
  const dds_data_representation_id_t xcdr1[] = {DDS_DATA_REPRESENTATION_XCDR1};
  dds_qset_data_representation(q, 1, xcdr1);
  if (!user_data.empty()) dds_qset_userdata(q, user_data.data(), user_data.size());
  return q;
}

Participant::Participant(int domain_id) : domain_(domain_id) {
  if (domain_id < 0 || domain_id > kMaxDomainId)
    throw DdsError("domain " + std::to_string(domain_id) + ": not in [0, " +
                   std::to_string(kMaxDomainId) + "]");
  pp_ = dds_create_participant(static_cast<dds_domainid_t>(domain_id), nullptr, nullptr);
  checkRc(pp_, "domain " + std::to_string(domain_id) + ": cannot create a participant" +
                   " (check CYCLONEDDS_URI)");
}

Participant::~Participant() {
  if (pp_ > 0) dds_delete(pp_);
}

Endpoint::Endpoint(const Participant& pp, const dds_topic_descriptor_t* desc,
                   const std::string& topic, const QosProfile& qos, const std::string& user_data,
                   bool writer)
    : writer_(writer), topic_name_(topic) {
  topic_ = dds_create_topic(pp.handle(), desc, topic.c_str(), nullptr, nullptr);
  checkRc(topic_, "topic " + topic + " (" + desc->m_typename + ")");
  dds_qos_t* q = makeQos(qos, user_data);
  ent_ = writer ? dds_create_writer(pp.handle(), topic_, q, nullptr)
                : dds_create_reader(pp.handle(), topic_, q, nullptr);
  dds_delete_qos(q);
  if (ent_ < 0) {
    const dds_return_t rc = ent_;
    dds_delete(topic_);
    checkRc(rc, std::string(writer ? "writer" : "reader") + " on " + topic);
  }
}

Endpoint::~Endpoint() {
  if (ent_ > 0) dds_delete(ent_);
  if (topic_ > 0) dds_delete(topic_);
}

int Endpoint::matched() const {
  if (writer_) {
    dds_publication_matched_status_t st;
    if (dds_get_publication_matched_status(ent_, &st) < 0) return 0;
    return static_cast<int>(st.current_count);
  }
  dds_subscription_matched_status_t st;
  if (dds_get_subscription_matched_status(ent_, &st) < 0) return 0;
  return static_cast<int>(st.current_count);
}

bool Endpoint::waitForMatch(int count, double timeout_s) const {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (matched() < count) {
    if (std::chrono::steady_clock::now() >= end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

WaitSet::WaitSet(const Participant& pp) {
  ws_ = checkRc(dds_create_waitset(pp.handle()), "waitset");
  guard_ = checkRc(dds_create_guardcondition(pp.handle()), "guard condition");
  checkRc(dds_waitset_attach(ws_, guard_, 0), "waitset attach");
}

WaitSet::~WaitSet() {
  if (ws_ > 0) {
    dds_waitset_detach(ws_, guard_);
    dds_delete(guard_);
    dds_delete(ws_);
  }
}

void WaitSet::attach(dds_entity_t condition, intptr_t tag) {
  checkRc(dds_waitset_attach(ws_, condition, tag), "waitset attach");
}

std::vector<intptr_t> WaitSet::wait(double timeout_s) {
  dds_attach_t triggered[16];
  const dds_return_t n = dds_waitset_wait(ws_, triggered, 16, toDdsDuration(timeout_s));
  std::vector<intptr_t> tags;
  for (dds_return_t i = 0; i < n && i < 16; ++i) {
    tags.push_back(triggered[i]);
    if (triggered[i] == 0) dds_set_guardcondition(guard_, false);
  }
  return tags;
}

void WaitSet::wake() { dds_set_guardcondition(guard_, true); }

}  // namespace refgrasp::dds
