#include "ddace/eval/metrics.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "ddace/eval/frechet.h"
#include "ddace/task/end_point.h"

namespace ddace::eval {

double TrialScore::meanFd() const {
  if (fd.empty()) return std::numeric_limits<double>::quiet_NaN();
  double s = 0;
  for (double v : fd) s += v;
  return s / fd.size();
}

std::string ObjectLeftShort::describe() const {
  char line[160];
  std::snprintf(line, sizeof line, "step %d: %s left %.1f cm short of its end", step + 1, token.c_str(),
                distance_m * 100);
  return line;
}

namespace {
std::vector<task::Token> sorted(std::vector<task::Token> tokens) {
  std::sort(tokens.begin(), tokens.end());
  return tokens;
}
}  // namespace

TrialScore scoreTrial(const task::TaskSpec& spec, const task::Demonstration& gt, const exec::Trial& trial,
                      bool use_executed_paths) {
  TrialScore s;
  s.demo = gt.source;
  s.gt_steps = static_cast<int>(gt.steps.size());
  s.predicted_steps = static_cast<int>(trial.predicted.size());
  for (int i = 0; i < s.gt_steps; ++i)
    if (i < s.predicted_steps && sorted(trial.predicted[i].tokens) == sorted(gt.steps[i].tokens)) ++s.correct_steps;
  s.ended_correctly = trial.ended && s.predicted_steps == s.gt_steps;

  // Each executed token matches at most one ground-truth token with the same key.
  std::vector<bool> used(trial.executed.size(), false);
  auto match = [&](const task::Token& t) -> int {
    for (size_t i = 0; i < trial.executed.size(); ++i)
      if (!used[i] && trial.executed[i].token == t) {
        used[i] = true;
        return static_cast<int>(i);
      }
    return -1;
  };
  for (const auto& seg : gt.segments) {
    if (!seg.token.isMotion()) continue;
    const int i = match(seg.token);
    const bool robot = spec.entities[seg.token.entity].kind == task::EntityKind::Robot;
    if (robot) ++s.gt_robot_motions;
    if (i < 0) continue;
    const exec::ExecutedToken& ex = trial.executed[i];
    const bool arrived = task::arrived(ex.executed.back(), ex.goal, spec.arrival_radius);
    if (robot && arrived) ++s.achieved_robot_motions;
    if (!robot && trial.bodies && !arrived)
      s.objects_left_short.push_back({ex.step, task::tokenKey(ex.token, spec), (ex.executed.back() - ex.goal).norm()});
    const exec::Path& generated = use_executed_paths || ex.planned.empty() ? ex.executed : ex.planned;
    const auto truth = gt.segmentPath(seg);
    if (generated.size() >= 2 && truth.size() >= 2 && (truth.back() - truth.front()).norm() > 1e-9)
      s.fd.push_back(normalisedFrechet(generated, truth));
  }

  for (const auto& g : spec.goal_conditions)
    if (trial.final_positions.size() != spec.entities.size() || !task::goalConditionMet(spec, g, trial.final_positions))
      s.goal_conditions_hold = false;
  s.bodies = trial.bodies;
  s.makespan_s = trial.makespan_s;
  if (trial.bodies) {
    s.collisions = static_cast<int>(trial.body_report.collisions.size());
    if (trial.body_report.closest.a >= 0) s.min_clearance_m = trial.body_report.closest.clearance_m;
  }
  s.success = s.correct_steps == s.gt_steps && s.ended_correctly && s.achieved_robot_motions == s.gt_robot_motions &&
              s.goal_conditions_hold && s.objectsArrived() && s.collisions == 0;
  return s;
}

Summary summarise(const std::vector<TrialScore>& scores) {
  Summary m;
  m.trials = static_cast<int>(scores.size());
  int ok = 0, steps = 0, correct = 0, motions = 0, achieved = 0;
  double fd = 0;
  for (const auto& s : scores) {
    ok += s.success;
    steps += s.gt_steps;
    correct += s.correct_steps;
    motions += s.gt_robot_motions;
    achieved += s.achieved_robot_motions;
    for (double v : s.fd) fd += v;
    m.fd_tokens += static_cast<int>(s.fd.size());
    m.bodies = m.bodies || s.bodies;
    m.collisions += s.collisions;
    m.trials_with_collision += s.collisions > 0;
    if (std::isfinite(s.min_clearance_m) && !(m.min_clearance_m <= s.min_clearance_m))
      m.min_clearance_m = s.min_clearance_m;
    m.makespan_s += s.makespan_s;
  }
  if (m.trials) m.makespan_s /= m.trials;
  m.osr = m.trials ? static_cast<double>(ok) / m.trials : 0;
  m.ssr = steps ? static_cast<double>(correct) / steps : 0;
  m.gcr = motions ? static_cast<double>(achieved) / motions : 0;
  m.fd = m.fd_tokens ? fd / m.fd_tokens : std::numeric_limits<double>::quiet_NaN();
  return m;
}

}  // namespace ddace::eval
