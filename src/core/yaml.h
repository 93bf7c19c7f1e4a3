#pragma once
// Reading YAML files strictly, with one-line errors that name the file and the field.
//
// Strict: a key given twice, an alias (*name), a non-scalar key or a second document is an error
// at load; onlyKeys() and rejectUnknownFields() refuse fields the reader does not know, with a
// "did you mean" for a near miss of a known one; numbers must be finite.
#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/pose.h"

namespace refgrasp {

/// A parsed YAML file; every accessor throws ConfigError("<path>: <field>: <problem>").
class YamlFile {
 public:
  /// Throws ConfigError when the file is missing, not a regular file, larger than
  /// kMaxConfigFileBytes, not valid YAML, has duplicate keys or aliases, or is not a mapping.
  explicit YamlFile(const std::string& path);
  /// Parses `text` as if read from `path` (same checks; relative paths resolve against path's folder).
  static YamlFile fromText(const std::string& path, const std::string& text);
  YamlFile(const std::string& path, const YAML::Node& root) : path_(path), root_(root) {}

  const std::string& path() const { return path_; }
  const YAML::Node& root() const { return root_; }
  /// Directory of the file, for resolving relative paths ("" for the current directory).
  std::string dir() const;
  /// `rel` resolved against dir() unless absolute.
  std::string resolve(const std::string& rel) const;

  /// Field access by dotted name ("reference_pose.translation") relative to `node`; undefined
  /// when absent. A part of the name that is present but not a mapping fails "expected a mapping".
  /// Every key looked up is remembered as known for rejectUnknownFields().
  YAML::Node get(const YAML::Node& node, const std::string& field) const;
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
  /// A pose written as {translation: [x,y,z] (metres), rotation_vector: [rx,ry,rz] (radians)};
  /// other keys are unknown fields.
  Pose pose(const YAML::Node& node, const std::string& field) const;

  /// Fails "<where>: expected a mapping" unless node is a map, and "<where>.<key>: unknown field
  /// (did you mean <known>?)" for a key not in `keys`. where = "" for the top level.
  void onlyKeys(const YAML::Node& node, const std::string& where,
                const std::set<std::string>& keys) const;
  /// Call once the file is read: fails "<field>: unknown field (did you mean ...?)" for the first
  /// key (in file order) that no accessor looked up and no onlyKeys() list allowed.
  void rejectUnknownFields() const;

  [[noreturn]] void fail(const std::string& field, const std::string& problem) const;

 private:
  void noteKey(const YAML::Node& map, const std::string& key) const;
  void rejectUnknownIn(const YAML::Node& node, const std::string& where) const;

  std::string path_;
  YAML::Node root_;
  /// Keys looked up or allowed per mapping, by the mapping's offset in the file.
  mutable std::map<int, std::set<std::string>> known_keys_;
};

/// " (did you mean <c>?)" for the candidate nearest to `key` (a typo: at most 2 edits, or one a
/// prefix of the other), else "".
std::string didYouMean(const std::string& key, const std::set<std::string>& candidates);

/// "a.b" / "[i]" joins for error field names (where = "" at the top level).
std::string joinField(const std::string& where, const std::string& key);

}  // namespace refgrasp
