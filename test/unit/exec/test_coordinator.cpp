// The coordinator's state machine: event-driven decisions, time-outs, e-stop, pause.
#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <optional>

#include "ddace/common/error.h"
#include "ddace/exec/coordinator.h"
#include "ddace/exec/push_path.h"
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

task::Token tok(const task::TaskSpec& spec, const std::string& key) {
  return task::parseTokenKey(key, spec);
}

PlannedPath straight(const PathRequest& r) {
  return {{r.start, r.goal}, {0, 0}};
}

/// A status as an executor sends it on `entity`'s own topic.
StatusReport report(const Coordinator& c, int entity, uint32_t segment_id, SegmentState st, double progress,
                    const std::string& message = "") {
  StatusReport r;
  r.topic_entity = entity;
  r.entity = c.spec().entities[entity].name;
  r.segment_id = segment_id;
  r.code = static_cast<int>(st);
  r.progress = progress;
  r.message = message;
  return r;
}

/// The entity is tracked at its goal, then its executor reports DONE.
CoordinatorOutput arriveDone(Coordinator& c, const SegmentCommand& s, double now) {
  EntityObservation obs = c.observation();
  obs.positions[s.entity] = s.goal;
  c.onEntities(obs, now);
  return c.onSegmentStatus(report(c, s.entity, s.segment_id, SegmentState::Done, 1.0), now);
}

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

/// The paper's execution: any failure or time-out aborts the run (no recovery;
/// test_coordinator_replan.cpp covers the default's).
CoordinatorConfig withoutRecovery() {
  CoordinatorConfig cfg;
  cfg.max_replans = 0;
  return cfg;
}

