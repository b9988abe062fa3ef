// Scripted truth for the vision rostests: R1..R4 drive on small circles, G1 stands
// still (the entities of config/markers.yaml). Time t in seconds from the first message.
#pragma once

#include <cmath>
#include <string>

#include <ros/ros.h>

#include "ddace/EntityArray.h"

namespace vision_test {

inline double wrap(double a) {
  return std::atan2(std::sin(a), std::cos(a));
}

/// Pose of entity `i` (0..4) at time t: x, y metres, theta radians.
inline void truePose(int i, double t, double& x, double& y, double& theta) {
  if (i == 4) {
    x = 0.85, y = 0.8, theta = 0;
    return;
  }
  const double w = 0.8 + 0.3 * i;  // rad/s on a 8 cm circle: 6..14 cm/s
  const double a = w * t + i;
  x = 0.2 + 0.2 * i + 0.08 * std::cos(a);
  y = 0.3 + 0.15 * (i % 2) + 0.08 * std::sin(a);
  theta = wrap(a + M_PI / 2);
}

inline const char* kNames[5] = {"R1", "R2", "R3", "R4", "G1"};

/// The truth at time t; R2 is under a hand (visible = false) while hide_r2.
inline ddace::EntityArray truthMsg(double t, const ros::Time& stamp, bool hide_r2 = false) {
  ddace::EntityArray msg;
  msg.header.stamp = stamp;
  msg.header.frame_id = "table";
  for (int i = 0; i < 5; ++i) {
    ddace::Entity e;
    e.name = kNames[i];
    e.kind = i == 4 ? "goal" : "robot";
    truePose(i, t, e.pose.x, e.pose.y, e.pose.theta);
    e.visible = !(hide_r2 && i == 1);
    e.last_seen = stamp;
    msg.entities.push_back(e);
  }
  return msg;
}

}  // namespace vision_test
