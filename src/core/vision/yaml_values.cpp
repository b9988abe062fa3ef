#include "yaml_values.h"

namespace ddace::vision::detail {

YAML::Node parseRoot(YamlChecker& c, const std::string& text, const std::string& what) {
  const YAML::Node root = c.parse(text);
  c.throwIfErrors();
  if (root.IsNull()) c.error(YAML::Mark::null_mark(), "the file is empty");
  else c.expectMap(root, what);
  c.throwIfErrors();
  return root;
}

namespace {

/// `map[key]` when it is given (neither absent nor null), else an undefined node.
YAML::Node given(const YAML::Node& map, const std::string& key) {
  const YAML::Node n = map[key];
  return n.IsDefined() && !n.IsNull() ? n : YAML::Node(YAML::NodeType::Undefined);
}

}  // namespace

// Each value is checked by the common YamlChecker, so the vision configs word their
// errors as every other reader does; a rejected value records its error and the
// fallback stands (throwIfErrors() then refuses the file).
double numberOr(YamlChecker& c, const YAML::Node& map, const std::string& key, double fallback, double lo, double hi) {
  double v = fallback;
  if (const YAML::Node n = given(map, key)) c.number(n, "'" + key + "'", lo, hi, v);
  return v;
}

int integerOr(YamlChecker& c, const YAML::Node& map, const std::string& key, int fallback, int lo, int hi) {
  int v = fallback;
  if (const YAML::Node n = given(map, key)) c.integer(n, "'" + key + "'", lo, hi, v);
  return v;
}

bool booleanOr(YamlChecker& c, const YAML::Node& map, const std::string& key, bool fallback) {
  bool v = fallback;
  if (const YAML::Node n = given(map, key)) c.boolean(n, "'" + key + "'", v);
  return v;
}

std::string stringOr(YamlChecker& c, const YAML::Node& map, const std::string& key, const std::string& fallback) {
  std::string v = fallback;
  if (const YAML::Node n = given(map, key)) c.scalar(n, "'" + key + "'", v);
  return v;
}

}  // namespace ddace::vision::detail
