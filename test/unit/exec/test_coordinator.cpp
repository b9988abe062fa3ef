// The coordinator's state machine: event-driven decisions, time-outs, e-stop, pause.
#include <gtest/gtest.h>

#include "ddace/common/error.h"
#include "ddace/exec/coordinator.h"
#include "ddace/exec/replay.h"
#include "ddace/tasks/generators.h"

using namespace ddace;
using namespace ddace::exec;
using Eigen::Vector2d;

namespace {

task::TaskDir task4(int demos = 1) {
  tasks::GeneratorOptions o;
  o.family = "task4";
  o.demos = demos;
  o.seed = 3;
  return tasks::generate(o);
}

EntityObservation observe(const std::vector<Vector2d>& positions, bool tracked = true) {
  return {positions, std::vector<bool>(positions.size(), tracked)};
}

task::Token tok(const task::TaskSpec& spec, const std::string& key) { return task::parseTokenKey(key, spec); }

PlannedPath straight(const PathRequest& r) { return {{r.start, r.goal}, {0, 0}}; }

/// Answers every path request with a straight line; returns the segments sent.
std::vector<SegmentCommand> answerPaths(Coordinator& c, const CoordinatorOutput& out, double now) {
  std::vector<SegmentCommand> segs;
  for (const auto& r : out.paths) {
    const auto o = c.onPath(r.id, straight(r), "", now);
    segs.insert(segs.end(), o.segments.begin(), o.segments.end());
    EXPECT_FALSE(o.decision) << "a decision was requested while paths were pending";
  }
  return segs;
}

struct Fixture : ::testing::Test {
  task::TaskDir dir = task4();
  const task::Demonstration& demo = dir.demos.front();
  Coordinator c{dir.spec, CoordinatorConfig{}};
  std::vector<Vector2d> start = demo.positions.front();

  /// Starts and answers the first decision with step 1 of the demonstration.
  std::vector<SegmentCommand> runToFirstStep() {
    c.onEntities(observe(start), 0.0);
    const auto s = c.start(0.0);
    EXPECT_TRUE(s.decision);
    const auto d = c.onDecision(s.decision->id, replayDecision(demo, s.decision->history), 0.1);
    EXPECT_EQ(c.state(), RunState::Planning);
    EXPECT_EQ(d.paths.size(), 2u);
    return answerPaths(c, d, 0.2);
  }
};

}  // namespace

TEST_F(Fixture, WaitsUntilEveryEntityIsTracked) {
  EntityObservation obs = observe(start);
  obs.tracked[2] = false;
  c.onEntities(obs, 0.0);
  const auto out = c.start(0.0);
  EXPECT_FALSE(out.decision);
  EXPECT_EQ(c.state(), RunState::WaitingForEntities);
  // Positions update but R3 is still missing: still no decision.
  EXPECT_FALSE(c.onEntities(obs, 0.5).decision);
  obs.tracked[2] = true;
  const auto now_tracked = c.onEntities(obs, 1.0);
  ASSERT_TRUE(now_tracked.decision);
  EXPECT_EQ(now_tracked.decision->step, 0);
  ASSERT_EQ(now_tracked.decision->history.size(), 1u);
  EXPECT_EQ(now_tracked.decision->history[0].positions, start);
  EXPECT_EQ(c.state(), RunState::Deciding);
}

TEST_F(Fixture, SegmentsGoToEveryMotionTokenWithTheTargetsPositionAsGoal) {
  const auto segs = runToFirstStep();
  ASSERT_EQ(segs.size(), 2u);
  EXPECT_EQ(c.state(), RunState::Executing);
  const auto& spec = dir.spec;
  EXPECT_EQ(segs[0].token, tok(spec, "R1:move:R3"));
  EXPECT_EQ(segs[0].entity, spec.entityIndex("R1"));
  EXPECT_EQ(segs[0].goal, start[spec.entityIndex("R3")]);
  EXPECT_EQ(segs[1].goal, start[spec.entityIndex("R4")]);
  EXPECT_NE(segs[0].segment_id, segs[1].segment_id);
  EXPECT_GT(segs[0].timeout_s, 0.0);
  EXPECT_EQ(c.activeEntities().size(), 2u);
}

