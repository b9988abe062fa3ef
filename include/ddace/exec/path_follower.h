// The path-following control law of a differential-drive robot: pure pursuit with a
// progress term.
//
// The robot's progress along the path (arc-length fraction in [0, 1]) only moves
// forward, and the closest point is searched only in a window ahead of it, so a path that
// loops or passes close to itself (Task 4's spirals) is followed in order instead of
// being short-cut. The pursuit point lies `lookahead_m` of arc beyond the progress point;
// the curvature toward it (2 sin(alpha) / distance) sets the turn rate. Speed falls off
// near the goal and with the heading error; beyond `rotate_in_place_rad` of heading error
// the robot turns on the spot. Done = within `stop_radius_m` (the stop radius, task::stopRadius) of the final point
// with (almost) all of the path covered.
//
// Owns: the control law, progress and arrival. Must not: know about ROS, time-outs or
// stale poses (the node and the coordinator handle those).
// Units: metres, radians, m/s; table frame.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "ddace/exec/diff_drive.h"

namespace ddace::exec {

/// A planned path: points in order (table frame, metres) and optionally the per-point
/// standard deviation (metres, same length as points, or empty). Its progress
/// parameter is the arc-length fraction.
struct PlannedPath {
  std::vector<Eigen::Vector2d> points;
  std::vector<double> stddev_m;
};

/// Arc-length fraction of every point, [0] = 0, back() = 1 (all 0 for a path of
/// zero length). Used as the pose stamps of a progress-parameterised nav_msgs/Path.
std::vector<double> progressOf(const std::vector<Eigen::Vector2d>& points);

/// `n` >= 2 points evenly spaced in arc length along `path` (same ends); a path of one
/// point or zero length gives `n` copies of its first point. Per-point values in
/// `stddev_m` (same length as the path, or empty) are interpolated alike.
PlannedPath resampleByArcLength(const PlannedPath& path, int n);

struct FollowerGains {
  double cruise_speed_mps = 0.12;     ///< forward speed on a straight, far from the goal
  double min_speed_mps = 0.02;        ///< never slower than this while moving forward
  double lookahead_m = 0.04;          ///< arc length from the progress point to the pursuit point
  double slowdown_radius_m = 0.08;    ///< speed ramps down linearly inside this distance to the goal
  double rotate_in_place_rad = 1.0;   ///< heading errors beyond this turn on the spot
  double heading_gain = 3.0;          ///< rad/s per rad of heading error when turning on the spot
  double max_turn_rate_radps = 4.0;   ///< |yaw rate| limit
  double search_window_m = 0.10;      ///< progress advances at most this much arc per call
  double stop_radius_m = 0.03;        ///< the stop radius: done within this distance of the final point
  double wheel_base_m = 0.030;        ///< as DiffDriveParams::wheel_base_m
  double max_wheel_speed_mps = 0.20;  ///< both wheels are scaled together to stay within +-this

  /// Throws ddace::Error naming the first invalid gain.
  void validate() const;
};

/// Calls `visit(name, field)` for every gain, by the name config/execution.yaml gives it
/// (path_follower/gains): the one list the ROS parameters and `ddace eval --config` read.
template <typename Visit>
void visitParams(FollowerGains& g, Visit&& visit) {
  visit("cruise_speed_mps", g.cruise_speed_mps);
  visit("min_speed_mps", g.min_speed_mps);
  visit("lookahead_m", g.lookahead_m);
  visit("slowdown_radius_m", g.slowdown_radius_m);
  visit("rotate_in_place_rad", g.rotate_in_place_rad);
  visit("heading_gain", g.heading_gain);
  visit("max_turn_rate_radps", g.max_turn_rate_radps);
  visit("search_window_m", g.search_window_m);
  visit("stop_radius_m", g.stop_radius_m);
  visit("wheel_base_m", g.wheel_base_m);
  visit("max_wheel_speed_mps", g.max_wheel_speed_mps);
}

/// What the control law decided for one pose.
struct FollowerOutput {
  WheelSpeeds wheels;             ///< zero when done
  double progress = 0;            ///< arc-length fraction covered, [0, 1], never decreases
  double distance_to_goal_m = 0;  ///< straight-line distance to the final point
  double cross_track_m = 0;       ///< distance from the path at the progress point
  bool done = false;              ///< arrived: stays true until the next setPath()
};

class PathFollower {
 public:
  explicit PathFollower(const FollowerGains& gains = {});

  /// Starts following `path` from progress 0. Throws ddace::Error when the path has no
  /// point or a non-finite coordinate.
  void setPath(const PlannedPath& path);
  /// The stop radius from now on (the path kept). Throws ddace::Error unless positive.
  void setStopRadius(double stop_radius_m);
  /// Forgets the path; compute() then returns zero wheels.
  void clear();
  bool hasPath() const { return !points_.empty(); }

  /// One control cycle for the robot at `pose`.
  FollowerOutput compute(const Pose2D& pose);

  double progress() const { return total_m_ > 0 ? s_m_ / total_m_ : (done_ ? 1.0 : 0.0); }
  /// The path's last point: where the motion ends (no path: the origin).
  Eigen::Vector2d endPoint() const { return points_.empty() ? Eigen::Vector2d::Zero() : points_.back(); }
  /// The path's points (no path: none).
  const std::vector<Eigen::Vector2d>& points() const { return points_; }
  double lengthM() const { return total_m_; }
  const FollowerGains& gains() const { return gains_; }

 private:
  Eigen::Vector2d pointAt(double s_m) const;

  FollowerGains gains_;
  std::vector<Eigen::Vector2d> points_;
  std::vector<double> cum_m_;  ///< cumulative arc length at each point
  double total_m_ = 0;
  double s_m_ = 0;  ///< arc length of the progress point
  bool done_ = false;
};

}  // namespace ddace::exec
