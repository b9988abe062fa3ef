// Closed-loop simulator + metrics: a policy that replays the ground truth scores perfectly;
// each kind of mistake lowers exactly the metric the spec says it should.
#include <gtest/gtest.h>

#include <cmath>

#include "ddace/eval/metrics.h"
#include "ddace/tasks/generators.h"

using namespace ddace;

namespace {

task::TaskDir testSet(const std::string& family, int demos = 3) {
  tasks::GeneratorOptions o;
  o.family = family;
  o.demos = demos;
  o.seed = 11;
  return tasks::generate(o);
}

/// Replays the ground truth's steps, then END; `mutate` may change step k.
exec::Policy replay(const task::Demonstration& gt, std::function<void(size_t, exec::Decision&)> mutate = nullptr) {
  return [&gt, mutate](const std::vector<task::Snapshot>& history) {
    exec::Decision d;
    const size_t k = history.size() - 1;
    if (k >= gt.steps.size()) {
      d.end = true;
    } else {
      d.tokens = gt.steps[k].tokens;
    }
    if (mutate) mutate(k, d);
    return d;
  };
}

/// The demonstrated path of the segment with this token (a replay starts and decides
/// exactly where the demonstration did, so start and goal coincide with it).
exec::PathGenerator truthPaths(const task::Demonstration& gt) {
  return [&gt](const task::Token& t, const Eigen::Vector2d& start, const Eigen::Vector2d& goal) {
    for (const auto& s : gt.segments)
      if (s.token == t && (gt.segmentPath(s).front() - start).norm() < 1e-9) return gt.segmentPath(s);
    return exec::Path{start, goal};
  };
}

/// Where the test set's own motions end (task/end_point.h).
task::EndPointModel ends(const task::TaskDir& dir) {
  return task::learnEndPoints(dir.spec, dir.demos);
}

exec::PathGenerator straight() {
  return [](const task::Token&, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    exec::Path p;
    for (int i = 0; i <= 50; ++i) p.push_back(a + (b - a) * (i / 50.0));
    return p;
  };
}

}  // namespace

TEST(ClosedLoop, ReplayingTheGroundTruthIsAPerfectTrial) {
  for (const auto& family : tasks::families()) {
    const auto dir = testSet(family);
    exec::IdealExecution ideal;
    std::vector<eval::TrialScore> scores;
    for (const auto& gt : dir.demos) {
      const exec::Trial trial = exec::runTrial(dir.spec, gt, replay(gt), truthPaths(gt), ideal, ends(dir));
      EXPECT_TRUE(trial.ended);
      EXPECT_EQ(trial.snapshots.size(), gt.steps.size() + 1);
      scores.push_back(eval::scoreTrial(dir.spec, gt, trial));
      EXPECT_TRUE(scores.back().success) << family;
    }
    const eval::Summary m = eval::summarise(scores);
    EXPECT_EQ(m.trials, 3);
    EXPECT_DOUBLE_EQ(m.osr, 1.0) << family;
    EXPECT_DOUBLE_EQ(m.ssr, 1.0);
    EXPECT_DOUBLE_EQ(m.gcr, 1.0);
    EXPECT_LT(m.fd, 0.01) << family;
    EXPECT_GT(m.fd_tokens, 0);
  }
}

TEST(ClosedLoop, GoalsAreTheEndPointsWhenTheStepIsDecided) {
  const auto dir = testSet("task4", 1);
  const auto& gt = dir.demos[0];
  exec::IdealExecution ideal;
  const exec::Trial trial = exec::runTrial(dir.spec, gt, replay(gt), straight(), ideal, ends(dir));
  for (const auto& ex : trial.executed) {
    const auto& decided = trial.snapshots[ex.step].positions;
    const auto& step = trial.predicted[ex.step].tokens;
    const size_t i = static_cast<size_t>(std::find(step.begin(), step.end(), ex.token) - step.begin());
    EXPECT_LT((ex.goal - task::endPoint(dir.spec, ends(dir), step, i, decided)).norm(), 1e-12);
    EXPECT_LT((ex.executed.back() - ex.goal).norm(), 1e-12);
  }
}

