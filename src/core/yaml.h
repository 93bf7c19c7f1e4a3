#pragma once
// Reading YAML files with one-line errors that name the file and the field.
#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <set>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/pose.h"

namespace refgrasp {

/// A parsed YAML file; every accessor throws ConfigError("<path>: <field>: <problem>").
class YamlFile {
 public:
  /// Throws ConfigError when the file is missing, unreadable or not valid YAML.
  explicit YamlFile(const std::string& path);
  YamlFile(const std::string& path, const YAML::Node& root) : path_(path), root_(root) {}

  const std::string& path() const { return path_; }
  const YAML::Node& root() const { return root_; }
  /// Directory of the file, for resolving relative paths ("" for the current directory).
  std::string dir() const;
  /// `rel` resolved against dir() unless absolute.
  std::string resolve(const std::string& rel) const;

  /// Field access by dotted name ("reference_pose.translation") relative to `node`.
  YAML::Node get(const YAML::Node& node, const std::string& field) const;  // may be undefined
  bool has(const YAML::Node& node, const std::string& field) const;

  double number(const YAML::Node& node, const std::string& field) const;
  double number(const YAML::Node& node, const std::string& field, double fallback) const;
  int integer(const YAML::Node& node, const std::string& field) const;
  int integer(const YAML::Node& node, const std::string& field, int fallback) const;
  bool boolean(const YAML::Node& node, const std::string& field, bool fallback) const;
  std::string string(const YAML::Node& node, const std::string& field) const;
  std::string string(const YAML::Node& node, const std::string& field,
                     const std::string& fallback) const;
  /// A list of exactly n finite numbers (n < 0: any length).
  std::vector<double> numbers(const YAML::Node& node, const std::string& field, int n = -1) const;
  Eigen::Vector3d vec3(const YAML::Node& node, const std::string& field) const;
  /// A pose written as {translation: [x,y,z] (metres), rotation_vector: [rx,ry,rz] (radians)}.
  Pose pose(const YAML::Node& node, const std::string& field) const;

  /// Fails "<where>: expected a mapping" unless node is a map, and "<where>.<key>: unknown field"
  /// for a key not in `keys` (typos). where = "" for the top level.
  void onlyKeys(const YAML::Node& node, const std::string& where,
                const std::set<std::string>& keys) const;

  [[noreturn]] void fail(const std::string& field, const std::string& problem) const;

 private:
  std::string path_;
  YAML::Node root_;
};

}  // namespace refgrasp
