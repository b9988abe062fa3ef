// Reading ROS parameters without silent defaults, for every node (library ddace_ros).
//
// roscpp's NodeHandle::param() falls back to its default when a parameter is present
// but of another type (rate_hz: "fast"), so a typo in a launch file would run the node
// on the default. These helpers throw ddace::Error naming the resolved parameter
// instead; the nodes' main() logs it and exits non-zero. Types are roscpp's: a double
// also accepts an integer value, an int, bool or string does not accept the others.
#pragma once

#include <initializer_list>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <type_traits>
#include <vector>

#include <ros/ros.h>

#include "ddace/common/error.h"

namespace ddace::rosparam {

/// Every parameter a node of this process asked for through these helpers, resolved
/// ("/path_follower/rate_hz"), set or not: what nodes::rejectUnknownParams() knows. Nodelets of one
/// manager share it; their private namespaces keep their names apart.
class ReadParams {
 public:
  static void add(const std::string& resolved) {
    const std::lock_guard<std::mutex> lock(mutex());
    names().insert(resolved);
  }
  /// True when `resolved` was read, or lies under one read as a whole (a map: "~scene").
  static bool known(const std::string& resolved) {
    const std::lock_guard<std::mutex> lock(mutex());
    for (const std::string& n : names())
      if (resolved == n || resolved.rfind(n + "/", 0) == 0) return true;
    return false;
  }
  /// The names read under `ns` + "/", without it, sorted.
  static std::vector<std::string> under(const std::string& ns) {
    const std::lock_guard<std::mutex> lock(mutex());
    std::vector<std::string> out;
    for (const std::string& n : names())
      if (n.rfind(ns + "/", 0) == 0) out.push_back(n.substr(ns.size() + 1));
    return out;
  }

 private:
  static std::set<std::string>& names() {
    static std::set<std::string> s;
    return s;
  }
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
};

/// What a parameter of type T must hold, for error messages ("a number", ...).
template <typename T>
std::string expectedType() {
  if constexpr (std::is_same_v<T, bool>) return "true or false";
  else if constexpr (std::is_same_v<T, int>) return "an integer";
  else if constexpr (std::is_floating_point_v<T>) return "a number";
  else if constexpr (std::is_same_v<T, std::string>) return "a string";
  else if constexpr (std::is_same_v<T, std::vector<std::string>>) return "a list of strings";
  else if constexpr (std::is_same_v<T, std::vector<double>>) return "a list of numbers";
  else return "another type";
}

/// The parameter when it is set, std::nullopt when it is not; throws ddace::Error
/// naming it when it is set to a value of the wrong type.
template <typename T>
std::optional<T> optionalParam(const ros::NodeHandle& nh, const std::string& name) {
  ReadParams::add(nh.resolveName(name));
  if (!nh.hasParam(name)) return std::nullopt;
  T value;
  if (!nh.getParam(name, value))
    throw Error("parameter '" + nh.resolveName(name) + "' has the wrong type (expected " + expectedType<T>() + ")");
  return value;
}

/// An optional parameter with its default; a present but mistyped value throws.
template <typename T>
T param(const ros::NodeHandle& nh, const std::string& name, const T& fallback) {
  return optionalParam<T>(nh, name).value_or(fallback);
}

/// A required non-empty string parameter (typically a file path); `what` says what it
/// is for. Throws ddace::Error naming it when missing, empty or mistyped.
inline std::string requireString(const ros::NodeHandle& nh, const std::string& name, const std::string& what) {
  const std::string value = param<std::string>(nh, name, "");
  if (value.empty()) throw Error("parameter " + nh.resolveName(name) + " is required: " + what);
  return value;
}

/// Names a node reads in other modes only, or that a library it uses reads
/// (diagnostic_updater's ~diagnostic_period): known to nodes::rejectUnknownParams(), so setting them
/// is no error.
inline void alsoReads(const ros::NodeHandle& nh, std::initializer_list<const char*> names) {
  for (const char* n : names) ReadParams::add(nh.resolveName(n));
}

}  // namespace ddace::rosparam
