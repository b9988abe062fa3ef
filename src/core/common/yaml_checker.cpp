#include "ddace/common/yaml_checker.h"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace ddace {

YAML::Node YamlChecker::parse(const std::string& text) {
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    error(e.mark, "YAML syntax error: " + e.msg);
    return YAML::Node(YAML::NodeType::Undefined);
  }
}

void YamlChecker::error(const YAML::Node& node, const std::string& message) {
  error(node.Mark(), message);
}

void YamlChecker::error(const YAML::Mark& m, const std::string& message) {
  errors_.push_back({file_, m.is_null() ? 0 : m.line + 1, m.is_null() ? 0 : m.column + 1, message});
}

void YamlChecker::onlyKeys(const YAML::Node& map, const std::set<std::string>& allowed, const std::string& where) {
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

YAML::Node YamlChecker::required(const YAML::Node& map, const std::string& key, const std::string& where,
                                 const std::string& hint) {
  if (!map.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
  const YAML::Node n = map[key];
  if (n.IsDefined() && !n.IsNull()) return n;
  error(map, where + "missing key '" + key + "'" + (hint.empty() ? "" : " (" + hint + ")"));
  return YAML::Node(YAML::NodeType::Undefined);
}

bool YamlChecker::expectMap(const YAML::Node& node, const std::string& where) {
  if (node.IsMap()) return true;
  error(node, where + " must be a mapping (key: value)");
  return false;
}

bool YamlChecker::scalar(const YAML::Node& node, const std::string& what, std::string& out) {
  if (!node.IsScalar()) {
    error(node, what + " must be a single value");
    return false;
  }
  out = node.Scalar();
  return true;
}

namespace {

/// Why `s` is not printable UTF-8 text, or "" when it is.
std::string notPrintableText(const std::string& s) {
  for (size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c < 0x80) {
      if (std::iscntrl(c)) return "a control character at byte " + std::to_string(i + 1);
      ++i;
      continue;
    }
    // Lead byte: length and the smallest code point of that length (no overlong forms).
    const int length = (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
    if (length == 0 || i + length > s.size()) return "not UTF-8 at byte " + std::to_string(i + 1);
    unsigned long code = c & (0x7F >> length);
    for (int k = 1; k < length; ++k) {
      const auto b = static_cast<unsigned char>(s[i + k]);
      if ((b >> 6) != 0x2) return "not UTF-8 at byte " + std::to_string(i + 1);
      code = (code << 6) | (b & 0x3F);
    }
    const unsigned long smallest[] = {0, 0, 0x80, 0x800, 0x10000};
    if (code < smallest[length] || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF))
      return "not UTF-8 at byte " + std::to_string(i + 1);
    if (code < 0xA0) return "a control character at byte " + std::to_string(i + 1);  // C1 controls
    i += length;
  }
  return "";
}

}  // namespace

bool YamlChecker::text(const YAML::Node& node, const std::string& what, std::string& out) {
  std::string s;
  if (!scalar(node, what, s)) return false;
  if (const std::string why = notPrintableText(s); !why.empty()) {
    error(node, what + " must be printable UTF-8 text (" + why + ")");
    return false;
  }
  out = s;
  return true;
}

bool YamlChecker::number(const YAML::Node& node, const std::string& what, double& out) {
  std::string s;
  if (!scalar(node, what, s)) return false;
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || *end != '\0' || !std::isfinite(v)) {
    error(node, what + ": '" + s + "' is not a finite number");
    return false;
  }
  out = v;
  return true;
}

bool YamlChecker::number(const YAML::Node& node, const std::string& what, double lo, double hi, double& out) {
  double v = 0;
  if (!number(node, what, v)) return false;
  if (v < lo || v > hi) {
    char range[64];
    std::snprintf(range, sizeof range, "%g..%g", lo, hi);
    error(node, what + " must be in " + range + " (got " + node.Scalar() + ")");
    return false;
  }
  out = v;
  return true;
}

bool YamlChecker::integer(const YAML::Node& node, const std::string& what, long lo, long hi, long& out) {
  double v = 0;
  if (!number(node, what, v)) return false;
  // Compared as doubles first: a huge value must not overflow the conversion.
  // A long's limits are not doubles: 2^63 rounds to LONG_MAX's double and would overflow.
  if (v != std::floor(v) || v < static_cast<double>(lo) || v > static_cast<double>(hi) ||
      !(v < 9223372036854775808.0 && v >= -9223372036854775808.0)) {
    error(node, what + " must be an integer in " + std::to_string(lo) + ".." + std::to_string(hi) + " (got " +
                    node.Scalar() + ")");
    return false;
  }
  out = static_cast<long>(v);
  return true;
}

bool YamlChecker::integer(const YAML::Node& node, const std::string& what, int lo, int hi, int& out) {
  long v = 0;
  if (!integer(node, what, static_cast<long>(lo), static_cast<long>(hi), v)) return false;
  out = static_cast<int>(v);
  return true;
}

bool YamlChecker::positive(const YAML::Node& node, const std::string& what, double& out) {
  double v = 0;
  if (!number(node, what, v)) return false;
  if (!(v > 0)) {
    error(node, what + " must be > 0 (got " + node.Scalar() + ")");
    return false;
  }
  out = v;
  return true;
}

bool YamlChecker::boolean(const YAML::Node& node, const std::string& what, bool& out) {
  std::string s;
  if (!scalar(node, what, s)) return false;
  if (s == "true" || s == "True") {
    out = true;
  } else if (s == "false" || s == "False") {
    out = false;
  } else {
    error(node, what + ": '" + s + "' is not true or false");
    return false;
  }
  return true;
}

void YamlChecker::throwIfErrors() const {
  if (!errors_.empty()) throw Error(errors_);
}

}  // namespace ddace
