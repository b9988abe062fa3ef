// The perturbation suite of `ddace eval --perturb`: the learned task run through the
// coordinator (exec::Coordinator, the code that runs the robots) while the table changes
// under it once per trial, with and without recovery (CoordinatorConfig::max_replans).
//
// The table: every entity follows its segment's path ideally at the robots' cruise speed
// (points, no bodies: an object rides along its own path, as `--execution ideal` carries
// it), in control cycles of 50 Hz; the coordinator sees every entity's position every cycle
// and hears DONE when a segment's path is run. Once per trial, at a moment drawn from the
// seed (a step of the demonstration, and how far along one of its motions is: 20-80 %),
// one of these happens to a motion under way:
//   box_moved[:CM]    its target, a box, is put down CM cm away (default 6) in a drawn direction;
//   robot_pushed[:CM] its robot is pushed CM cm (default 5) across its path, and its follower
//                     fails the segment (it left its path);
//   robot_stalled[:S] its robot stands still S seconds (default 5), then goes on;
//   robot_lost        its robot stops and the tracker loses it for good.
// Kinds that fit no motion of a trial (box_moved in a task without boxes) leave it
// unperturbed; the report counts the trials perturbed.
//
// A trial succeeds when the run finished (the policy said END), it scores as a success
// against the test demonstration (eval/metrics.h: every step, END, every robot motion at
// its end point, the goal conditions) and no motion ended at an end point its target had
// left (more than the arrival radius + tolerance since the end point was fixed): a robot
// that went on to where a moved box was did not do its step.
//
// Owns: the perturbed runs and their report. Must not: decide, plan or recover (the
// coordinator does), score a trial (eval/metrics.h).
// Units: metres, seconds; table frame.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

#include "ddace/eval/metrics.h"
#include "ddace/exec/bodies_execution.h"
#include "ddace/exec/dispatch.h"
#include "ddace/pipeline/evaluation.h"

namespace ddace::pipeline {

enum class PerturbationKind : uint8_t { None = 0, BoxMoved, RobotPushed, RobotStalled, RobotLost };

struct Perturbation {
  PerturbationKind kind = PerturbationKind::None;
  double amount = 0;  ///< metres (box_moved, robot_pushed) or seconds (robot_stalled)
};
/// "box_moved", "box_moved:8" (cm), "robot_pushed[:CM]", "robot_stalled[:S]", "robot_lost".
/// Throws ddace::Error naming `what`, the text and the choices.
Perturbation parsePerturbation(const std::string& text, const std::string& what);
/// "box_moved 6 cm", "robot_stalled 5 s", ...
std::string toString(const Perturbation& p);

/// One run of a trial through the coordinator.
struct CoordinatedRun {
  exec::Trial trial;
  eval::TrialScore score;
  bool perturbed = false;         ///< the perturbation happened
  std::string what;               ///< "step 2, 40 %: B1 moved 6.0 cm"
  bool finished = false;          ///< the run finished (the policy said END)
  std::string reason;             ///< why it ended (the coordinator's reason)
  std::vector<std::string> lost;  ///< robots lost for good, with why (Coordinator::lostRobots)
  std::string failure;            ///< a finished run that failed: the first step that differs, or what did not hold
  int stale_ends = 0;             ///< motions that ended where their target had left
  int replans = 0, redecisions = 0;
  int precedence_violations = 0;
  int collisions = 0;              ///< with bodies
  std::vector<std::string> waits;  ///< who each token waited for (describeWaits)
  bool success = false;            ///< judged against the test demonstration (the scene before the hand)
  /// box_moved under the first step of a zoo task: judged instead by the
  /// steps the zoo's rule decides on the scene right after the hand (tasks::zooSteps) --
  /// every step, END, every motion at its end point, each object where those steps leave it,
  /// no collision: 1 done as the rule says there, 0 not (rule_failure says why), -1 not
  /// judged (another task or step, or a near tie there: no one answer). robot_lost in a zoo
  /// task: by the rule for the team without the lost robot on the scene right after the
  /// loss -- the run finished, every motion at its end point, each object where the rule
  /// leaves it, no collision (its steps are not compared: the run decided again from the
  /// step it was lost in); where the rule needs more robots than are left (it states nothing
  /// for the team left), aborted naming the lost robot or ended with every object where the
  /// demonstration left it. A finished run that lost a robot succeeds by this judgment.
  int by_rule = -1;
  std::string rule_failure;
  bool rule_tie = false;  ///< not judged: a decision of the rule there is a near tie
  double makespan_s = 0;  ///< from the first decision to the last token's end (simulated)
  /// The makespan async dispatch gives the run's steps were every token to take as long as
  /// it took in this run (exec::scheduleSteps): what any dispatch that never starts a token
  /// before its predecessors ended can reach, the tokens' times unchanged (0: not finished).
  double async_bound_s = 0;
};

/// Runs the model on `gt`'s start through the coordinator with `max_replans`, applying `p`
/// once at the moment drawn from `seed`; on points, or with `bodies` on the simulated table
/// (exec::BodiesExecution run live: each robot's own control cycle, segments starting
/// whenever the coordinator sends them). `speed_spread` (in [0, 1)): robots that differ in
/// speed, each moving at a factor drawn from [1 - speed_spread, 1] per trial (`seed`: the
/// same under either dispatch).
CoordinatedRun runCoordinated(const Model& model, const task::TaskSpec& spec, const task::Demonstration& gt,
                              const Perturbation& p, int max_replans, exec::DispatchMode dispatch, uint64_t seed,
                              const exec::BodiesExecutionParams* bodies = nullptr, double speed_spread = 0);

/// How a run that lost robots is judged in a task that states no goal condition: by the
/// demonstration's (`gt`) own ends, or the steps a zoo rule decides (`whose` names them). The
/// first object (task order) that is not at the last entity `gt` moved it to, unless that
/// entity is `lost`: "B1 did not end at G2, where the demonstration left it"; "" when every
/// one is. Without it a run that ended with a box mid-table would count as done.
std::string objectNotWhereDemonstrated(const task::TaskSpec& spec, const task::Demonstration& gt,
                                       const std::vector<Eigen::Vector2d>& final_positions,
                                       const std::vector<int>& lost, const std::string& whose = "the demonstration");

/// Per trial: unperturbed, perturbed without recovery (max_replans 0), perturbed with
/// (CoordinatorConfig::max_replans's default); all three with the same draw.
struct PerturbationReport {
  std::string task, variant, dispatch;
  Perturbation perturbation;
  std::vector<std::string> demos;
  std::vector<CoordinatedRun> unperturbed, without, with;
};
PerturbationReport evaluatePerturbed(const Model& model, const task::TaskDir& test, const Perturbation& p,
                                     exec::DispatchMode dispatch, uint64_t seed,
                                     const exec::BodiesExecutionParams* bodies = nullptr);
/// One line per trial, then per run: successes x/N, recoveries, mean makespan and time lost.
void printPerturbation(const PerturbationReport& r, std::ostream& out);
std::string perturbationJson(const PerturbationReport& r);

}  // namespace ddace::pipeline
