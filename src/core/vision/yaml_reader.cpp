#include "yaml_reader.h"

#include <cmath>
#include <fstream>
#include <sstream>

namespace ddace::vision::detail {

YAML::Node YamlReader::parse(const std::string& text) {
  try {
    YAML::Node root = YAML::Load(text);
    if (!root.IsDefined() || root.IsNull()) {
      errors_.push_back({file_, 0, 0, "the file is empty"});
      return YAML::Node(YAML::NodeType::Undefined);
    }
    return root;
  } catch (const YAML::Exception& e) {
    errors_.push_back({file_, e.mark.line + 1, e.mark.column + 1, "YAML syntax: " + e.msg});
    return YAML::Node(YAML::NodeType::Undefined);
  }
}

void YamlReader::error(const YAML::Node& node, const std::string& message) {
  const YAML::Mark m = node.Mark();
  errors_.push_back({file_, m.is_null() ? 0 : m.line + 1, m.is_null() ? 0 : m.column + 1, message});
}

void YamlReader::error(const YAML::Mark& m, const std::string& message) {
  errors_.push_back({file_, m.is_null() ? 0 : m.line + 1, m.is_null() ? 0 : m.column + 1, message});
}

void YamlReader::onlyKeys(const YAML::Node& map, const std::set<std::string>& allowed, const std::string& where) {
  if (!map.IsMap()) return;
  for (const auto& kv : map) {
    const std::string key = kv.first.IsScalar() ? kv.first.Scalar() : std::string("?");
    if (!allowed.count(key)) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      error(kv.first, "unknown key '" + key + "' in " + where + " (allowed: " + list + ")");
    }
  }
}

bool YamlReader::expectMap(const YAML::Node& node, const std::string& where) {
  if (node.IsMap()) return true;
  error(node, where + " must be a mapping (key: value)");
  return false;
}

double YamlReader::number(const YAML::Node& map, const std::string& key, double fallback, double lo, double hi) {
  const YAML::Node n = map[key];
  if (!n.IsDefined() || n.IsNull()) return fallback;
  double v = 0;
  try {
    if (!n.IsScalar()) throw YAML::Exception(n.Mark(), "not a scalar");
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    error(n, "'" + key + "' must be a number");
    return fallback;
  }
  if (!std::isfinite(v) || v < lo || v > hi) {
    std::ostringstream os;
    os << "'" << key << "' = " << n.Scalar() << " is out of range [" << lo << ", " << hi << "]";
    error(n, os.str());
    return fallback;
  }
  return v;
}

int YamlReader::integer(const YAML::Node& map, const std::string& key, int fallback, int lo, int hi) {
  const YAML::Node n = map[key];
  if (!n.IsDefined() || n.IsNull()) return fallback;
  long v = 0;
  try {
    if (!n.IsScalar()) throw YAML::Exception(n.Mark(), "not a scalar");
    v = n.as<long>();
  } catch (const YAML::Exception&) {
    error(n, "'" + key + "' must be an integer");
    return fallback;
  }
  if (v < lo || v > hi) {
    error(n, "'" + key + "' = " + n.Scalar() + " is out of range [" + std::to_string(lo) + ", " +
                 std::to_string(hi) + "]");
    return fallback;
  }
  return static_cast<int>(v);
}

bool YamlReader::boolean(const YAML::Node& map, const std::string& key, bool fallback) {
  const YAML::Node n = map[key];
  if (!n.IsDefined() || n.IsNull()) return fallback;
  try {
    if (!n.IsScalar()) throw YAML::Exception(n.Mark(), "not a scalar");
    return n.as<bool>();
  } catch (const YAML::Exception&) {
    error(n, "'" + key + "' must be true or false");
    return fallback;
  }
}

std::string YamlReader::string(const YAML::Node& map, const std::string& key, const std::string& fallback) {
  const YAML::Node n = map[key];
  if (!n.IsDefined() || n.IsNull()) return fallback;
  if (!n.IsScalar()) {
    error(n, "'" + key + "' must be a string");
    return fallback;
  }
  return n.Scalar();
}

void YamlReader::throwIfErrors() const {
  if (!errors_.empty()) throw Error(errors_);
}

std::string readTextFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(Diagnostic{path, 0, 0, "cannot read the file (does it exist?)"});
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

}  // namespace ddace::vision::detail
