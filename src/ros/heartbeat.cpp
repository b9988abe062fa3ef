// HeartbeatPublisher: see include/ddace/ros/heartbeat.h.
#include "ddace/ros/heartbeat.h"

#include <ddace/Heartbeat.h>

#include "params.h"

namespace ddace::nodes {

HeartbeatPublisher::HeartbeatPublisher(ros::NodeHandle& pnh, std::function<std::string()> problem)
    : problem_(std::move(problem)) {
  const double hz = rosparam::param(pnh, "heartbeat_rate_hz", kDefaultRateHz);
  if (!(hz > 0)) throw Error("parameter '" + pnh.resolveName("heartbeat_rate_hz") + "' must be positive");
  pub_ = pnh.advertise<ddace::Heartbeat>("heartbeat", 1);
  timer_ = pnh.createTimer(ros::Duration(1.0 / hz), [this](const ros::TimerEvent&) {
    ddace::Heartbeat h;
    h.header.stamp = ros::Time::now();
    if (problem_) h.problem = problem_();
    pub_.publish(h);
  });
}

}  // namespace ddace::nodes
