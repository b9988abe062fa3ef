// The simulator's second execution model: each robot is a differential-drive unicycle
// (exec/diff_drive.h) steered along its planned path by the same control law the ROS
// path_follower_node runs (exec/path_follower.h), from poses measured with Gaussian noise.
// Objects are carried and follow their paths ideally. A robot keeps its heading from one
// segment to the next; its first heading points along its first path.
// Units: metres, radians, seconds; table frame.
#pragma once

#include <map>

#include "ddace/exec/diff_drive.h"
#include "ddace/exec/path_follower.h"
#include "ddace/exec/simulator.h"

namespace ddace::exec {

class DiffDriveExecution : public ExecutionModel {
 public:
  /// `arrival_radius_m`: the task's (the control law stops within task::stopRadius() of the
  /// end point, with task::stopTolerance(noise_m)); `noise_m`: std-dev of measured x and y.
  DiffDriveExecution(double arrival_radius_m, double noise_m, uint64_t seed, const FollowerGains& gains = {},
                     const DiffDriveParams& robot = {});
  std::string name() const override { return "diffdrive"; }
  /// Follows until the control law reports done or a time limit (3x the path at cruise
  /// speed + 10 s) passes; returns the true positions at the control rate.
  Path follow(const Path& planned, bool is_robot, int entity) override;

 private:
  FollowerGains gains_;
  DiffDriveParams robot_;
  std::map<int, double> yaw_;  ///< heading each robot ended its last segment with
  uint64_t calls_ = 0;
};

}  // namespace ddace::exec
