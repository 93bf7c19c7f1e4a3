#include "robot/dds/service.h"

#include <cstdio>

namespace refgrasp::dds {

std::string ddsRequestTopicName(const std::string& ros_service) {
  return "rq" + ros_service + "Request";
}
std::string ddsReplyTopicName(const std::string& ros_service) {
  return "rr" + ros_service + "Reply";
}

std::string makeClientServiceId(const Participant& pp) {
  static std::atomic<uint32_t> counter{0};
  dds_guid_t guid;
  std::memset(&guid, 0, sizeof guid);
  dds_get_guid(pp.handle(), &guid);
  uint8_t id[16];
  std::memcpy(id, guid.v, 12);
  const uint32_t x = ++counter;
  for (int i = 0; i < 4; ++i) id[12 + i] = static_cast<uint8_t>(x >> (24 - 8 * i));
  std::string s;
  char buf[4];
  for (int i = 0; i < 16; ++i) {
    std::snprintf(buf, sizeof buf, i == 0 ? "%02x" : ".%x", id[i]);
    s += buf;
  }
  return s;
}

std::string userDataValue(const dds_qos_t* qos, const std::string& key) {
  void* ud = nullptr;
  size_t sz = 0;
  if (!qos || !dds_qget_userdata(qos, &ud, &sz) || !ud) return "";
  const std::string data(static_cast<const char*>(ud), sz);
  dds_free(ud);
  size_t pos = 0;
  while (pos < data.size()) {
    const size_t semi = data.find(';', pos);
    const std::string kv = data.substr(pos, semi == std::string::npos ? std::string::npos : semi - pos);
    const size_t eq = kv.find('=');
    if (eq != std::string::npos && kv.substr(0, eq) == key) return kv.substr(eq + 1);
    if (semi == std::string::npos) break;
    pos = semi + 1;
  }
  return "";
}

}  // namespace refgrasp::dds