TEST(ClosedLoop, GcrCountsArrivalAtTheEndPointNotAtTheTargetsCentre) {
  const auto dir = testSet("task2", 1);
  const auto& gt = dir.demos[0];
  exec::IdealExecution ideal;
  // Robots that stop at contact with the robot they drive to (4.4 cm from its centre,
  // more than the 3 cm arrival radius) have arrived: GCR measures at the end point.
  task::EndPointModel contact;
  contact.by_class["robot->robot"] = {Eigen::Vector2d(-dir.spec.contactDistance(0, 1), 0), 10};
  const exec::Trial trial = exec::runTrial(dir.spec, gt, replay(gt), straight(), ideal, contact);
  double farthest = 0;
  for (const auto& ex : trial.executed)
    if (ex.token.isMotion() && dir.spec.entities[ex.token.target].kind == task::EntityKind::Robot)
      farthest = std::max(farthest, (ex.executed.back() - trial.snapshots[ex.step].positions[ex.token.target]).norm());
  EXPECT_GT(farthest, dir.spec.arrival_radius);
  const auto s = eval::scoreTrial(dir.spec, gt, trial);
  EXPECT_DOUBLE_EQ(s.gcr(), 1.0);
  // The same motions judged at the targets' centres (the old rule) would not have arrived.
  exec::Trial at_centres = trial;
  for (auto& ex : at_centres.executed)
    if (ex.token.isMotion()) ex.goal = at_centres.snapshots[ex.step].positions[ex.token.target];
  EXPECT_LT(eval::scoreTrial(dir.spec, gt, at_centres).gcr(), 1.0);
}

TEST(ClosedLoop, StraightPathsOnCurvedDemonstrationsRaiseOnlyFd) {
  const auto dir = testSet("task4", 2);
  exec::IdealExecution ideal;
  std::vector<eval::TrialScore> scores;
  for (const auto& gt : dir.demos)
    scores.push_back(
        eval::scoreTrial(dir.spec, gt, exec::runTrial(dir.spec, gt, replay(gt), straight(), ideal, ends(dir))));
  const eval::Summary m = eval::summarise(scores);
  EXPECT_DOUBLE_EQ(m.osr, 1.0);
  EXPECT_GT(m.fd, 0.1);  // arcs of 0.3 and spirals are far from straight lines
}

TEST(ClosedLoop, AWrongStepLowersSsrAndOsr) {
  const auto dir = testSet("task4", 1);
  const auto& gt = dir.demos[0];
  exec::IdealExecution ideal;
  // Step 2 forgets R4's token: R4 never reaches G1.
  auto drop = [](size_t k, exec::Decision& d) {
    if (k == 1) d.tokens.pop_back();
  };
  const auto s =
      eval::scoreTrial(dir.spec, gt, exec::runTrial(dir.spec, gt, replay(gt, drop), straight(), ideal, ends(dir)));
  EXPECT_EQ(s.correct_steps, 1);
  EXPECT_DOUBLE_EQ(s.ssr(), 0.5);
  EXPECT_DOUBLE_EQ(s.gcr(), 0.75);
  EXPECT_FALSE(s.goal_conditions_hold);  // R4 is not at G1
  EXPECT_FALSE(s.success);
}

TEST(ClosedLoop, NeverEndingPolicyStopsTwoStepsAfterTheGroundTruth) {
  const auto dir = testSet("task4", 1);
  const auto& gt = dir.demos[0];
  exec::IdealExecution ideal;
  auto never_end = [&](size_t k, exec::Decision& d) {
    if (k >= gt.steps.size()) {
      d.end = false;
      d.tokens = gt.steps[0].tokens;
    }
  };
  const exec::Trial trial = exec::runTrial(dir.spec, gt, replay(gt, never_end), straight(), ideal, ends(dir));
  EXPECT_FALSE(trial.ended);
  EXPECT_EQ(trial.predicted.size(), gt.steps.size() + 2);
  const auto s = eval::scoreTrial(dir.spec, gt, trial);
  EXPECT_DOUBLE_EQ(s.ssr(), 1.0);
  EXPECT_FALSE(s.ended_correctly);
  EXPECT_FALSE(s.success);
}

