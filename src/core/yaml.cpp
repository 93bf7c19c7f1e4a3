#include "core/yaml.h"

#include <yaml-cpp/eventhandler.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "core/file.h"

namespace refgrasp {
namespace fs = std::filesystem;

namespace {

// Checks what yaml-cpp accepts silently: a key given twice (yaml-cpp keeps one of them), aliases
// (shared subtrees: exponential walks), keys that are not plain scalars, a second document.
class StrictEvents : public YAML::EventHandler {
 public:
  explicit StrictEvents(const std::string& path) : path_(path) {}

  void OnDocumentStart(const YAML::Mark&) override {}
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& m, YAML::anchor_t) override { element(m, nullptr, false); }
  void OnAlias(const YAML::Mark& m, YAML::anchor_t) override {
    throw ConfigError(path_, "line " + std::to_string(m.line + 1) +
                                 ": aliases (*name) are not supported");
  }
  void OnScalar(const YAML::Mark& m, const std::string&, YAML::anchor_t,
                const std::string& value) override {
    element(m, &value, false);
  }
  void OnSequenceStart(const YAML::Mark& m, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {
    element(m, nullptr, true);
    stack_.emplace_back(false);
  }
  void OnSequenceEnd() override { close(); }
  void OnMapStart(const YAML::Mark& m, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {
    element(m, nullptr, true);
    stack_.emplace_back(true);
  }
  void OnMapEnd() override { close(); }

 private:
  struct Level {
    explicit Level(bool is_map) : map(is_map) {}
    bool map;
    size_t index = 0;     // sequences: the current element
    bool at_key = true;   // mappings: the next node is a key
    std::string key;      // mappings: the current key
    std::map<std::string, int> key_lines;
  };

  // Dotted name of the innermost container's current element's parent.
  std::string where() const {
    std::string w;
    for (size_t i = 0; i + 1 < stack_.size(); ++i)
      w = stack_[i].map ? joinField(w, stack_[i].key) : w + "[" + std::to_string(stack_[i].index) + "]";
    return w;
  }

  // A node starts: a mapping key, or a value (a container's End completes it later).
  void element(const YAML::Mark& m, const std::string* scalar, bool container) {
    if (stack_.empty()) return;  // the document's root
    Level& l = stack_.back();
    if (l.map && l.at_key) {
      const std::string line = "line " + std::to_string(m.line + 1);
      const std::string at = where().empty() ? line : where() + ": " + line;
      if (container) throw ConfigError(path_, at + ": a key must be a plain name");
      if (!scalar) throw ConfigError(path_, at + ": empty key");
      const auto it = l.key_lines.find(*scalar);
      if (it != l.key_lines.end())
        throw ConfigError(path_, joinField(where(), *scalar),
                          "given twice (lines " + std::to_string(it->second) + " and " +
                              std::to_string(m.line + 1) + ")");
      l.key_lines[*scalar] = m.line + 1;
      l.key = *scalar;
      l.at_key = false;
      return;
    }
    if (!container) completed();
  }
  void close() {
    stack_.pop_back();
    completed();
  }
  void completed() {
    if (stack_.empty()) return;
    Level& l = stack_.back();
    if (l.map)
      l.at_key = true;
    else
      ++l.index;
  }

  std::string path_;
  std::vector<Level> stack_;
};

YAML::Node parseStrict(const std::string& path, const std::string& text) {
  try {
    std::istringstream in(text);
    YAML::Parser parser(in);
    StrictEvents events(path);
    int documents = 0;
    while (parser.HandleNextDocument(events))
      if (++documents > 1) throw ConfigError(path, "more than one YAML document (---)");
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(path, "invalid YAML at line " + std::to_string(e.mark.line + 1) + ": " +
                                e.msg);
  }
}

// Optimal string alignment distance (edits and adjacent transpositions).
size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1));
  for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (size_t i = 1; i <= a.size(); ++i)
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

bool toDouble(const YAML::Node& n, double* out) {
  if (!n.IsScalar()) return false;
  try {
    *out = n.as<double>();
  } catch (const YAML::Exception&) {
    return false;
  }
  return true;
}

}  // namespace

std::string joinField(const std::string& where, const std::string& key) {
  return where.empty() ? key : where + "." + key;
}

