// The closed-loop simulator of docs/task-format.md, "Evaluation on a test set".
//
// One trial: every entity starts at the test demonstration's first row; then, until the
// policy predicts END or the number of predicted steps exceeds the ground truth's by 2:
// take a snapshot, ask the policy for the next step, generate a path for every motion
// token to its end point (task/end_point.h: from the positions when the step is decided
// and the learned end offsets -- at contact with a body, on a goal, a carrier behind its
// load and the load on the target), move each entity along its path with the execution
// model, and repeat. In-place tokens do not move. Objects move only through their own
// tokens, exactly like robots (ideal following): a carried load's path is its own and
// ends on the target, its carrier's ends behind it. The execution model gets every motion
// of a step at once (executeStep): one with bodies (exec/bodies_execution.h) moves them
// together on a simulated table and reports where every entity ended, the collisions and
// the closest approach; the others follow each path on its own.
//
// Owns: the loop and what happened in it. Must not: know how the policy or the paths are
// learned (they come in as functions), or compute metrics (eval/metrics.h does).
// Units: metres, table frame.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ddace/exec/clearance.h"
#include "ddace/exec/diff_drive.h"
#include "ddace/task/demonstration.h"
#include "ddace/task/end_point.h"

namespace ddace::exec {

using Path = std::vector<Eigen::Vector2d>;

/// The next step decided from the snapshot history (oldest first), or END.
struct Decision {
  bool end = false;
  std::vector<task::Token> tokens;
};
using Policy = std::function<Decision(const std::vector<task::Snapshot>& history)>;

/// A path from `start` to `goal` (the motion's end point) for a motion token (table frame,
/// metres).
using PathGenerator =
    std::function<Path(const task::Token& token, const Eigen::Vector2d& start, const Eigen::Vector2d& goal)>;

/// One motion token of a step as the execution model gets it.
struct StepMotion {
  size_t token = 0;  ///< index in the step's tokens
  int entity = -1;   ///< the entity that moves
  int target = -1;   ///< the token's target (the body a motion may end touching)
  bool robot = false;
  Path planned;  ///< from its start to its end point
};

/// What the execution model did with one step.
struct StepExecution {
  std::vector<Path> executed;  ///< per motion: the positions passed through, ending where it stopped
  /// Every entity's position at the end of the step, when the model moves others too (a
  /// pushed body); empty: only the movers moved, each to its executed path's end.
  std::vector<Eigen::Vector2d> positions;
  double duration_s = 0;              ///< simulated time the step took (0: the model has no time)
  std::vector<std::string> failures;  ///< why a motion stopped short, naming the robot (a deadlock)
};

/// What a model with bodies measured over a trial.
struct BodyReport {
  /// Collisions: two bodies that touched, except a motion touching its own target, a
  /// carrier touching its load and a motion touching the body its end point touches
  /// (exec/bodies_execution.h; docs/execution.md, "The closed-loop simulator with bodies").
  std::vector<BodyContact> collisions;
  ClosestApproach closest;  ///< the smallest gap between two bodies, the same exceptions
};

/// How the entities of a step follow their planned paths.
class ExecutionModel {
 public:
  virtual ~ExecutionModel() = default;
  virtual std::string name() const = 0;
  /// Whether the model has bodies (collisions and clearance are measured: report()).
  virtual bool bodies() const { return false; }
  /// Whether a carrier pushes its load and backs off it when done (bodies, loads not riding).
  virtual bool pushesLoads() const { return false; }
  /// A trial begins from every entity's `start` pose (the task's order).
  virtual void beginTrial(const task::TaskSpec& /*spec*/, const std::vector<Pose2D>& /*start*/) {}
  /// Runs every motion of one step (`tokens`, decided at `positions`). The default runs
  /// each motion alone through follow().
  virtual StepExecution executeStep(const task::TaskSpec& spec, const std::vector<task::Token>& tokens,
                                    const std::vector<Eigen::Vector2d>& positions,
                                    const std::vector<StepMotion>& motions);
  /// A model with bodies: the collisions and closest approach of the trial so far.
  virtual BodyReport report() const { return {}; }
  /// One entity along its path alone. Returns the positions it actually passed through,
  /// ending where it stopped. `is_robot`: objects are carried and always follow their
  /// path ideally.
  virtual Path follow(const Path& planned, bool is_robot, int entity) = 0;
};

/// The paper's model: every entity traverses its planned path exactly.
class IdealExecution : public ExecutionModel {
 public:
  std::string name() const override { return "ideal"; }
  Path follow(const Path& planned, bool, int) override { return planned; }
};

/// One motion or in-place token as it was executed in a trial.
struct ExecutedToken {
  task::Token token;
  int step = 0;                 ///< index of the predicted step
  Eigen::Vector2d start{0, 0};  ///< entity position when the step was decided
  /// The motion's end point (task/end_point.h) when the step was decided (= start when in place).
  Eigen::Vector2d goal{0, 0};
  Path planned;   ///< the generated path (empty for in-place tokens)
  Path executed;  ///< the positions actually passed through
};

struct Trial {
  std::vector<task::Step> predicted;      ///< the predicted steps, in order (keyframe_row unused)
  bool ended = false;                     ///< the policy predicted END
  std::vector<ExecutedToken> executed;    ///< every token of every predicted step
  std::vector<task::Snapshot> snapshots;  ///< the snapshots the policy saw
  std::vector<Eigen::Vector2d> final_positions;
  bool bodies = false;                ///< executed with bodies: `body_report` was measured
  BodyReport body_report;             ///< collisions and the closest approach (bodies only)
  double makespan_s = 0;              ///< simulated time of every step together (0: the model has no time)
  std::vector<std::string> failures;  ///< "step K: <why a motion stopped short>"
};

struct SimulatorOptions {
  int extra_steps = 2;  ///< stop after (ground-truth steps + extra_steps) predicted steps
};

/// Runs one trial from `ground_truth`'s first row; motions end where `end_points` says
/// (the model's, gp::PrimitiveLibrary::endPoints()). Throws ddace::Error when the policy
/// returns a token naming an entity that does not exist, or two tokens of one entity in a step.
Trial runTrial(const task::TaskSpec& spec, const task::Demonstration& ground_truth, const Policy& policy,
               const PathGenerator& paths, ExecutionModel& execution, const task::EndPointModel& end_points,
               const SimulatorOptions& options = {});

}  // namespace ddace::exec
