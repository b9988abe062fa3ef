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
// ends on the target, its carrier's ends behind it.
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

/// How an entity follows a planned path. Returns the positions it actually passed
/// through, ending where it stopped.
class ExecutionModel {
 public:
  virtual ~ExecutionModel() = default;
  virtual std::string name() const = 0;
  /// `is_robot`: objects are carried and always follow their path ideally.
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
};

struct SimulatorOptions {
  int extra_steps = 2;  ///< stop after (ground-truth steps + extra_steps) predicted steps
};

/// Runs one trial from `ground_truth`'s first row; motions end where `end_points` says
/// (the model's, gp::PrimitiveLibrary::endPoints()). Throws ddace::Error when the policy
/// returns a token naming an entity that does not exist.
Trial runTrial(const task::TaskSpec& spec, const task::Demonstration& ground_truth, const Policy& policy,
               const PathGenerator& paths, ExecutionModel& execution, const task::EndPointModel& end_points,
               const SimulatorOptions& options = {});

}  // namespace ddace::exec