TEST_F(Fixture, NextDecisionOnlyWhenEveryActiveRobotIsDone) {
  const auto segs = runToFirstStep();
  // Time passes, robots move and report progress: never a decision.
  for (double t = 0.3; t < 5.0; t += 0.1) {
    EXPECT_FALSE(c.onTick(t).decision);
    EXPECT_FALSE(c.onEntities(observe(start), t).decision);
    EXPECT_FALSE(c.onSegmentStatus(segs[0].entity, segs[0].segment_id, SegmentState::Running, t / 5, "", t).decision);
  }
  // The first robot is done: still waiting for the second.
  auto out = c.onSegmentStatus(segs[0].entity, segs[0].segment_id, SegmentState::Done, 1.0, "", 5.0);
  EXPECT_FALSE(out.decision);
  EXPECT_EQ(c.activeEntities(), std::vector<int>{segs[1].entity});
  // A duplicate "done" from the same robot changes nothing.
  EXPECT_FALSE(c.onSegmentStatus(segs[0].entity, segs[0].segment_id, SegmentState::Done, 1.0, "", 5.1).decision);
  // A status for an unknown segment id is ignored.
  EXPECT_FALSE(c.onSegmentStatus(segs[1].entity, 9999, SegmentState::Done, 1.0, "", 5.2).decision);
  out = c.onSegmentStatus(segs[1].entity, segs[1].segment_id, SegmentState::Done, 1.0, "", 6.0);
  ASSERT_TRUE(out.decision);
  EXPECT_EQ(out.decision->step, 1);
  EXPECT_EQ(out.decision->history.size(), 2u);
  EXPECT_TRUE(c.steps().front().complete);
  EXPECT_DOUBLE_EQ(c.steps().front().finished_s, 6.0);
}

TEST_F(Fixture, RunsTheWholeTaskAndFinishesOnEnd) {
  std::vector<Vector2d> pos = start;
  c.onEntities(observe(pos), 0);
  auto out = c.start(0);
  double t = 0;
  int decisions = 0;
  while (out.decision) {
    ++decisions;
    t += 1;
    out = c.onDecision(out.decision->id, replayDecision(demo, out.decision->history), t);
    if (c.state() == RunState::Finished) break;
    const auto segs = answerPaths(c, out, t);
    out = {};
    for (const auto& s : segs) {
      pos[s.entity] = s.goal;  // ideal execution
      c.onEntities(observe(pos), t);
      auto o = c.onSegmentStatus(s.entity, s.segment_id, SegmentState::Done, 1, "", t);
      if (o.decision) out = o;
    }
  }
  EXPECT_EQ(c.state(), RunState::Finished);
  EXPECT_EQ(decisions, 3);  // two steps, then END
  ASSERT_EQ(c.steps().size(), demo.steps.size());
  for (size_t k = 0; k < demo.steps.size(); ++k) {
    ASSERT_EQ(c.steps()[k].tokens.size(), demo.steps[k].tokens.size());
    for (size_t i = 0; i < demo.steps[k].tokens.size(); ++i)
      EXPECT_EQ(c.steps()[k].tokens[i].token, demo.steps[k].tokens[i]);
  }
  // Task 4's goal: R3 and R4 at G1.
  for (bool met : c.goalConditionsMet()) EXPECT_TRUE(met);
}

TEST_F(Fixture, SegmentTimeoutAbortsAndStopsTheRobots) {
  CoordinatorConfig cfg;
  cfg.segment_timeout_s = 2.0;
  cfg.segment_timeout_per_m_s = 0;
  c = Coordinator(dir.spec, cfg);
  const auto segs = runToFirstStep();
  c.onSegmentStatus(segs[0].entity, segs[0].segment_id, SegmentState::Done, 1, "", 1.0);
  EXPECT_TRUE(c.onTick(2.1).empty()) << "aborted before the time-out";
  const auto out = c.onTick(2.3);
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_TRUE(out.stop_all);
  EXPECT_EQ(out.stop, std::vector<int>{segs[1].entity}) << "the robot still running must be stopped";
  EXPECT_FALSE(out.decision);
  EXPECT_NE(c.reason().find("R2:move:R4"), std::string::npos) << c.reason();
  EXPECT_NE(c.reason().find("timed out"), std::string::npos) << c.reason();
  // A late "done" does not revive the run.
  EXPECT_FALSE(c.onSegmentStatus(segs[1].entity, segs[1].segment_id, SegmentState::Done, 1, "", 3).decision);
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_FALSE(c.start(3).decision) << "start after abort needs a reset";
}

TEST_F(Fixture, FailedSegmentAborts) {
  const auto segs = runToFirstStep();
  const auto out = c.onSegmentStatus(segs[1].entity, segs[1].segment_id, SegmentState::Failed, 0.3, "pose stale", 1);
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_TRUE(out.stop_all);
  EXPECT_NE(c.reason().find("pose stale"), std::string::npos);
}

