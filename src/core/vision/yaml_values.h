// The vision configs' optional values: `map[key]` with a fallback and a range,
// checked with the common YamlChecker (private to src/core/vision).
#pragma once

#include <limits>
#include <string>

#include "ddace/common/yaml_checker.h"

namespace ddace::vision::detail {

/// The root mapping of a config file: parses `text` and throws ddace::Error when it
/// is not valid YAML, is empty, or is not a mapping (named `what`).
YAML::Node parseRoot(YamlChecker& c, const std::string& text, const std::string& what);

/// `map[key]` as a number/integer/bool/string; `fallback` when absent or null; an
/// error recorded (and `fallback` returned) when present but of the wrong type or
/// outside [lo, hi], worded by YamlChecker ("'key' must be in lo..hi (got x)", ...).
double numberOr(YamlChecker& c, const YAML::Node& map, const std::string& key, double fallback,
                double lo = -std::numeric_limits<double>::infinity(),
                double hi = std::numeric_limits<double>::infinity());
int integerOr(YamlChecker& c, const YAML::Node& map, const std::string& key, int fallback, int lo = -2147483647,
              int hi = 2147483647);
bool booleanOr(YamlChecker& c, const YAML::Node& map, const std::string& key, bool fallback);
std::string stringOr(YamlChecker& c, const YAML::Node& map, const std::string& key, const std::string& fallback);

}  // namespace ddace::vision::detail
