// Checking YAML configuration files with file:line:column diagnostics.
//
// The readers of task.yaml, the Hamster config and the vision configs walk the
// yaml-cpp tree with one YamlChecker: each check records a Diagnostic at the node
// it concerns and tells the caller whether the value is usable, so one pass reports
// every problem of a file; throwIfErrors() then throws them all at once.
#pragma once

#include <initializer_list>
#include <set>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "ddace/common/error.h"

namespace ddace {

class YamlChecker {
 public:
  /// `file` is the path the diagnostics name (as given by the caller).
  explicit YamlChecker(std::string file) : file_(std::move(file)) {}

  /// Parses `text`. A syntax error is recorded ("YAML syntax error: ...", at its
  /// line and column) and an undefined node returned.
  YAML::Node parse(const std::string& text);

  /// Records `message` at `node` (line/column 0 when the node has no position).
  void error(const YAML::Node& node, const std::string& message);
  void error(const YAML::Mark& mark, const std::string& message);

  /// Records "unknown key 'k' in <where> (allowed: a, b, ...)" at every key of
  /// `map` that is not in `allowed`. Does nothing when `map` is not a mapping.
  void onlyKeys(const YAML::Node& map, const std::set<std::string>& allowed, const std::string& where);
  /// `map[key]` when `map` holds `key` with a value; else records "<where>missing key
  /// '<key>'" at `map` (a null value is no value), followed by " (<hint>)" when a hint is
  /// given (how to get the value), and returns an undefined node (false in a condition).
  /// Records nothing when `map` is not a mapping (expectMap says so).
  YAML::Node required(const YAML::Node& map, const std::string& key, const std::string& where = "",
                      const std::string& hint = "");
  /// True when `node` is a mapping; else records "<where> must be a mapping (key: value)".
  bool expectMap(const YAML::Node& node, const std::string& where);

  /// The scalar text of `node` into `out`; false (and "<what> must be a single
  /// value" recorded) when `node` is not a scalar. `out` is untouched on failure,
  /// as with every check below.
  bool scalar(const YAML::Node& node, const std::string& what, std::string& out);
  /// A scalar that is text: valid UTF-8 without control characters (what a YAML writer
  /// writes back unchanged); else records "<what> must be printable UTF-8 text (...)".
  bool text(const YAML::Node& node, const std::string& what, std::string& out);
  /// A finite number (the whole scalar, strtod syntax); else records
  /// "<what>: '<text>' is not a finite number".
  bool number(const YAML::Node& node, const std::string& what, double& out);
  /// A finite number in [lo, hi]; else records "<what> must be in <lo>..<hi> (got <text>)"
  /// (the bounds as %g prints them).
  bool number(const YAML::Node& node, const std::string& what, double lo, double hi, double& out);
  /// A number > 0; else records "<what> must be > 0 (got <text>)".
  bool positive(const YAML::Node& node, const std::string& what, double& out);
  /// A whole number in [lo, hi] (a fraction is an error, never truncated); else records
  /// "<what> must be an integer in <lo>..<hi> (got <text>)".
  bool integer(const YAML::Node& node, const std::string& what, long lo, long hi, long& out);
  bool integer(const YAML::Node& node, const std::string& what, int lo, int hi, int& out);
  /// true/True or false/False; else records "<what>: '<text>' is not true or false".
  bool boolean(const YAML::Node& node, const std::string& what, bool& out);

  /// True when every check passed. Each is evaluated (a braced list runs left to right,
  /// unlike `&&`), so one pass reports every problem: allOf({c.number(..), c.integer(..)}).
  static bool allOf(std::initializer_list<bool> checks) {
    bool all = true;
    for (const bool passed : checks) all = all && passed;
    return all;
  }

  const std::string& file() const { return file_; }
  const std::vector<Diagnostic>& errors() const { return errors_; }
  /// Throws ddace::Error with every recorded diagnostic, if any.
  void throwIfErrors() const;

 private:
  std::string file_;
  std::vector<Diagnostic> errors_;
};

}  // namespace ddace
