// Reading ROS parameters without silent defaults, for every node (library ddace_ros).
//
// roscpp's NodeHandle::param() falls back to its default when a parameter is present
// but of another type (rate_hz: "fast"), so a typo in a launch file would run the node
// on the default. These helpers throw ddace::Error naming the resolved parameter
// instead; the nodes' main() logs it and exits non-zero. Types are roscpp's: a double
// also accepts an integer value, an int, bool or string does not accept the others.
#pragma once

#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include <ros/ros.h>

#include "ddace/common/error.h"

namespace ddace::rosparam {

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

}  // namespace ddace::rosparam