TEST_F(Fixture, DecisionAndPathTimeoutsAbort) {
  CoordinatorConfig cfg;
  cfg.decision_timeout_s = 1;
  cfg.path_timeout_s = 1;
  Coordinator a(dir.spec, cfg);
  a.onEntities(observe(start), 0);
  a.start(0);
  EXPECT_TRUE(a.onTick(0.9).empty());
  a.onTick(1.1);
  EXPECT_EQ(a.state(), RunState::Aborted);
  EXPECT_NE(a.reason().find("decision"), std::string::npos);

  Coordinator b(dir.spec, cfg);
  b.onEntities(observe(start), 0);
  const auto s = b.start(0);
  const auto d = b.onDecision(s.decision->id, replayDecision(demo, s.decision->history), 0.5);
  b.onPath(d.paths[0].id, straight(d.paths[0]), "", 0.6);  // the second never comes
  b.onTick(1.6);
  EXPECT_EQ(b.state(), RunState::Aborted);
  EXPECT_NE(b.reason().find("path"), std::string::npos);
}

TEST_F(Fixture, PathErrorsAbortWithTheKey) {
  c.onEntities(observe(start), 0);
  const auto s = c.start(0);
  const auto d = c.onDecision(s.decision->id, replayDecision(demo, s.decision->history), 0.1);
  c.onPath(d.paths[1].id, {}, "no primitive for this key", 0.2);
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_NE(c.reason().find("R2:move:R4"), std::string::npos) << c.reason();
  EXPECT_NE(c.reason().find("no primitive"), std::string::npos);
}

TEST_F(Fixture, InvalidDecisionsAbort) {
  c.onEntities(observe(start), 0);
  auto s = c.start(0);
  Decision bad;
  bad.tokens = {task::Token{0, "move", 0}};  // toward itself
  c.onDecision(s.decision->id, bad, 0.1);
  EXPECT_EQ(c.state(), RunState::Aborted);

  c.reset(1);
  s = c.start(1);
  Decision empty;
  c.onDecision(s.decision->id, empty, 1.1);
  EXPECT_EQ(c.state(), RunState::Aborted);

  c.reset(2);
  s = c.start(2);
  Decision twice;
  twice.tokens = {task::Token{0, "move", 2}, task::Token{0, "move", 3}};
  c.onDecision(s.decision->id, twice, 2.1);
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_NE(c.reason().find("two tokens"), std::string::npos);
}

TEST_F(Fixture, StaleOrUnaskedDecisionsAreIgnored) {
  c.onEntities(observe(start), 0);
  const auto s = c.start(0);
  EXPECT_TRUE(c.onDecision(s.decision->id + 100, replayDecision(demo, s.decision->history), 0.1).paths.empty());
  EXPECT_EQ(c.state(), RunState::Deciding);
}

TEST_F(Fixture, EmergencyStopStopsEveryRobotAndHoldsUntilReset) {
  const auto segs = runToFirstStep();
  const auto out = c.emergencyStop(1.0, "operator");
  EXPECT_TRUE(out.stop_all);
  EXPECT_EQ(out.stop.size(), 2u);
  EXPECT_EQ(c.state(), RunState::EStopped);
  // Nothing moves it on: not a done, not a tick, not start.
  EXPECT_TRUE(c.onSegmentStatus(segs[0].entity, segs[0].segment_id, SegmentState::Done, 1, "", 2).empty());
  EXPECT_TRUE(c.onTick(100).empty());
  EXPECT_FALSE(c.start(3).decision);
  EXPECT_EQ(c.state(), RunState::EStopped);
  c.reset(4);
  EXPECT_EQ(c.state(), RunState::Idle);
  EXPECT_TRUE(c.start(5).decision);
}

TEST_F(Fixture, PauseStopsAndResumeReplansTheUnfinishedTokens) {
  const auto segs = runToFirstStep();
  c.onSegmentStatus(segs[0].entity, segs[0].segment_id, SegmentState::Done, 1, "", 1);
  const auto p = c.pause(2);
  EXPECT_EQ(c.state(), RunState::Paused);
  EXPECT_EQ(p.stop, std::vector<int>{segs[1].entity});
  EXPECT_TRUE(c.onTick(1000).empty()) << "no time-out while paused";
  // R2 stopped half-way; resume asks for a path from there to the same goal.
  std::vector<Vector2d> moved = start;
  moved[segs[1].entity] = (start[segs[1].entity] + segs[1].goal) / 2;
  c.onEntities(observe(moved), 1001);
  const auto r = c.start(1001);
  ASSERT_EQ(r.paths.size(), 1u);
  EXPECT_EQ(r.paths[0].token, segs[1].token);
  EXPECT_TRUE(r.paths[0].start.isApprox(moved[segs[1].entity]));
  EXPECT_EQ(r.paths[0].goal, segs[1].goal);
  const auto resent = answerPaths(c, r, 1002);
  ASSERT_EQ(resent.size(), 1u);
  EXPECT_NE(resent[0].segment_id, segs[1].segment_id);
  // The old segment's id no longer counts.
  EXPECT_FALSE(c.onSegmentStatus(segs[1].entity, segs[1].segment_id, SegmentState::Done, 1, "", 1003).decision);
  EXPECT_TRUE(c.onSegmentStatus(resent[0].entity, resent[0].segment_id, SegmentState::Done, 1, "", 1004).decision);
}