std::string didYouMean(const std::string& key, const std::set<std::string>& candidates) {
  const size_t max_edits = key.size() >= 6 ? 2 : 1;
  std::string best;
  size_t best_d = max_edits + 1;
  for (const std::string& c : candidates) {
    const size_t len_diff = c.size() > key.size() ? c.size() - key.size() : key.size() - c.size();
    if (len_diff > max_edits) continue;  // a lower bound of the distance
    const size_t d = editDistance(key, c);
    if (d < best_d) {
      best_d = d;
      best = c;
    }
  }
  if (best.empty())  // "frame_rate" for "frame_rate_hz", "matching" for "match"
    for (const std::string& c : candidates)
      if (std::min(c.size(), key.size()) >= 4 && (c.rfind(key, 0) == 0 || key.rfind(c, 0) == 0)) {
        best = c;
        break;
      }
  return best.empty() ? "" : " (did you mean " + best + "?)";
}

YamlFile::YamlFile(const std::string& path)
    : path_(path), root_(parseStrict(path, readRegularFile(path, kMaxConfigFileBytes))) {
  if (!root_.IsMap()) throw ConfigError(path, "expected a YAML mapping at the top level");
}

YamlFile YamlFile::fromText(const std::string& path, const std::string& text) {
  if (text.size() > kMaxConfigFileBytes)
    throw ConfigError(path, "more than " + std::to_string(kMaxConfigFileBytes) + " bytes");
  YamlFile f(path, parseStrict(path, text));
  if (!f.root_.IsMap()) throw ConfigError(path, "expected a YAML mapping at the top level");
  return f;
}

std::string YamlFile::dir() const { return fs::path(path_).parent_path().string(); }

std::string YamlFile::resolve(const std::string& rel) const {
  const fs::path p(rel);
  if (p.is_absolute() || dir().empty()) return p.string();
  return (fs::path(dir()) / p).string();
}

void YamlFile::noteKey(const YAML::Node& map, const std::string& key) const {
  const int pos = map.Mark().pos;
  if (pos >= 0) known_keys_[pos].insert(key);
}

YAML::Node YamlFile::get(const YAML::Node& node, const std::string& field) const {
  YAML::Node cur(node);  // a handle on the same node; reset() moves it (assignment would copy into it)
  size_t start = 0;
  while (true) {
    const size_t dot = field.find('.', start);
    const std::string key = field.substr(start, dot == std::string::npos ? dot : dot - start);
    if (!cur.IsDefined() || cur.IsNull()) return YAML::Node(YAML::NodeType::Undefined);
    if (!cur.IsMap()) {
      if (start == 0) return YAML::Node(YAML::NodeType::Undefined);
      fail(field.substr(0, start - 1), "expected a mapping");
    }
    noteKey(cur, key);
    const YAML::Node& const_cur = cur;  // const lookup: never inserts
    const YAML::Node next = const_cur[key];
    if (!next.IsDefined()) return YAML::Node(YAML::NodeType::Undefined);
    cur.reset(next);
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
  for (const std::string& k : keys) noteKey(node, k);
  for (const auto& kv : node) {
    const std::string k = kv.first.Scalar();
    if (!keys.count(k)) fail(joinField(where, k), "unknown field" + didYouMean(k, keys));
  }
}

void YamlFile::rejectUnknownIn(const YAML::Node& node, const std::string& where) const {
  if (node.IsMap()) {
    static const std::set<std::string> kNone;
    const auto it = known_keys_.find(node.Mark().pos);
    const std::set<std::string>& known = it == known_keys_.end() ? kNone : it->second;
    for (const auto& kv : node) {
      const std::string k = kv.first.Scalar();
      if (!known.count(k)) fail(joinField(where, k), "unknown field" + didYouMean(k, known));
      rejectUnknownIn(kv.second, joinField(where, k));
    }
  } else if (node.IsSequence()) {
    for (size_t i = 0; i < node.size(); ++i)
      rejectUnknownIn(node[i], where + "[" + std::to_string(i) + "]");
  }
}

void YamlFile::rejectUnknownFields() const {
  if (root_.Mark().pos < 0) return;  // built in memory: no positions to tell mappings apart
  rejectUnknownIn(root_, "");
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
  const YAML::Node n = get(node, field);
  if (!n.IsScalar()) fail(field, "expected true or false");
  try {
    return n.as<bool>();
  } catch (const YAML::Exception&) {
    fail(field, "expected true or false");
  }
}

std::string YamlFile::string(const YAML::Node& node, const std::string& field) const {
  const YAML::Node n = get(node, field);
  if (!n.IsDefined() || n.IsNull()) fail(field, "missing (expected a string)");
  if (!n.IsScalar()) fail(field, "expected a string");
  return n.Scalar();
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
  if (n >= 0 && seq.size() != static_cast<size_t>(n))
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
  onlyKeys(n, field, {"translation", "rotation_vector"});
  return Pose::fromRotationVector(vec3(node, field + ".rotation_vector"),
                                  vec3(node, field + ".translation"));
}

}  // namespace refgrasp
