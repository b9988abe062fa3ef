// The scene a run starts from and how objects move in it: shared by the closed-loop
// simulator (exec/simulator.h) and the mock robot node, so both start from the same
// poses and carry objects the same way.
//
// Objects move only through their own motion tokens, following their planned path
// ideally (the task format's execution model), here in time at a constant speed.
// Units: metres, radians, seconds; table frame.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "ddace/exec/diff_drive.h"
#include "ddace/task/demonstration.h"
#include "ddace/task/task_spec.h"

namespace ddace::exec {

/// Every entity's pose at the demonstration's first row, facing the direction in which
/// it first moves more than `min_motion_m` (yaw 0 when it never moves). Throws
/// ddace::Error for a demonstration without rows.
std::vector<Pose2D> startPoses(const task::Demonstration& demo, double min_motion_m = 0.01);

/// A start pose given for an entity by name; `where` names its source for errors (e.g.
/// "parameter '/mock_robots/scene/R1'").
struct NamedPose {
  std::string name;
  Pose2D pose;
  std::string where;
};

/// Every entity's start pose in `spec`'s order: `base` (a demonstration's startPoses, or
/// empty for none) with each of `named` put over it. Throws ddace::Error naming the
/// `where` of a name that is no entity of the task, for a `base` of the wrong size, and
/// for the first entity left without a pose (`missing_hint` says how to give one).
std::vector<Pose2D> sceneStartPoses(const task::TaskSpec& spec, const std::vector<Pose2D>& base,
                                    const std::vector<NamedPose>& named, const std::string& missing_hint);

/// An object carried along a planned path at a constant speed (ideal following).
class CarriedObject {
 public:
  /// Starts at `from` (where the object is; replaces the path's first point) along `path`.
  /// Throws ddace::Error for an empty path or a speed that is not positive.
  CarriedObject(std::vector<Eigen::Vector2d> path, const Eigen::Vector2d& from, double speed_mps);
  /// Moves on for `dt_s`; returns the new position.
  Eigen::Vector2d advance(double dt_s);
  Eigen::Vector2d position() const;
  bool arrived() const { return s_m_ >= cum_m_.back(); }
  double progress() const { return cum_m_.back() > 0 ? std::min(1.0, s_m_ / cum_m_.back()) : 1.0; }
  const Eigen::Vector2d& goal() const { return path_.back(); }
  const Eigen::Vector2d& start() const { return path_.front(); }

 private:
  std::vector<Eigen::Vector2d> path_;
  std::vector<double> cum_m_;
  double speed_mps_;
  double s_m_ = 0;
};

}  // namespace ddace::exec
