// Demonstration replay: a policy and a path source taken straight from one or more
// demonstrations, without learning. Used to check a set-up (camera, robots, followers,
// coordinator) before a model exists, as the "replay" baseline, and by the tests of the
// execution graph.
//
// Owns: the open-loop step sequence of a demonstration and the similarity retargeting
// of a demonstrated path to a new start and goal. Must not: learn anything (that is tgn/
// and gp/).
// Units: metres, table frame.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ddace/exec/path_follower.h"
#include "ddace/exec/simulator.h"
#include "ddace/task/demonstration.h"

namespace ddace::exec {

/// Step k of `demo` for a history of k+1 snapshots, END after the last step.
Decision replayDecision(const task::Demonstration& demo, const std::vector<task::Snapshot>& history);

/// Maps `demonstrated` (first point -> start, last point -> goal) by the rotation, uniform
/// scale and translation that takes its start-to-end chord onto start-to-goal. A
/// demonstrated path whose ends coincide (within 1 mm) is translated only. Throws
/// ddace::Error when `demonstrated` is empty.
std::vector<Eigen::Vector2d> retargetPath(const std::vector<Eigen::Vector2d>& demonstrated,
                                          const Eigen::Vector2d& start, const Eigen::Vector2d& goal);

/// The demonstrated trajectory of every motion key (first demonstration that has it).
class DemonstrationPaths {
 public:
  DemonstrationPaths(const task::TaskSpec& spec, const std::vector<task::Demonstration>& demos);
  /// The retargeted path of `token`'s key; stddev_m is all zero (one demonstration has no
  /// spread). Throws ddace::Error naming the key when no demonstration has it.
  PlannedPath generate(const task::Token& token, const Eigen::Vector2d& start, const Eigen::Vector2d& goal) const;
  size_t size() const { return paths_.size(); }

 private:
  task::TaskSpec spec_;
  std::map<std::string, std::vector<Eigen::Vector2d>> paths_;
};

}  // namespace ddace::exec
