#include "ddace/exec/simulator.h"

#include "ddace/common/error.h"
#include "ddace/exec/push_path.h"
#include "ddace/exec/ride_path.h"
#include "ddace/exec/scene.h"

namespace ddace::exec {

StepExecution ExecutionModel::executeStep(const task::TaskSpec&, const std::vector<task::Token>&,
                                          const std::vector<Eigen::Vector2d>&, const std::vector<StepMotion>& motions) {
  StepExecution out;
  for (const StepMotion& m : motions) out.executed.push_back(follow(m.planned, m.robot, m.entity));
  return out;
}

Trial runTrial(const task::TaskSpec& spec, const task::Demonstration& gt, const Policy& policy,
               const PathGenerator& paths, ExecutionModel& execution, const task::EndPointModel& end_points,
               const SimulatorOptions& options) {
  Trial trial;
  if (gt.rows() == 0) throw Error(Diagnostic{gt.source, 0, 0, "test demonstration has no rows"});
  const int n = static_cast<int>(spec.entities.size());
  std::vector<Eigen::Vector2d> pos;  // the scene, as the mock robots start it
  const std::vector<Pose2D> start = startPoses(gt);
  for (const Pose2D& p : start) pos.push_back(p.position());
  execution.beginTrial(spec, start);
  trial.bodies = execution.bodies();
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
    std::vector<bool> acts(static_cast<size_t>(n), false);
    for (const auto& token : d.tokens) {
      if (token.entity < 0 || token.entity >= n || token.target >= n)
        throw Error("policy returned a token for a non-existent entity");
      // One token per entity and step (the step's motions run at once; a second would
      // replace the first mid-step).
      if (acts[static_cast<size_t>(token.entity)])
        throw Error("policy returned two tokens of '" + spec.entities[token.entity].name + "' in step " +
                    std::to_string(k + 1));
      acts[static_cast<size_t>(token.entity)] = true;
    }
    // With bodies, the step's ends are placed where bodies fit (two robots sent onto one goal
    // end touching); points end where the rule puts each motion alone (the paper's Table 2).
    const std::vector<Eigen::Vector2d> ends =
        execution.bodies() ? task::stepEndPositions(spec, end_points, d.tokens, decided, std::nullopt, k) : decided;
    std::vector<StepMotion> motions;
    const size_t first = trial.executed.size();
    std::vector<std::pair<size_t, int>> pushers;  // (executed token, its load) of every carrier that moves a load
    for (size_t i = 0; i < d.tokens.size(); ++i) {
      const task::Token& token = d.tokens[i];
      ExecutedToken ex;
      ex.token = token;
      ex.step = k;
      ex.start = decided[token.entity];
      ex.goal = execution.bodies() ? ends[static_cast<size_t>(token.entity)]
                                   : task::endPoint(spec, end_points, d.tokens, i, decided, k);
      if (token.isMotion()) {
        ex.planned = paths(token, ex.start, ex.goal);
        if (ex.planned.empty()) ex.planned = {ex.start, ex.goal};
        // With bodies a carrier pushes its load, as the coordinator plans it for the robots,
        // unless the load rides and the path shown passes the bodies standing (ride_path.h).
        const std::optional<int> load = execution.bodies() ? pushedLoad(spec, d.tokens, i, decided) : std::nullopt;
        if (load && !drivesShownPath(spec, d.tokens, i, *load, decided, ex.planned, !execution.pushesLoads())) {
          ex.planned = drivenPath(spec, d.tokens, i, decided, ends, std::move(ex.planned));
          ex.goal = carrierEnd(ex.planned.back(), ends[static_cast<size_t>(*load)], ends[static_cast<size_t>(*load)],
                               !execution.pushesLoads());
          pushers.push_back({trial.executed.size(), *load});
        }
        motions.push_back(
            {i, token.entity, token.target, spec.entities[token.entity].kind == task::EntityKind::Robot, ex.planned});
      } else {
        ex.executed = {ex.start};
      }
      trial.executed.push_back(std::move(ex));
    }
    // Every motion of the step runs at once (a model with bodies moves them together).
    StepExecution done = execution.executeStep(spec, d.tokens, decided, motions);
    if (done.executed.size() != motions.size()) throw Error("execution model returned paths for another step");
    for (size_t m = 0; m < motions.size(); ++m) {
      ExecutedToken& ex = trial.executed[first + motions[m].token];
      ex.executed = std::move(done.executed[m]);
      if (ex.executed.empty()) ex.executed = {ex.start};
      pos[ex.token.entity] = ex.executed.back();
    }
    if (done.positions.size() == pos.size()) pos = done.positions;  // pushed bodies moved too
    // A carrier is judged behind where its load ended, as the coordinator judges it.
    for (const auto& [token, load] : pushers) {
      ExecutedToken& ex = trial.executed[token];
      ex.goal = carrierEnd(ex.planned.back(), ends[static_cast<size_t>(load)], pos[static_cast<size_t>(load)],
                           !execution.pushesLoads());
    }
    trial.makespan_s += done.duration_s;
    for (const std::string& f : done.failures) trial.failures.push_back("step " + std::to_string(k + 1) + ": " + f);
    trial.predicted.push_back(std::move(step));
  }
  trial.final_positions = pos;
  trial.body_report = execution.report();
  return trial;
}

}  // namespace ddace::exec
