// ~heartbeat (ddace/Heartbeat) of a node that serves a role of the execution graph (the
// sequence, path and recorder nodes; the followers' heartbeat is their wheel stream).
//
// Published by a timer on the node's callback queue, the one its requests are served on:
// when that thread hangs the heartbeat stops, and the coordinator's role watch notices it
// (coordinator/roles/heartbeat_timeout_s). Parameter ~heartbeat_rate_hz (Hz, > 0).
#pragma once

#include <functional>
#include <string>

#include <ros/ros.h>

namespace ddace::nodes {

class HeartbeatPublisher {
 public:
  /// The default of every node's ~heartbeat_rate_hz (config/execution.yaml).
  static constexpr double kDefaultRateHz = 10.0;

  /// Reads ~heartbeat_rate_hz from `pnh` (throws ddace::Error naming it when not positive)
  /// and starts beating. `problem`: asked at every beat; a non-empty answer says why the
  /// node cannot serve its role now (the coordinator then treats the role as lost).
  explicit HeartbeatPublisher(ros::NodeHandle& pnh, std::function<std::string()> problem = {});

 private:
  std::function<std::string()> problem_;
  ros::Publisher pub_;
  ros::Timer timer_;
};

}  // namespace ddace::nodes