struct Fixture : ::testing::Test {
  task::TaskDir dir = task4();
  const task::Demonstration& demo = dir.demos.front();
  task::EndPointModel ends = task::learnEndPoints(dir.spec, dir.demos);
  Coordinator c{dir.spec, withoutRecovery(), ends};
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

TEST_F(Fixture, SegmentsGoToEveryMotionTokenWithItsEndPointAsGoal) {
  const auto segs = runToFirstStep();
  ASSERT_EQ(segs.size(), 2u);
  EXPECT_EQ(c.state(), RunState::Executing);
  const auto& spec = dir.spec;
  EXPECT_EQ(segs[0].token, tok(spec, "R1:move:R3"));
  EXPECT_EQ(segs[0].entity, spec.entityIndex("R1"));
  // The end points the rule gives (task/end_point.h), learned from the demonstration.
  const std::vector<task::Token> step = {segs[0].token, segs[1].token};
  EXPECT_EQ(segs[0].goal, task::endPoint(spec, ends, step, 0, start));
  EXPECT_EQ(segs[1].goal, task::endPoint(spec, ends, step, 1, start));

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
    EXPECT_FALSE(
        c.onSegmentStatus(report(c, segs[0].entity, segs[0].segment_id, SegmentState::Running, t / 5, ""), t).decision);
  }
  // The first robot is done: still waiting for the second.
  auto out = arriveDone(c, segs[0], 5.0);
  EXPECT_FALSE(out.decision);
  EXPECT_EQ(c.activeEntities(), std::vector<int>{segs[1].entity});
  // A duplicate "done" from the same robot changes nothing.
  EXPECT_FALSE(arriveDone(c, segs[0], 5.1).decision);
  // A status for an unknown segment id is ignored.
  EXPECT_FALSE(c.onSegmentStatus(report(c, segs[1].entity, 9999, SegmentState::Done, 1.0, ""), 5.2).decision);
  out = arriveDone(c, segs[1], 6.0);
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
      auto o = arriveDone(c, s, t);
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

TEST_F(Fixture, DoneCountsAtTheEndPointNotAtTheTargetsCentre) {
  // Demonstrations that stopped at contact with the robot driven to.
  ends.by_class["robot->robot"] = {Vector2d(-dir.spec.contactDistance(0, 2), 0), 10};
  c = Coordinator(dir.spec, CoordinatorConfig{}, ends);
  const auto segs = runToFirstStep();
  EXPECT_NEAR((segs[0].goal - start[segs[0].token.target]).norm(), dir.spec.contactDistance(0, 2), 1e-9);
  const SegmentCommand& s = segs[0];
  // A robot that drove onto its target's centre (pushing it) has not arrived ...
  EntityObservation obs = c.observation();
  obs.positions[s.entity] = start[s.token.target];
  c.onEntities(obs, 1.0);
  c.onSegmentStatus(report(c, s.entity, s.segment_id, SegmentState::Done, 1.0), 1.0);
  EXPECT_NE(c.steps().back().tokens[0].state, SegmentState::Done);
  // ... one stopped at contact, within the arrival radius of the end point, has.
  obs.positions[s.entity] = s.goal + Vector2d(0.01, 0.0);
  c.onEntities(obs, 1.5);
  EXPECT_EQ(c.steps().back().tokens[0].state, SegmentState::Done);
}

TEST_F(Fixture, SegmentTimeoutAbortsAndStopsTheRobots) {
  CoordinatorConfig cfg = withoutRecovery();
  cfg.segment_timeout_s = 2.0;
  cfg.segment_timeout_per_m_s = 0;
  c = Coordinator(dir.spec, cfg, ends);
  const auto segs = runToFirstStep();
  arriveDone(c, segs[0], 1.0);
  EXPECT_TRUE(c.onTick(2.1).empty()) << "aborted before the time-out";
  const auto out = c.onTick(2.3);
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_TRUE(out.stop_all);
  EXPECT_EQ(out.stop, std::vector<int>{segs[1].entity}) << "the robot still running must be stopped";
  EXPECT_FALSE(out.decision);
  EXPECT_NE(c.reason().find("R2:move:R4"), std::string::npos) << c.reason();
  EXPECT_NE(c.reason().find("timed out"), std::string::npos) << c.reason();
  // A late "done" does not revive the run.
  EXPECT_FALSE(arriveDone(c, segs[1], 3).decision);
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_FALSE(c.start(3).decision) << "start after abort needs a reset";
}

TEST_F(Fixture, FailedSegmentAborts) {
  const auto segs = runToFirstStep();
  const auto out =
      c.onSegmentStatus(report(c, segs[1].entity, segs[1].segment_id, SegmentState::Failed, 0.3, "pose stale"), 1);
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_TRUE(out.stop_all);
  EXPECT_NE(c.reason().find("pose stale"), std::string::npos);
}

TEST_F(Fixture, DecisionAndPathTimeoutsAbort) {
  CoordinatorConfig cfg;
  cfg.decision_timeout_s = 1;
  cfg.path_timeout_s = 1;
  Coordinator a(dir.spec, cfg, ends);
  a.onEntities(observe(start), 0);
  a.start(0);
  EXPECT_TRUE(a.onTick(0.9).empty());
  a.onTick(1.1);
  EXPECT_EQ(a.state(), RunState::Aborted);
  EXPECT_NE(a.reason().find("decision"), std::string::npos);

  Coordinator b(dir.spec, cfg, ends);
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
  EXPECT_TRUE(arriveDone(c, segs[0], 2).empty());
  EXPECT_TRUE(c.onTick(100).empty());
  EXPECT_FALSE(c.start(3).decision);
  EXPECT_EQ(c.state(), RunState::EStopped);
  c.reset(4);
  EXPECT_EQ(c.state(), RunState::Idle);
  EXPECT_TRUE(c.start(5).decision);
}

TEST_F(Fixture, PauseStopsAndResumeReplansTheUnfinishedTokens) {
  const auto segs = runToFirstStep();
  arriveDone(c, segs[0], 1);
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
  EXPECT_FALSE(arriveDone(c, segs[1], 1003).decision);
  EXPECT_TRUE(arriveDone(c, resent[0], 1004).decision);
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
  Coordinator k(d2.spec, {}, task::learnEndPoints(d2.spec, d2.demos));
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
  Coordinator k(dir.spec, cfg, ends);
  std::vector<Vector2d> pos = start;
  k.onEntities(observe(pos), 0);
  const auto s = k.start(0);
  const auto d = k.onDecision(s.decision->id, replayDecision(demo, s.decision->history), 0.1);
  const auto segs = answerPaths(k, d, 0.2);
  for (const auto& g : segs) arriveDone(k, g, 1);
  EXPECT_EQ(k.state(), RunState::Aborted);
  EXPECT_NE(k.reason().find("max_steps"), std::string::npos);
}

TEST_F(Fixture, ObservationOfTheWrongSizeIsRefused) {
  EXPECT_THROW(c.onEntities(observe({{0, 0}}), 0), Error);
  CoordinatorConfig cfg;
  cfg.segment_timeout_s = 0;
  EXPECT_THROW(Coordinator(dir.spec, cfg, ends), Error);
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

TEST_F(Fixture, StatusesWithTheWrongEntityCodeOrSegmentAreIgnored) {
  const auto segs = runToFirstStep();
  // R-something's DONE on the right topic with the right segment id but another entity name.
  StatusReport forged = report(c, segs[0].entity, segs[0].segment_id, SegmentState::Done, 1.0);
  forged.entity = "R9";
  EntityObservation obs = c.observation();
  obs.positions[segs[0].entity] = segs[0].goal;
  c.onEntities(obs, 1.0);
  auto out = c.onSegmentStatus(forged, 1.0);
  ASSERT_EQ(out.log.size(), 1u);
  EXPECT_NE(out.log[0].find("R9"), std::string::npos) << out.log[0];
  // An invalid code, and "sent" (only the coordinator sends).
  StatusReport bad = report(c, segs[0].entity, segs[0].segment_id, SegmentState::Done, 1.0);
  bad.code = 17;
  EXPECT_FALSE(c.onSegmentStatus(bad, 1.1).log.empty());
  bad.code = static_cast<int>(SegmentState::Sent);
  EXPECT_FALSE(c.onSegmentStatus(bad, 1.1).log.empty());
  // The other robot's segment id on this robot's topic.
  out = c.onSegmentStatus(report(c, segs[0].entity, segs[1].segment_id, SegmentState::Done, 1.0), 1.2);
  EXPECT_FALSE(out.log.empty());
  EXPECT_EQ(c.activeEntities().size(), 2u) << "no forged status may complete a segment";
  EXPECT_EQ(c.state(), RunState::Executing);
}

TEST_F(Fixture, DoneCountsOnlyWhenTheTrackedPoseIsAtTheGoal) {
  const auto segs = runToFirstStep();
  arriveDone(c, segs[1], 1.0);
  // R's executor says DONE while the tracker sees it 0.25 m from the goal.
  EntityObservation obs = c.observation();
  const Vector2d far = segs[0].goal + Vector2d(0.25, 0);
  obs.positions[segs[0].entity] = far;
  c.onEntities(obs, 2.0);
  auto out = c.onSegmentStatus(report(c, segs[0].entity, segs[0].segment_id, SegmentState::Done, 1.0), 2.0);
  EXPECT_FALSE(out.decision);
  ASSERT_EQ(out.log.size(), 1u);
  EXPECT_NE(out.log[0].find("ignoring DONE"), std::string::npos) << out.log[0];
  // Said again: ignored without another log line.
  out = c.onSegmentStatus(report(c, segs[0].entity, segs[0].segment_id, SegmentState::Done, 1.0), 2.1);
  EXPECT_FALSE(out.decision);
  EXPECT_TRUE(out.log.empty());
  EXPECT_EQ(c.activeEntities(), std::vector<int>{segs[0].entity});
  ASSERT_NE(c.currentStep(), nullptr);
  for (const auto& t : c.currentStep()->tokens)
    if (t.segment_id == segs[0].segment_id) {
      EXPECT_NEAR(t.distance_to_goal_m, 0.25, 1e-9);
    }
  // Still far: nothing; within the radius: the claimed DONE counts and the next decision goes out.
  obs.positions[segs[0].entity] = segs[0].goal + Vector2d(0.1, 0);
  EXPECT_FALSE(c.onEntities(obs, 3.0).decision);
  obs.positions[segs[0].entity] = segs[0].goal + Vector2d(0.02, 0);
  out = c.onEntities(obs, 4.0);
  ASSERT_TRUE(out.decision);
  EXPECT_EQ(out.decision->step, 1);
}

TEST_F(Fixture, ADoneThatNeverArrivesTimesOut) {
  const auto segs = runToFirstStep();
  arriveDone(c, segs[1], 1.0);
  c.onSegmentStatus(report(c, segs[0].entity, segs[0].segment_id, SegmentState::Done, 1.0), 1.0);
  EXPECT_FALSE(c.onTick(0.2 + segs[0].timeout_s - 0.5).stop_all);
  const auto out = c.onTick(0.2 + segs[0].timeout_s + 0.5);
  EXPECT_TRUE(out.stop_all);
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_NE(c.reason().find("timed out"), std::string::npos) << c.reason();
}

TEST_F(Fixture, APathForAnotherGoalAborts) {
  c.onEntities(observe(start), 0);
  const auto s = c.start(0);
  const auto d = c.onDecision(s.decision->id, replayDecision(demo, s.decision->history), 0.1);
  ASSERT_FALSE(d.paths.empty());
  PlannedPath p = straight(d.paths[0]);
  p.points.back() += Vector2d(0.2, 0);
  const auto out = c.onPath(d.paths[0].id, p, "", 0.2);
  EXPECT_TRUE(out.stop_all);
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_NE(c.reason().find("from its end point"), std::string::npos) << c.reason();
}

TEST_F(Fixture, APathWithANonFinitePointOrStddevAborts) {
  for (const bool in_stddev : {false, true}) {
    c.reset(0);
    c.onEntities(observe(start), 0);
    const auto s = c.start(0);
    const auto d = c.onDecision(s.decision->id, replayDecision(demo, s.decision->history), 0.1);
    ASSERT_FALSE(d.paths.empty());
    PlannedPath p = straight(d.paths[0]);
    if (in_stddev) {
      p.stddev_m.assign(p.points.size(), 0.01);
      p.stddev_m[1] = std::numeric_limits<double>::infinity();
    } else {
      p.points[1].y() = std::numeric_limits<double>::quiet_NaN();
    }
    const auto out = c.onPath(d.paths[0].id, p, "", 0.2);
    EXPECT_TRUE(out.stop_all);
    EXPECT_EQ(c.state(), RunState::Aborted);
    EXPECT_NE(c.reason().find(in_stddev ? "standard deviation" : "non-finite point"), std::string::npos) << c.reason();
    EXPECT_NE(c.reason().find(task::tokenKey(d.paths[0].token, c.spec())), std::string::npos) << c.reason();
  }
}

TEST_F(Fixture, ResetForgetsTheRunAndAStartPlansFromTheCurrentPoses) {
  const auto segs = runToFirstStep();
  arriveDone(c, segs[0], 1.0);
  ASSERT_EQ(c.decisionsRequested(), 1u);
  ASSERT_TRUE(c.lastDecision());
  const auto r = c.reset(2.0);
  EXPECT_TRUE(r.stop_all);
  EXPECT_EQ(c.state(), RunState::Idle);
  EXPECT_TRUE(c.steps().empty());
  EXPECT_EQ(c.decisionsRequested(), 0u);
  EXPECT_FALSE(c.lastDecision());
  const EntityObservation now = c.observation();
  const auto s = c.start(3.0);
  ASSERT_TRUE(s.decision);
  EXPECT_EQ(s.decision->step, 0);
  ASSERT_EQ(s.decision->history.size(), 1u);
  EXPECT_EQ(s.decision->history[0].positions, now.positions) << "the new run starts from where the entities are";
  EXPECT_EQ(c.decisionsRequested(), 1u);
}

TEST_F(Fixture, ALostRoleAbortsARunningRunOnly) {
  EXPECT_TRUE(c.abortRun("node /sequence is gone", 0).empty()) << "nothing runs yet";
  runToFirstStep();
  const auto out = c.abortRun("role sequence: node /sequence is gone", 1.0);
  EXPECT_TRUE(out.stop_all);
  EXPECT_EQ(out.stop.size(), 2u);
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_NE(c.reason().find("/sequence"), std::string::npos);
}

TEST_F(Fixture, ARunThatCouldNotStartIsAbortedWithWhyFromIdleOnly) {
  const auto out = c.abortStart("not started within start_timeout_s = 60 s; waiting for: node /sequence", 60.0);
  EXPECT_TRUE(out.stop_all) << "every robot is told to stop";
  EXPECT_TRUE(out.state_changed);
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_NE(c.reason().find("node /sequence"), std::string::npos) << c.reason();
  EXPECT_FALSE(c.start(61.0).decision) << "an aborted run needs a reset first";
  // Once a run is under way, abortStart changes nothing (abortRun is for that).
  Coordinator k{dir.spec, CoordinatorConfig{}, ends};
  k.onEntities(observe(start), 0);
  ASSERT_TRUE(k.start(0).decision);
  EXPECT_FALSE(k.abortStart("late", 1.0).stop_all);
  EXPECT_EQ(k.state(), RunState::Deciding);
}

TEST_F(Fixture, TheLastDecisionKeepsItsProbabilities) {
  c.onEntities(observe(start), 0);
  const auto s = c.start(0);
  const Decision d = replayDecision(demo, s.decision->history);
  DecisionProbabilities p;
  p.tokens.assign(d.tokens.size(), 0.75);
  p.end = 0.01;
  c.onDecision(s.decision->id, d, 0.1, p);
  ASSERT_TRUE(c.lastDecision());
  EXPECT_EQ(c.lastDecision()->probabilities.tokens, p.tokens);
  EXPECT_DOUBLE_EQ(c.lastDecision()->probabilities.end, 0.01);
  // Probabilities that do not fit the tokens are refused.
  Coordinator k{dir.spec, CoordinatorConfig{}, ends};
  k.onEntities(observe(start), 0);
  const auto s2 = k.start(0);
  p.tokens.push_back(0.5);
  k.onDecision(s2.decision->id, d, 0.1, p);
  EXPECT_EQ(k.state(), RunState::Aborted);
}

namespace {

/// Runs `demo`'s task on `c` with ideal execution; returns every request and segment id it
/// issued, in order.
std::vector<uint32_t> runTaskIds(Coordinator& c, const task::Demonstration& demo) {
  std::vector<uint32_t> ids;
  std::vector<Vector2d> pos = demo.positions.front();
  c.onEntities(observe(pos), 0);
  auto out = c.start(0);
  double t = 0;
  while (out.decision) {
    ids.push_back(out.decision->id);
    t += 1;
    out = c.onDecision(out.decision->id, replayDecision(demo, out.decision->history), t);
    if (c.state() == RunState::Finished) break;
    for (const auto& r : out.paths) ids.push_back(r.id);
    const auto segs = answerPaths(c, out, t);
    out = {};
    for (const auto& s : segs) {
      ids.push_back(s.segment_id);
      pos[s.entity] = s.goal;
      c.onEntities(observe(pos), t);
      auto o = arriveDone(c, s, t);
      if (o.decision) out = o;
    }
  }
  EXPECT_EQ(c.state(), RunState::Finished);
  return ids;
}

}  // namespace

// A coordinator restarted mid-session (its node died and came back) must not repeat the ids
// of the one before: a follower still running a segment of it takes a segment with the same
// id for a re-sent copy and ignores it, and a late answer of the sequence node or planner to
// an old request would be taken for the new one's. The node starts each coordinator's ids
// at its wall clock's milliseconds (firstIdAt).
TEST(CoordinatorIds, ARestartedCoordinatorNeverRepeatsTheIdsOfTheOneBefore) {
  const task::TaskDir dir = task4();
  const task::EndPointModel ends = task::learnEndPoints(dir.spec, dir.demos);
  const double t0 = 1796256000.0;  // 2026-12-03, seconds since the epoch
  Coordinator before(dir.spec, CoordinatorConfig{}, ends, firstIdAt(t0));
  const std::vector<uint32_t> old_ids = runTaskIds(before, dir.demos.front());
  ASSERT_FALSE(old_ids.empty());
  // Restarted a second later, it runs the task again.
  Coordinator after(dir.spec, CoordinatorConfig{}, ends, firstIdAt(t0 + 1.0));
  const std::vector<uint32_t> new_ids = runTaskIds(after, dir.demos.front());
  for (uint32_t id : new_ids) {
    EXPECT_EQ(std::count(old_ids.begin(), old_ids.end(), id), 0) << "id " << id << " repeated";
    EXPECT_NE(id, 0u);
  }
  // Two coordinators constructed alike (the default: 1) would repeat every one of them.
  Coordinator a(dir.spec, CoordinatorConfig{}, ends), b(dir.spec, CoordinatorConfig{}, ends);
  EXPECT_EQ(runTaskIds(a, dir.demos.front()), runTaskIds(b, dir.demos.front()));
}

// Ids count up past 0 (0 is "none" on the wire), and no wall clock gives 0.
TEST(CoordinatorIds, AreNeverZero) {
  const task::TaskDir dir = task4();
  Coordinator c(dir.spec, CoordinatorConfig{}, task::learnEndPoints(dir.spec, dir.demos), 0xfffffffeu);
  const std::vector<uint32_t> ids = runTaskIds(c, dir.demos.front());
  ASSERT_GE(ids.size(), 3u);
  EXPECT_EQ(ids[0], 0xfffffffeu);
  EXPECT_EQ(ids[1], 0xffffffffu);
  EXPECT_EQ(ids[2], 1u);
  EXPECT_EQ(firstIdAt(2147483.648), 1u);  // 2^31 ms: 0 modulo 2^31
  EXPECT_EQ(firstIdAt(-1.0), 1u);
  EXPECT_EQ(firstIdAt(std::numeric_limits<double>::quiet_NaN()), 1u);
}

// A carrier that pushes its load backs off it when done (RobotController::backOff): the
// coordinator judges it where it then stands (exec::carrierEnd), kPushBackOffM beyond the
// contact behind the load's end where its path stops; a carrier whose load rides, at that
// contact. Judged at contact, a pushing carrier spent 2 of the 3 cm arrival radius backing
// off, and a DONE from where it stands backed off and as far again on was ignored.
// A fetch (seed 3) replayed until its carry goes out: `run` holds the coordinator (without
// recovery) and the carrier's and the load's segments.
struct FetchCarry {
  task::TaskDir dir = fetchTask();
  const task::Demonstration& demo = dir.demos.front();
  const int b1 = dir.spec.entityIndex("B1");
  std::optional<Coordinator> c;
  SegmentCommand robot, load;
  size_t step = 0;  ///< the carry's step

  static task::TaskDir fetchTask() {
    tasks::GeneratorOptions o;
    o.family = "fetch";
    o.demos = 2;
    o.seed = 3;
    return tasks::generate(o);
  }
  /// Runs the steps before the carry (each arriving) and the carry's decision; false (with
  /// a test failure) when no carry of B1 by one robot went out.
  bool run(bool loads_ride) {
    CoordinatorConfig cfg = withoutRecovery();
    cfg.loads_ride = loads_ride;
    c.emplace(dir.spec, cfg, task::learnEndPoints(dir.spec, dir.demos));
    c->onEntities(observe(demo.positions.front()), 0.0);
    CoordinatorOutput next = c->start(0.0);
    std::vector<SegmentCommand> carry;
    for (double now = 0.1; next.decision && carry.empty() && now < 20; now += 1) {  // a few steps, never a hang
      const auto segs =
          answerPaths(*c, c->onDecision(next.decision->id, replayDecision(demo, next.decision->history), now), now);
      if (std::any_of(segs.begin(), segs.end(), [&](const SegmentCommand& g) { return g.entity == b1; })) carry = segs;
      for (const auto& g : segs)
        if (carry.empty()) next = arriveDone(*c, g, now + 0.5);
    }
    EXPECT_EQ(carry.size(), 2u) << "the carrier and its load: " << c->reason();
    if (carry.size() != 2u) return false;
    step = c->steps().size() - 1;
    robot = carry[0].entity == b1 ? carry[1] : carry[0];
    load = carry[0].entity == b1 ? carry[0] : carry[1];
    return true;
  }
};

TEST(CoordinatorPush, APushingCarrierIsJudgedWhereItStandsBackedOffItsLoad) {
  for (const bool ride : {true, false}) {
    SCOPED_TRACE(ride ? "riding" : "pushed");
    FetchCarry f;
    ASSERT_TRUE(f.run(ride));
    Coordinator& c = *f.c;
    const task::TaskDir& dir = f.dir;
    const int b1 = f.b1;
    const size_t k = f.step;
    const SegmentCommand &robot = f.robot, &load = f.load;
    const Vector2d push_end = robot.path.points.back();
    const double contact = dir.spec.contactDistance(robot.entity, b1);
    ASSERT_NEAR((push_end - load.goal).norm(), contact, 1e-6) << "the push stops at contact behind the load's end";
    const double beyond = ride ? 0.0 : kPushBackOffM;
    EXPECT_NEAR((robot.goal - load.goal).norm(), contact + beyond, 1e-6);
    EXPECT_NEAR((robot.goal - push_end).norm(), beyond, 1e-6) << "straight away from the load's end";
    EXPECT_TRUE(c.steps()[k].tokens[0].goal.isApprox(robot.goal) || c.steps()[k].tokens[1].goal.isApprox(robot.goal))
        << "the run's record judges it there";
    // Done where it stands (backed off, for a pushing carrier) and 3 cm farther on, within
    // the arrival radius: 5 cm from the contact for a pushing carrier.
    const Vector2d away = (push_end - load.goal).normalized();
    EntityObservation obs = c.observation();
    obs.positions[static_cast<size_t>(robot.entity)] = push_end + (beyond + 0.03) * away;
    obs.positions[static_cast<size_t>(b1)] = load.goal;
    c.onEntities(obs, 20.0);
    c.onSegmentStatus(report(c, b1, load.segment_id, SegmentState::Done, 1.0), 20.0);
    c.onSegmentStatus(report(c, robot.entity, robot.segment_id, SegmentState::Done, 1.0), 20.0);
    EXPECT_TRUE(c.steps()[k].complete) << "its DONE counts";
  }
}

// A pushing carrier stops where its load does: a box that ended 2.5 cm to the side of its
// end point (within its arrival radius) has its carrier behind it, backed off, 2.5 cm to the
// side of where it was planned to stand. The coordinator judges it behind where the box is
// tracked when it reports DONE (exec::carrierEnd, as the simulator does), and the run's
// record says so: scored against the planned place, with the box 3 cm off, the carrier was
// "stopped 4-5 cm from its end point" in the simulator (zoo:41/direct-4mm scenes 7 and 8).
TEST(CoordinatorPush, APushingCarrierIsJudgedBehindWhereItsLoadEnded) {
  FetchCarry f;
  ASSERT_TRUE(f.run(/*loads_ride=*/false));
  Coordinator& c = *f.c;
  const int b1 = f.b1;
  const size_t k = f.step;
  const SegmentCommand &robot = f.robot, &load = f.load;
  const Vector2d away = (robot.path.points.back() - load.goal).normalized(), side(-away.y(), away.x());
  const Vector2d box = load.goal + 0.025 * side, behind = robot.goal + 0.025 * side;
  EntityObservation obs = c.observation();
  obs.positions[static_cast<size_t>(robot.entity)] = behind;
  obs.positions[static_cast<size_t>(b1)] = box;
  c.onEntities(obs, 20.0);
  c.onSegmentStatus(report(c, b1, load.segment_id, SegmentState::Done, 1.0), 20.0);
  c.onSegmentStatus(report(c, robot.entity, robot.segment_id, SegmentState::Done, 1.0), 20.0);
  EXPECT_TRUE(c.steps()[k].complete) << "its DONE counts";
  for (const TokenRecord& t : c.steps()[k].tokens) {
    if (t.token.entity == robot.entity) {
      EXPECT_LT((t.goal - behind).norm(), 1e-6) << "the run's record judges it behind where its box ended";
    }
  }
}
