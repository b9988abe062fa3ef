// Demonstrations where the scene decides who does what and each role moves its own way,
// for the tests of motion primitives by role: the generators' families move every role
// alike (their shapes are per name or bent around bodies), a person need not.
#pragma once

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "ddace/common/error.h"
#include "ddace/common/random.h"
#include "ddace/tasks/generators.h"

namespace ddace::test {

/// How a role moves: a planned shape (tasks::PathShape), kept as planned (no bending
/// around bodies).
struct RoleMotion {
  tasks::PathShape::Kind kind = tasks::PathShape::Straight;
  double amplitude = 0;  ///< + left, - right, in start-to-end distances
};

/// A role task: `robots` robots R1.. and one goal G1 on the table. The robots are ranked by
/// their distance to G1 (a clear order: the scene decides the roles), and `plan` gives the
/// steps of a ranking: rank -> (action's target: -1 G1, else the robot of that rank; shape).
struct RoleStep {
  int rank;    ///< the mover's rank
  int target;  ///< -1: G1; else the rank of the robot it moves toward
  RoleMotion motion;
};

inline task::TaskDir roleTask(const std::string& name, int robots, const std::vector<RoleStep>& plan, int demos,
                              uint64_t seed) {
  task::TaskDir dir;
  dir.spec.name = name;
  dir.spec.actions = {"move"};
  dir.spec.actions_declared = true;
  for (int i = 0; i < robots; ++i)
    dir.spec.entities.push_back({"R" + std::to_string(i + 1), task::EntityKind::Robot, "hamster"});
  dir.spec.entities.push_back({"G1", task::EntityKind::Goal, ""});
  const int goal = robots;
  SplitMix64 rng(seed * 0x9E3779B97F4A7C15ULL + 0x51ED2701ULL);
  for (int attempt = 0; static_cast<int>(dir.demos.size()) < demos; ++attempt) {
    if (attempt > 100000) throw Error("role task '" + name + "': no clear scene in 100000 draws");
    std::vector<Eigen::Vector2d> at;
    for (int e = 0; e <= robots; ++e) at.emplace_back(rng.uniform(0.1, 0.9), rng.uniform(0.1, 0.9));
    bool apart = true;
    for (size_t a = 0; a < at.size(); ++a)
      for (size_t b = a + 1; b < at.size(); ++b) apart = apart && (at[a] - at[b]).norm() >= tasks::kSceneMinSeparation;
    std::vector<int> rank(robots);
    for (int i = 0; i < robots; ++i) rank[i] = i;
    const auto d = [&](int r) { return (at[r] - at[goal]).norm(); };
    std::sort(rank.begin(), rank.end(), [&](int a, int b) { return d(a) < d(b); });
    for (int k = 0; k + 1 < robots; ++k) apart = apart && d(rank[k + 1]) - d(rank[k]) >= tasks::kSceneDecisionMargin;
    if (!apart) continue;
    std::vector<tasks::PlannedStep> steps;
    for (const RoleStep& s : plan) {
      tasks::PlannedToken t;
      t.token.entity = rank[s.rank];
      t.token.action = "move";
      t.token.target = s.target < 0 ? goal : rank[s.target];
      // Demonstrations are never identical: the amplitude varies by 5%.
      t.shape = {s.motion.kind, s.motion.amplitude * (1 + 0.05 * rng.uniform(-1, 1))};
      steps.push_back({t});
    }
    tasks::DemoMotion motion;
    motion.avoid = false;
    bool clear = false;
    task::Demonstration demo = tasks::simulateSteps(dir.spec, at, steps, motion, &clear);
    if (!clear) continue;  // a body passed through another: draw again
    demo.source = "demo_" + std::to_string(dir.demos.size()) + ".csv";
    dir.demos.push_back(std::move(demo));
  }
  return dir;
}

/// The line-up: the robot nearest G1 drives to it, the second joins it arcing right, the
/// third joins the second arcing left. R2:move:R1 is sometimes the second joining the head,
/// sometimes the third joining the second.
inline task::TaskDir lineUp(int demos, uint64_t seed, int robots = 3) {
  std::vector<RoleStep> plan = {{0, -1, {}}};
  for (int k = 1; k < robots; ++k) plan.push_back({k, k - 1, {tasks::PathShape::Arc, k == 1 ? -0.25 : 0.25}});
  return roleTask("line_up", robots, plan, demos, seed);
}

/// Two robots to one goal: the nearer drives straight to G1, then the other arcs left to it.
inline task::TaskDir twoToOneGoal(int demos, uint64_t seed) {
  return roleTask("two_to_one_goal", 2, {{0, -1, {}}, {1, -1, {tasks::PathShape::Arc, 0.3}}}, demos, seed);
}

}  // namespace ddace::test