TEST_F(Fixture, PauseWhileDecidingAsksAgainOnResume) {
  c.onEntities(observe(start), 0);
  const auto s = c.start(0);
  c.pause(0.1);
  EXPECT_TRUE(c.onDecision(s.decision->id, replayDecision(demo, s.decision->history), 0.2).paths.empty());
  const auto r = c.start(1);
  ASSERT_TRUE(r.decision);
  EXPECT_EQ(r.decision->history.size(), 1u);
  EXPECT_NE(r.decision->id, s.decision->id);
}

TEST_F(Fixture, InPlaceTokensCompleteWhenDecided) {
  tasks::GeneratorOptions o;
  o.family = "task2";
  o.demos = 1;
  o.robots = 6;
  const auto d2 = tasks::generate(o);
  Coordinator k(d2.spec, {});
  k.onEntities(observe(d2.demos[0].positions.front()), 0);
  auto s = k.start(0);
  Decision stop;
  stop.tokens = {tok(d2.spec, "R5:stop")};
  const auto out = k.onDecision(s.decision->id, stop, 0.1);
  // No segment: the step is complete at once and the next decision is asked for.
  EXPECT_TRUE(out.paths.empty());
  ASSERT_TRUE(out.decision);
  EXPECT_EQ(out.decision->step, 1);
}

TEST_F(Fixture, StepLimitAborts) {
  CoordinatorConfig cfg;
  cfg.max_steps = 1;
  Coordinator k(dir.spec, cfg);
  std::vector<Vector2d> pos = start;
  k.onEntities(observe(pos), 0);
  const auto s = k.start(0);
  const auto d = k.onDecision(s.decision->id, replayDecision(demo, s.decision->history), 0.1);
  const auto segs = answerPaths(k, d, 0.2);
  for (const auto& g : segs) k.onSegmentStatus(g.entity, g.segment_id, SegmentState::Done, 1, "", 1);
  EXPECT_EQ(k.state(), RunState::Aborted);
  EXPECT_NE(k.reason().find("max_steps"), std::string::npos);
}

TEST_F(Fixture, ObservationOfTheWrongSizeIsRefused) {
  EXPECT_THROW(c.onEntities(observe({{0, 0}}), 0), Error);
  CoordinatorConfig cfg;
  cfg.segment_timeout_s = 0;
  EXPECT_THROW(Coordinator(dir.spec, cfg), Error);
}

TEST(Replay, RetargetMapsEndsAndKeepsShape) {
  const std::vector<Vector2d> demo = {{0, 0}, {0.5, 0.5}, {1, 0}};
  const auto p = retargetPath(demo, {1, 1}, {1, 3});
  ASSERT_EQ(p.size(), 3u);
  EXPECT_TRUE(p[0].isApprox(Vector2d(1, 1)));
  EXPECT_TRUE(p[2].isApprox(Vector2d(1, 3)));
  // Rotated by +90 degrees and scaled by 2: the bulge goes to -x.
  EXPECT_TRUE(p[1].isApprox(Vector2d(0, 2))) << p[1].transpose();
  EXPECT_THROW(retargetPath({}, {0, 0}, {1, 1}), Error);
}

TEST(Replay, DemonstrationPathsKnowEveryMotionKey) {
  const auto dir = task4(2);
  DemonstrationPaths paths(dir.spec, dir.demos);
  EXPECT_EQ(paths.size(), 4u);
  const auto p = paths.generate(task::parseTokenKey("R3:move:G1", dir.spec), {0.1, 0.1}, {0.9, 0.9});
  EXPECT_TRUE(p.points.front().isApprox(Vector2d(0.1, 0.1)));
  EXPECT_TRUE(p.points.back().isApprox(Vector2d(0.9, 0.9)));
  EXPECT_EQ(p.stddev_m.size(), p.points.size());
  EXPECT_THROW(paths.generate(task::parseTokenKey("R1:move:G1", dir.spec), {0, 0}, {1, 1}), Error);
}
