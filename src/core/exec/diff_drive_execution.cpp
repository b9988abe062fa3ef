#include "ddace/exec/diff_drive_execution.h"

#include <algorithm>
#include <cmath>

#include "ddace/task/end_point.h"

namespace ddace::exec {

DiffDriveExecution::DiffDriveExecution(double arrival_radius_m, double noise_m, uint64_t seed,
                                       const FollowerGains& gains, const DiffDriveParams& robot)
    : gains_(gains), robot_(robot) {
  // The one stop rule with this model's own noise as the tolerance.
  gains_.stop_radius_m = task::stopRadius(arrival_radius_m, task::stopTolerance(noise_m));
  robot_.position_noise_m = noise_m;
  robot_.seed = seed;
  gains_.validate();
  robot_.validate();
}

Path DiffDriveExecution::follow(const Path& planned, bool is_robot, int entity) {
  if (!is_robot || planned.size() < 2) return planned;
  auto it = yaw_.find(entity);
  if (it == yaw_.end()) {
    const Eigen::Vector2d d = planned[std::min<size_t>(5, planned.size() - 1)] - planned.front();
    it = yaw_.emplace(entity, std::atan2(d.y(), d.x())).first;
  }
  DiffDriveParams params = robot_;
  params.seed = robot_.seed * 1000003ULL + (++calls_);  // fresh, reproducible noise per segment
  DiffDriveModel robot(params, Pose2D{planned.front().x(), planned.front().y(), it->second});
  PathFollower follower(gains_);
  follower.setPath(PlannedPath{planned, {}});
  const double limit_s = 3.0 * follower.lengthM() / gains_.cruise_speed_mps + 10.0;
  Path executed{planned.front()};
  while (robot.time() < limit_s) {
    const FollowerOutput out = follower.compute(robot.measuredPose());
    if (out.done) break;
    robot.command(out.wheels, robot.time());
    robot.step();
    executed.push_back(robot.truePose().position());
  }
  it->second = robot.truePose().yaw;
  return executed;
}

}  // namespace ddace::exec
