#include "core/yaml.h"

#include <cmath>
#include <filesystem>
#include <fstream>

namespace refgrasp {
namespace fs = std::filesystem;

YamlFile::YamlFile(const std::string& path) : path_(path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw ConfigError(path, "file not found");
  if (fs::is_directory(path, ec)) throw ConfigError(path, "is a directory, expected a YAML file");
  std::ifstream in(path);
  if (!in) throw ConfigError(path, "cannot open for reading");
  try {
    root_ = YAML::Load(in);
  } catch (const YAML::Exception& e) {
    throw ConfigError(path, "invalid YAML at line " + std::to_string(e.mark.line + 1) + ": " +
                                e.msg);
  }
  if (!root_.IsMap()) throw ConfigError(path, "expected a YAML mapping at the top level");
}

std::string YamlFile::dir() const { return fs::path(path_).parent_path().string(); }

std::string YamlFile::resolve(const std::string& rel) const {
  const fs::path p(rel);
  if (p.is_absolute() || dir().empty()) return p.string();
  return (fs::path(dir()) / p).string();
}

YAML::Node YamlFile::get(const YAML::Node& node, const std::string& field) const {
  YAML::Node cur = YAML::Clone(node);
  size_t start = 0;
  while (true) {
    const size_t dot = field.find('.', start);
    const std::string key = field.substr(start, dot == std::string::npos ? dot : dot - start);
    if (!cur.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
    const YAML::Node next = cur[key];
    if (!next) return YAML::Node(YAML::NodeType::Undefined);
    cur = next;
    if (dot == std::string::npos) return cur;
    start = dot + 1;
  }
}

bool YamlFile::has(const YAML::Node& node, const std::string& field) const {
  const YAML::Node n = get(node, field);
  return n.IsDefined() && !n.IsNull();
}

void YamlFile::fail(const std::string& field, const std::string& problem) const {
  throw ConfigError(path_, field, problem);
}

void YamlFile::onlyKeys(const YAML::Node& node, const std::string& where,
                        const std::set<std::string>& keys) const {
  if (!node.IsMap()) fail(where, "expected a mapping");
  for (const auto& kv : node) {
    const std::string k = kv.first.as<std::string>();
    if (!keys.count(k)) fail(where.empty() ? k : where + "." + k, "unknown field");
  }
}

static bool toDouble(const YAML::Node& n, double* out) {
  if (!n.IsScalar()) return false;
  try {
    *out = n.as<double>();
  } catch (const YAML::Exception&) {
    return false;
  }
  return true;
}

double YamlFile::number(const YAML::Node& node, const std::string& field) const {
  const YAML::Node n = get(node, field);
  if (!n.IsDefined() || n.IsNull()) fail(field, "missing (expected a number)");
  double v = 0;
  if (!toDouble(n, &v)) fail(field, "expected a number");
  if (!std::isfinite(v)) fail(field, "must be finite");
  return v;
}

double YamlFile::number(const YAML::Node& node, const std::string& field, double fallback) const {
  return has(node, field) ? number(node, field) : fallback;
}

int YamlFile::integer(const YAML::Node& node, const std::string& field) const {
  const double v = number(node, field);
  if (v != std::floor(v) || std::abs(v) > 2e9) fail(field, "expected an integer");
  return static_cast<int>(v);
}

int YamlFile::integer(const YAML::Node& node, const std::string& field, int fallback) const {
  return has(node, field) ? integer(node, field) : fallback;
}

bool YamlFile::boolean(const YAML::Node& node, const std::string& field, bool fallback) const {
  if (!has(node, field)) return fallback;
  try {
    return get(node, field).as<bool>();
  } catch (const YAML::Exception&) {
    fail(field, "expected true or false");
  }
}

std::string YamlFile::string(const YAML::Node& node, const std::string& field) const {
  const YAML::Node n = get(node, field);
  if (!n.IsDefined() || n.IsNull()) fail(field, "missing (expected a string)");
  if (!n.IsScalar()) fail(field, "expected a string");
  return n.as<std::string>();
}

std::string YamlFile::string(const YAML::Node& node, const std::string& field,
                             const std::string& fallback) const {
  return has(node, field) ? string(node, field) : fallback;
}

std::vector<double> YamlFile::numbers(const YAML::Node& node, const std::string& field,
                                      int n) const {
  const YAML::Node seq = get(node, field);
  if (!seq.IsDefined() || seq.IsNull()) fail(field, "missing (expected a list of numbers)");
  if (!seq.IsSequence()) fail(field, "expected a list of numbers");
  if (n >= 0 && static_cast<int>(seq.size()) != n)
    fail(field, "expected " + std::to_string(n) + " numbers, got " + std::to_string(seq.size()));
  std::vector<double> out;
  for (size_t i = 0; i < seq.size(); ++i) {
    double v = 0;
    if (!toDouble(seq[i], &v)) fail(field, "element " + std::to_string(i) + " is not a number");
    if (!std::isfinite(v)) fail(field, "element " + std::to_string(i) + " is not finite");
    out.push_back(v);
  }
  return out;
}

Eigen::Vector3d YamlFile::vec3(const YAML::Node& node, const std::string& field) const {
  const auto v = numbers(node, field, 3);
  return Eigen::Vector3d(v[0], v[1], v[2]);
}

Pose YamlFile::pose(const YAML::Node& node, const std::string& field) const {
  const YAML::Node n = get(node, field);
  if (!n.IsDefined() || n.IsNull()) fail(field, "missing (expected translation and rotation_vector)");
  if (!n.IsMap()) fail(field, "expected a mapping with translation and rotation_vector");
  return Pose::fromRotationVector(vec3(node, field + ".rotation_vector"),
                                  vec3(node, field + ".translation"));
}

}  // namespace refgrasp
