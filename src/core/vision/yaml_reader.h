// Reading the vision module's YAML files with file:line:column diagnostics
// (private to src/core/vision).
#pragma once

#include <set>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "ddace/common/error.h"

namespace ddace::vision::detail {

class YamlReader {
 public:
  explicit YamlReader(std::string file) : file_(std::move(file)) {}

  /// Parses `text`; a syntax error is recorded and an undefined node returned.
  YAML::Node parse(const std::string& text);

  void error(const YAML::Node& node, const std::string& message);
  void error(const YAML::Mark& mark, const std::string& message);
  /// Records an error for every key of `map` not in `allowed`.
  void onlyKeys(const YAML::Node& map, const std::set<std::string>& allowed, const std::string& where);
  /// True when `node` is a map (else records an error naming `where`).
  bool expectMap(const YAML::Node& node, const std::string& where);

  /// `map[key]` as a number/bool/string/int; `fallback` when absent; an error (and
  /// fallback) when present but of the wrong type or outside [lo, hi].
  double number(const YAML::Node& map, const std::string& key, double fallback,
                double lo = -1e300, double hi = 1e300);
  int integer(const YAML::Node& map, const std::string& key, int fallback, int lo = -2147483647,
              int hi = 2147483647);
  bool boolean(const YAML::Node& map, const std::string& key, bool fallback);
  std::string string(const YAML::Node& map, const std::string& key, const std::string& fallback);

  const std::string& file() const { return file_; }
  const std::vector<Diagnostic>& errors() const { return errors_; }
  /// Throws ddace::Error with every recorded diagnostic, if any.
  void throwIfErrors() const;

 private:
  std::string file_;
  std::vector<Diagnostic> errors_;
};

/// Reads a whole file; throws ddace::Error naming it when it cannot be read.
std::string readTextFile(const std::string& path);

}  // namespace ddace::vision::detail
