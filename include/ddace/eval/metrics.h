// The evaluation metrics of docs/task-format.md: OSR, SSR, GCR and FD, per trial
// and aggregated over a test set.
//
// Owns: scoring a simulated (or rolled-out) trial against its ground-truth demonstration.
// Must not: run anything (exec/simulator.h does). Units: metres; FD is dimensionless
// (measured in the ground-truth segment's canonical frame, where start-goal distance = 1).
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include "ddace/exec/simulator.h"
#include "ddace/task/task_dir.h"

namespace ddace::eval {

/// With bodies: an object whose executed motion ended outside the arrival radius of its end point.
struct ObjectLeftShort {
  int step = 0;           ///< index of the predicted step
  std::string token;      ///< task::tokenKey of its motion ("B1:carry:G1")
  double distance_m = 0;  ///< from where it ended to its end point
  /// "step 2: B1:carry:G1 left 6.2 cm short of its end"
  std::string describe() const;
};

struct TrialScore {
  std::string demo;                  ///< test demonstration file
  int gt_steps = 0;                  ///< ground-truth steps
  int predicted_steps = 0;           ///< steps the policy predicted
  int correct_steps = 0;             ///< ground-truth steps whose token set was predicted at the same index
  bool ended_correctly = false;      ///< END right after the last ground-truth step
  int gt_robot_motions = 0;          ///< ground-truth motion tokens of robots
  int achieved_robot_motions = 0;    ///< ... executed (same entity, action, target) and arrived
  bool goal_conditions_hold = true;  ///< every goal_conditions entry at the end (task::goalConditionMet)
  /// With bodies: the objects whose executed motion did not arrive (a load its carrier pushed
  /// and left short of its end point fails the trial, goal condition or not).
  std::vector<ObjectLeftShort> objects_left_short;
  std::vector<double> fd;  ///< normalised Fréchet distance per matched motion token
  /// Executed with bodies (exec::Trial::bodies): the collisions count against success.
  bool bodies = false;
  int collisions = 0;            ///< bodies that touched (exec::BodyReport), 0 without bodies
  double min_clearance_m = NAN;  ///< smallest gap between two bodies (NaN: not measured)
  double makespan_s = 0;         ///< simulated time of the trial's steps (0: the model has no time)
  bool success = false;          ///< OSR: all of the above, and no collision

  double ssr() const { return gt_steps ? static_cast<double>(correct_steps) / gt_steps : 1.0; }
  double gcr() const { return gt_robot_motions ? static_cast<double>(achieved_robot_motions) / gt_robot_motions : 1.0; }
  double meanFd() const;  ///< NaN when no motion token matched
  bool objectsArrived() const { return objects_left_short.empty(); }
};

/// Scores one trial. `use_executed_paths`: FD on the executed positions instead of the
/// generated path (for a baseline that rolls out its own trajectories, both are the same).
TrialScore scoreTrial(const task::TaskSpec& spec, const task::Demonstration& ground_truth, const exec::Trial& trial,
                      bool use_executed_paths = false);

struct Summary {
  int trials = 0;
  double osr = 0;  ///< fraction of successful trials
  double ssr = 0;  ///< correct steps / ground-truth steps, over all trials
  double gcr = 0;  ///< achieved robot motions / ground-truth robot motions, over all trials
  double fd = 0;   ///< mean over every matched motion token of every trial (NaN when none)
  int fd_tokens = 0;
  bool bodies = false;  ///< the trials had bodies
  int collisions = 0;   ///< over all trials
  int trials_with_collision = 0;
  double min_clearance_m = NAN;  ///< the smallest over all trials (NaN: not measured)
  double makespan_s = 0;         ///< mean over the trials
};

Summary summarise(const std::vector<TrialScore>& scores);

}  // namespace ddace::eval
