#include "yaml_values.h"

#include <cmath>
#include <sstream>

namespace ddace::vision::detail {

YAML::Node parseRoot(YamlChecker& c, const std::string& text, const std::string& what) {
  const YAML::Node root = c.parse(text);
  c.throwIfErrors();
  if (root.IsNull()) c.error(YAML::Mark::null_mark(), "the file is empty");
  else c.expectMap(root, what);
  c.throwIfErrors();
  return root;
}

double numberOr(YamlChecker& c, const YAML::Node& map, const std::string& key, double fallback, double lo, double hi) {
  const YAML::Node n = map[key];
  if (!n.IsDefined() || n.IsNull()) return fallback;
  double v = 0;
  try {
    if (!n.IsScalar()) throw YAML::Exception(n.Mark(), "not a scalar");
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    c.error(n, "'" + key + "' must be a number");
    return fallback;
  }
  if (!std::isfinite(v) || v < lo || v > hi) {
    std::ostringstream os;
    os << "'" << key << "' = " << n.Scalar() << " is out of range [" << lo << ", " << hi << "]";
    c.error(n, os.str());
    return fallback;
  }
  return v;
}

int integerOr(YamlChecker& c, const YAML::Node& map, const std::string& key, int fallback, int lo, int hi) {
  const YAML::Node n = map[key];
  if (!n.IsDefined() || n.IsNull()) return fallback;
  int v = fallback;
  c.integer(n, "'" + key + "'", lo, hi, v);
  return v;
}

bool booleanOr(YamlChecker& c, const YAML::Node& map, const std::string& key, bool fallback) {
  const YAML::Node n = map[key];
  if (!n.IsDefined() || n.IsNull()) return fallback;
  try {
    if (!n.IsScalar()) throw YAML::Exception(n.Mark(), "not a scalar");
    return n.as<bool>();
  } catch (const YAML::Exception&) {
    c.error(n, "'" + key + "' must be true or false");
    return fallback;
  }
}

std::string stringOr(YamlChecker& c, const YAML::Node& map, const std::string& key, const std::string& fallback) {
  const YAML::Node n = map[key];
  if (!n.IsDefined() || n.IsNull()) return fallback;
  if (!n.IsScalar()) {
    c.error(n, "'" + key + "' must be a string");
    return fallback;
  }
  return n.Scalar();
}

}  // namespace ddace::vision::detail
