// refgrasp's own interface exists twice: as ROS 2 .msg/.srv files (src/robot/dds/ros/refgrasp_msgs,
// for ROS users) and as the hand-written IDL the component is built from. Both must list the same
// fields in the same order with the same types, and the service must keep its documented
// contract (docs/component.md).
#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <sstream>

namespace {

const std::string kSource = REFGRASP_SOURCE_DIR;

std::string read(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

using Fields = std::vector<std::pair<std::string, std::string>>;  // (ROS type, name)

/// Fields of a .msg text (one part of a .srv): "type name" lines, comments dropped.
Fields msgFields(const std::string& text) {
  Fields f;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    line = line.substr(0, line.find('#'));
    std::istringstream l(line);
    std::string type, name;
    if (l >> type >> name) f.emplace_back(type, name);
  }
  return f;
}

/// Fields of an IDL struct in ROS terms; the rmw request header (RequestHeader_) is skipped.
Fields idlFields(const std::string& idl, const std::string& name) {
  const std::regex re("struct " + name + " \\{([^}]*)\\};");
  std::smatch m;
  if (!std::regex_search(idl, m, re)) return {};
  Fields f;
  std::istringstream in(m[1].str());
  std::string line;
  const std::map<std::string, std::string> types = {
      {"std_msgs::msg::dds_::Header_", "std_msgs/Header"}, {"string", "string"}, {"boolean", "bool"},
      {"double", "float64"}, {"int32", "int32"}};
  const std::regex field(R"(^\s*([A-Za-z_:][A-Za-z0-9_:]*)\s+([a-z_]+)(\[(\d+)\])?;)");
  while (std::getline(in, line)) {
    std::smatch fm;
    if (!std::regex_search(line, fm, field) || fm[1] == "RequestHeader_") continue;
    const auto t = types.find(fm[1]);
    std::string type = t == types.end() ? "?" + fm[1].str() : t->second;
    if (fm[4].matched) type += "[" + fm[4].str() + "]";
    f.emplace_back(type, fm[2]);
  }
  return f;
}

}  // namespace

TEST(InterfaceFiles, IdlAndRosDefinitionsAgree) {
  const std::string idl = read(kSource + "/src/robot/dds/idl/refgrasp_msgs.idl");
  const std::string pkg = kSource + "/src/robot/dds/ros/refgrasp_msgs";
  const Fields info = msgFields(read(pkg + "/msg/ObjectInfo.msg"));
  ASSERT_EQ(info.size(), 6u);
  EXPECT_EQ(idlFields(idl, "ObjectInfo_"), info);
  const Fields corners = msgFields(read(pkg + "/msg/ObjectCorners.msg"));
  ASSERT_EQ(corners.size(), 7u);
  EXPECT_EQ(idlFields(idl, "ObjectCorners_"), corners);
  // The public contract (docs/component.md), literally.
  EXPECT_EQ(corners, (Fields{{"std_msgs/Header", "header"}, {"string", "object_name"}, {"bool", "found"},
                             {"bool", "tracked"}, {"float64[8]", "corners"}, {"float64[9]", "homography"},
                             {"int32", "inliers"}}));

  const std::string srv = read(pkg + "/srv/Detect.srv");
  const size_t sep = srv.find("\n---\n");
  ASSERT_NE(sep, std::string::npos);
  const Fields request = msgFields(srv.substr(0, sep)), response = msgFields(srv.substr(sep + 5));
  EXPECT_EQ(idlFields(idl, "Detect_Request_"), request);
  EXPECT_EQ(idlFields(idl, "Detect_Response_"), response);
  // The public contract (docs/component.md), literally.
  EXPECT_EQ(request, (Fields{{"string", "object_name"}, {"float64", "timeout_s"}}));
  EXPECT_EQ(response, (Fields{{"bool", "found"}, {"float64[9]", "rotation"}, {"float64[3]", "translation"},
                              {"string", "error"}}));
}
