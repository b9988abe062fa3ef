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

#include <ddace/Heartbeat.h>

#include "params.h"

namespace ddace::ros_exec {

/// The default of every node's ~heartbeat_rate_hz (one place).
constexpr double kHeartbeatRateHz = 10.0;

class HeartbeatPublisher {
 public:
  /// `problem`: called at every beat; a non-empty answer says why the node cannot serve
  /// its role now (the coordinator then treats the role as lost).
  explicit HeartbeatPublisher(ros::NodeHandle& pnh, std::function<std::string()> problem = {})
      : problem_(std::move(problem)) {
    const double hz = rosparam::param(pnh, "heartbeat_rate_hz", kHeartbeatRateHz);
    if (!(hz > 0)) throw Error("parameter '" + pnh.resolveName("heartbeat_rate_hz") + "' must be positive");
    pub_ = pnh.advertise<ddace::Heartbeat>("heartbeat", 1);
    timer_ = pnh.createTimer(ros::Duration(1.0 / hz), [this](const ros::TimerEvent&) {
      ddace::Heartbeat h;
      h.header.stamp = ros::Time::now();
      if (problem_) h.problem = problem_();
      pub_.publish(h);
    });
  }

 private:
  std::function<std::string()> problem_;
  ros::Publisher pub_;
  ros::Timer timer_;
};

}  // namespace ddace::ros_exec
