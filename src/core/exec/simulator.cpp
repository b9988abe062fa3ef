#include "ddace/exec/simulator.h"

#include "ddace/common/error.h"
#include "ddace/exec/scene.h"

namespace ddace::exec {

Trial runTrial(const task::TaskSpec& spec, const task::Demonstration& gt, const Policy& policy,
               const PathGenerator& paths, ExecutionModel& execution, const task::EndPointModel& end_points,
               const SimulatorOptions& options) {
  Trial trial;
  if (gt.rows() == 0) throw Error(Diagnostic{gt.source, 0, 0, "test demonstration has no rows"});
  const int n = static_cast<int>(spec.entities.size());
  std::vector<Eigen::Vector2d> pos;  // the scene, as the mock robots start it
  for (const Pose2D& p : startPoses(gt)) pos.push_back(p.position());
  const int max_steps = static_cast<int>(gt.steps.size()) + options.extra_steps;

  while (static_cast<int>(trial.predicted.size()) < max_steps) {
    trial.snapshots.push_back({0, false, pos});
    const Decision d = policy(trial.snapshots);
    if (d.end) {
      trial.snapshots.back().end = true;
      trial.ended = true;
      break;
    }
    task::Step step;
    step.tokens = d.tokens;
    const int k = static_cast<int>(trial.predicted.size());
    // Goals are fixed when the step is decided; all tokens then run concurrently.
    const std::vector<Eigen::Vector2d> decided = pos;
    for (const auto& token : d.tokens)
      if (token.entity < 0 || token.entity >= n || token.target >= n)
        throw Error("policy returned a token for a non-existent entity");
    for (size_t i = 0; i < d.tokens.size(); ++i) {
      const task::Token& token = d.tokens[i];
      ExecutedToken ex;
      ex.token = token;
      ex.step = k;
      ex.start = decided[token.entity];
      ex.goal = task::endPoint(spec, end_points, d.tokens, i, decided);
      if (token.isMotion()) {
        ex.planned = paths(token, ex.start, ex.goal);
        if (ex.planned.empty()) ex.planned = {ex.start, ex.goal};
        const bool robot = spec.entities[token.entity].kind == task::EntityKind::Robot;
        ex.executed = execution.follow(ex.planned, robot, token.entity);
        if (ex.executed.empty()) ex.executed = {ex.start};
        pos[token.entity] = ex.executed.back();
      } else {
        ex.executed = {ex.start};
      }
      trial.executed.push_back(std::move(ex));
    }
    trial.predicted.push_back(std::move(step));
  }
  trial.final_positions = pos;
  return trial;
}

}  // namespace ddace::exec