TEST(ClosedLoop, StoppingShortOfTheGoalLowersGcr) {
  const auto dir = testSet("task4", 1);
  const auto& gt = dir.demos[0];
  struct Short : exec::ExecutionModel {
    std::string name() const override { return "short"; }
    exec::Path follow(const exec::Path& p, bool, int) override {
      return exec::Path(p.begin(), p.begin() + static_cast<long>(p.size() * 0.8));
    }
  } short_model;
  const auto s =
      eval::scoreTrial(dir.spec, gt, exec::runTrial(dir.spec, gt, replay(gt), straight(), short_model, ends(dir)));
  EXPECT_DOUBLE_EQ(s.ssr(), 1.0);
  EXPECT_DOUBLE_EQ(s.gcr(), 0.0);
  EXPECT_FALSE(s.success);
}

TEST(ClosedLoop, AnEarlyEndLosesTheRemainingSteps) {
  const auto dir = testSet("task4", 1);
  const auto& gt = dir.demos[0];
  exec::IdealExecution ideal;
  auto early = [](size_t k, exec::Decision& d) {
    if (k == 1) {
      d.end = true;
      d.tokens.clear();
    }
  };
  const exec::Trial trial = exec::runTrial(dir.spec, gt, replay(gt, early), straight(), ideal, ends(dir));
  EXPECT_TRUE(trial.ended);
  const auto s = eval::scoreTrial(dir.spec, gt, trial);
  EXPECT_EQ(s.correct_steps, 1);
  EXPECT_FALSE(s.ended_correctly);
  EXPECT_DOUBLE_EQ(s.gcr(), 0.5);  // R3 and R4 never went to G1
  EXPECT_FALSE(s.success);
}

TEST(ClosedLoop, AnExtraStepBeforeEndIsNotASuccess) {
  const auto dir = testSet("task4", 1);
  const auto& gt = dir.demos[0];
  exec::IdealExecution ideal;
  auto extra = [&](size_t k, exec::Decision& d) {
    if (k == gt.steps.size()) {  // one more step (R1 -> G1), then END
      d.end = false;
      d.tokens = {task::Token{0, "move", 4}};
    }
  };
  const exec::Trial trial = exec::runTrial(dir.spec, gt, replay(gt, extra), straight(), ideal, ends(dir));
  EXPECT_TRUE(trial.ended);
  EXPECT_EQ(trial.predicted.size(), gt.steps.size() + 1);
  const auto s = eval::scoreTrial(dir.spec, gt, trial);
  EXPECT_DOUBLE_EQ(s.ssr(), 1.0);  // every ground-truth step was right ...
  EXPECT_DOUBLE_EQ(s.gcr(), 1.0);
  EXPECT_FALSE(s.ended_correctly);  // ... but END came one step late
  EXPECT_FALSE(s.success);
}

TEST(ClosedLoop, FdOfAPathWithAKnownOffset) {
  // The generated path is the demonstrated one shifted sideways by 5 % of the segment's
  // start-goal distance: in the canonical frame the Fréchet distance is exactly 0.05.
  const auto dir = testSet("task2", 1);
  const auto& gt = dir.demos[0];
  exec::IdealExecution ideal;
  const auto shifted = [&gt](const task::Token& t, const Eigen::Vector2d&, const Eigen::Vector2d&) {
    exec::Path p;
    for (const auto& s : gt.segments)
      if (s.token == t) {
        p = gt.segmentPath(s);
        const Eigen::Vector2d d = p.back() - p.front();
        const Eigen::Vector2d n = Eigen::Vector2d(-d.y(), d.x()) * 0.05;
        for (auto& q : p) q += n;
        break;
      }
    return p;
  };
  const auto s = eval::scoreTrial(dir.spec, gt, exec::runTrial(dir.spec, gt, replay(gt), shifted, ideal, ends(dir)));
  ASSERT_FALSE(s.fd.empty());
  for (double fd : s.fd) EXPECT_NEAR(fd, 0.05, 1e-6);
}
