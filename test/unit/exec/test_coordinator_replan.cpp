// The coordinator re-plans a token when the table changes under it
// (CoordinatorConfig::max_replans): a segment that failed (a robot pushed off its path or
// blocked), timed out (stalled), or whose target moved; it aborts naming why when it may not.
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <optional>

#include "ddace/exec/coordinator.h"
#include "ddace/exec/replay.h"
#include "ddace/task/body_geometry.h"
#include "ddace/tasks/generators.h"
#include "ddace/tasks/rule_zoo.h"

using namespace ddace;
using namespace ddace::exec;
using Eigen::Vector2d;

namespace {

/// One generated demonstration of `family` (seed 3).
task::TaskDir generated(const std::string& family) {
  tasks::GeneratorOptions o;
  o.family = family;
  o.demos = 1;
  o.seed = 3;
  return tasks::generate(o);
}

task::TaskDir task4() {
  return generated("task4");
}

EntityObservation observe(const std::vector<Vector2d>& positions) {
  return {positions, std::vector<bool>(positions.size(), true)};
}

std::vector<SegmentCommand> answer(Coordinator& c, const CoordinatorOutput& out, double now) {
  std::vector<SegmentCommand> segs;
  for (const auto& r : out.paths) {
    const auto o = c.onPath(r.id, {{r.start, r.goal}, {0, 0}}, "", now);
    segs.insert(segs.end(), o.segments.begin(), o.segments.end());
  }
  return segs;
}

/// Step 1 decided by a replay of `demo` with the entities at `at`, and its segments out
/// (Task 4: R1:move:R3, R2:move:R4).
std::vector<SegmentCommand> firstStep(Coordinator& c, const task::Demonstration& demo,
                                      const std::vector<Vector2d>& at) {
  c.onEntities(observe(at), 0.0);
  const auto s = c.start(0.0);
  return answer(c, c.onDecision(s.decision->id, replayDecision(demo, s.decision->history), 0.1), 0.2);
}

bool stops(const CoordinatorOutput& out, int entity) {
  return std::find(out.stop.begin(), out.stop.end(), entity) != out.stop.end();
}

/// `count` demonstrations of zoo:two-boxes (seed 3): two robots fetch the two boxes.
task::TaskDir twoBoxes(int count) {
  uint64_t rule = 0;
  EXPECT_TRUE(tasks::parseZooFamily("zoo:two-boxes", rule));
  return tasks::generateZoo(rule, count, 3);
}

/// Robots `a` and `b` half-way from `begun` to their ends `a_end`, `b_end`, observed at
/// `now`; then a hand puts `box` down 5 cm from `mover` (a or b) on the side it came from, at
/// one place with it (task::together), and nothing is at one place with the other robot.
/// Returns the coordinator's output of that observation.
CoordinatorOutput boxPutBesideOneOfTwo(Coordinator& c, std::vector<Vector2d>& at, const std::vector<Vector2d>& begun,
                                       size_t a, const Vector2d& a_end, size_t b, const Vector2d& b_end, size_t box,
                                       size_t mover, double now, const std::function<void(CoordinatorOutput)>& handle) {
  const task::TaskSpec& spec = c.spec();
  at[a] = (begun[a] + a_end) / 2;
  at[b] = (begun[b] + b_end) / 2;
  handle(c.onEntities(observe(at), now));
  at[box] = at[mover] + 0.05 * (begun[mover] - at[mover]).normalized();
  EXPECT_TRUE(task::together(spec, int(mover), at[mover], int(box), at[box]));
  const size_t other = mover == a ? b : a;
  for (size_t f = 0; f < at.size(); ++f)
    EXPECT_TRUE(f == other || !task::together(spec, int(other), at[other], int(f), at[f]));
  return c.onEntities(observe(at), now + 0.5);
}

struct Replan : ::testing::Test {
  task::TaskDir dir = task4();
  const task::Demonstration& demo = dir.demos.front();
  std::vector<Vector2d> at = demo.positions.front();
  // A replay decides in a fixed order: the step is kept and the token re-planned.
  Coordinator c{dir.spec, config(), task::learnEndPoints(dir.spec, dir.demos), 1, {}, /*policy_reads_scene=*/false};

  // Recovery as configured by default (max_replans 2): what a user's run does.
  static CoordinatorConfig config() { return CoordinatorConfig{}; }
  std::vector<SegmentCommand> firstStep() { return ::firstStep(c, demo, at); }
  CoordinatorOutput arrive(const SegmentCommand& s, double now) {
    at[static_cast<size_t>(s.entity)] = s.goal;
    c.onEntities(observe(at), now);
    return c.onSegmentStatus(s.entity, s.segment_id, SegmentState::Done, 1.0, "", now);
  }
};

}  // namespace

TEST_F(Replan, ARobotPushedOffItsPathIsReplannedFromWhereItIsAndTheRunGoesOn) {
  const auto segs = firstStep();
  ASSERT_EQ(segs.size(), 2u);
  const SegmentCommand& r1 = segs[0];
  // Pushed 5 cm off its way; its follower fails the segment.
  const Vector2d pushed = (at[static_cast<size_t>(r1.entity)] + r1.goal) / 2 + Vector2d(0, 0.05);
  at[static_cast<size_t>(r1.entity)] = pushed;
  c.onEntities(observe(at), 1.0);
  const auto out = c.onSegmentStatus(r1.entity, r1.segment_id, SegmentState::Failed, 0.4, "off the path band", 1.0);
  EXPECT_TRUE(c.running()) << c.reason();
  EXPECT_TRUE(stops(out, r1.entity));
  ASSERT_EQ(out.paths.size(), 1u);
  EXPECT_EQ(out.paths[0].token, r1.token);
  EXPECT_EQ(out.paths[0].start, pushed);
  EXPECT_TRUE(out.paths[0].goal.isApprox(r1.goal, 1e-9));  // its target did not move
  const auto again = answer(c, out, 1.1);
  ASSERT_EQ(again.size(), 1u);
  EXPECT_NE(again[0].segment_id, r1.segment_id);
  // The old segment's late DONE counts for nothing; the new one's does.
  EXPECT_FALSE(c.onSegmentStatus(r1.entity, r1.segment_id, SegmentState::Done, 1.0, "", 1.2).decision);
  arrive(segs[1], 2.0);
  const auto next = arrive(again[0], 3.0);
  EXPECT_TRUE(next.decision) << "step 2 is decided once both tokens of step 1 ended; " << toString(c.state()) << " "
                             << c.reason() << " " << (next.log.empty() ? "" : next.log.back());
}

TEST_F(Replan, AStalledRobotIsReplannedAfterItsTimeOutThenTheRunAbortsNamingWhy) {
  const auto segs = firstStep();
  arrive(segs[0], 1.0);  // R1 arrives; R2 stalls where it is
  int replans = 0;
  double now = 1.0;
  for (int i = 0; i < 20 && c.running(); ++i) {
    now += 200;  // past any segment's time-out
    const auto out = c.onTick(now);
    for (const auto& p : out.paths) {
      EXPECT_EQ(p.token, segs[1].token);
      EXPECT_TRUE(stops(out, segs[1].entity));
      ++replans;
    }
    answer(c, out, now);
  }
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_EQ(replans, 2) << "re-planned max_replans times";
  EXPECT_EQ(c.replans(), 2);
  EXPECT_NE(c.reason().find("R2:move:R4"), std::string::npos) << c.reason();
  EXPECT_NE(c.reason().find("timed out"), std::string::npos) << c.reason();
  EXPECT_NE(c.reason().find("max_replans = 2"), std::string::npos) << c.reason();
}

TEST_F(Replan, ATargetMovedBeyondTheArrivalRadiusIsReplannedToWhereItIsNow) {
  const auto segs = firstStep();
  const SegmentCommand& r1 = segs[0];  // R1:move:R3
  const auto r3 = static_cast<size_t>(r1.token.target);
  const Vector2d before = at[r3];
  // Tracking noise and a nudge within the arrival radius change nothing.
  at[r3] = before + Vector2d(0.01, 0);
  const auto small = c.onEntities(observe(at), 1.0);
  EXPECT_TRUE(small.paths.empty());
  EXPECT_TRUE(small.stop.empty());
  // Moved 6 cm by a hand: R1 stops and goes to where R3 is now.
  at[r3] = before + Vector2d(0.06, 0);
  const auto moved = c.onEntities(observe(at), 1.5);
  EXPECT_TRUE(c.running()) << c.reason();
  EXPECT_TRUE(stops(moved, r1.entity));
  ASSERT_EQ(moved.paths.size(), 1u);
  EXPECT_EQ(moved.paths[0].token, r1.token);
  EXPECT_LT((moved.paths[0].goal - at[r3]).norm(), (r1.goal - at[r3]).norm());
  EXPECT_NEAR((moved.paths[0].goal - at[r3]).norm(), (r1.goal - before).norm(), 0.02);
  EXPECT_FALSE(answer(c, moved, 1.6).empty());
}

TEST_F(Replan, AFailedSegmentOfARobotTheTrackerLostAbortsNamingIt) {
  const auto segs = firstStep();
  EntityObservation obs = observe(at);
  obs.tracked[static_cast<size_t>(segs[0].entity)] = false;
  c.onEntities(obs, 1.0);
  const auto out = c.onSegmentStatus(segs[0].entity, segs[0].segment_id, SegmentState::Failed, 0.2, "pose stale", 1.0);
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_TRUE(out.stop_all);
  EXPECT_NE(c.reason().find("R1 is lost"), std::string::npos) << c.reason();
  EXPECT_NE(c.reason().find("pose stale"), std::string::npos) << c.reason();
}

TEST(ReplanOff, WithoutReplansAFailureAbortsAndAMovedTargetIsNotFollowed) {
  const task::TaskDir dir = task4();
  CoordinatorConfig cfg;
  cfg.max_replans = 0;
  Coordinator c{dir.spec, cfg, task::learnEndPoints(dir.spec, dir.demos)};
  std::vector<Vector2d> at = dir.demos.front().positions.front();
  const auto segs = firstStep(c, dir.demos.front(), at);
  ASSERT_EQ(segs.size(), 2u);
  at[static_cast<size_t>(segs[0].token.target)] += Vector2d(0.06, 0);
  EXPECT_TRUE(c.onEntities(observe(at), 1.0).paths.empty());
  c.onSegmentStatus(segs[0].entity, segs[0].segment_id, SegmentState::Failed, 0.2, "blocked", 1.0);
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_NE(c.reason().find("blocked"), std::string::npos) << c.reason();
}

// A policy that reads the scene re-decides the step instead: every token of it that has not
// ended stops, and the step is asked for again from a snapshot of now in place of the one it
// was decided from; after max_replans re-decisions of the step the run aborts naming why.
TEST(Redecide, AMovedTargetWithdrawsTheStepAndAsksForItAgainFromTheSceneOfNow) {
  const task::TaskDir dir = task4();
  CoordinatorConfig cfg;
  cfg.max_replans = 1;
  Coordinator c{dir.spec, cfg, task::learnEndPoints(dir.spec, dir.demos)};  // reads the scene
  const task::Demonstration& demo = dir.demos.front();
  std::vector<Vector2d> at = demo.positions.front();
  const auto segs = firstStep(c, demo, at);
  ASSERT_EQ(segs.size(), 2u);
  // R1 arrives; then R2's target is moved 6 cm by a hand.
  at[static_cast<size_t>(segs[0].entity)] = segs[0].goal;
  c.onEntities(observe(at), 1.0);
  c.onSegmentStatus(segs[0].entity, segs[0].segment_id, SegmentState::Done, 1.0, "", 1.0);
  const auto r4 = static_cast<size_t>(segs[1].token.target);
  at[r4] += Vector2d(0.06, 0);
  const auto out = c.onEntities(observe(at), 1.5);
  EXPECT_TRUE(c.running()) << c.reason();
  EXPECT_TRUE(stops(out, segs[1].entity));
  EXPECT_FALSE(stops(out, segs[0].entity)) << "R1's token had ended";
  EXPECT_TRUE(out.paths.empty()) << "not re-planned: re-decided";
  ASSERT_TRUE(out.decision);
  EXPECT_EQ(out.decision->step, 0);
  ASSERT_EQ(out.decision->history.size(), 1u);
  EXPECT_TRUE(out.decision->history.back().positions[r4].isApprox(at[r4]));
  EXPECT_EQ(c.redecisions(), 1);
  ASSERT_EQ(c.withdrawnSteps().size(), 1u);
  EXPECT_TRUE(c.steps().empty());
  // The old segment's late DONE counts for nothing.
  EXPECT_FALSE(c.onSegmentStatus(segs[1].entity, segs[1].segment_id, SegmentState::Done, 1.0, "", 1.6).decision);
  // The same step again (a replay decides so): R2 now goes to where R4 is.
  const auto again = answer(c, c.onDecision(out.decision->id, replayDecision(demo, out.decision->history), 1.7), 1.8);
  ASSERT_EQ(again.size(), 2u);
  for (const auto& g : again)
    if (g.entity == segs[1].entity) {
      EXPECT_LT((g.goal - at[r4]).norm(), (segs[1].goal - at[r4]).norm());
    }
  // Moved again: the step was re-decided max_replans times, so the run aborts naming why.
  at[r4] += Vector2d(0.06, 0);
  c.onEntities(observe(at), 2.0);
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_NE(c.reason().find("R4 moved"), std::string::npos) << c.reason();
  EXPECT_NE(c.reason().find("max_replans = 1"), std::string::npos) << c.reason();
}

TEST(Redecide, ARobotBlockedPastItsReplansIsReDecidedAndANoDecisionAbortsNamingWhy) {
  const task::TaskDir dir = task4();
  CoordinatorConfig cfg;
  cfg.max_replans = 2;
  Coordinator c{dir.spec, cfg, task::learnEndPoints(dir.spec, dir.demos)};
  std::vector<Vector2d> at = dir.demos.front().positions.front();
  const auto segs = firstStep(c, dir.demos.front(), at);
  ASSERT_EQ(segs.size(), 2u);
  // Blocked: first re-planned from where it stands (twice), then the step is re-decided.
  auto out = c.onSegmentStatus(segs[0].entity, segs[0].segment_id, SegmentState::Failed, 0.3, "blocked", 1.0);
  for (int i = 0; i < 2; ++i) {
    ASSERT_FALSE(out.decision);
    ASSERT_EQ(out.paths.size(), 1u);
    const auto again = answer(c, out, 1.0 + i);
    ASSERT_EQ(again.size(), 1u);
    out = c.onSegmentStatus(again[0].entity, again[0].segment_id, SegmentState::Failed, 0.3, "blocked", 1.5 + i);
  }
  EXPECT_EQ(c.replans(), 2);
  ASSERT_TRUE(out.decision) << "re-plans used up: the step is decided again";
  c.onDecisionError(out.decision->id, "no token fits the scene", 1.1);
  EXPECT_EQ(c.state(), RunState::Aborted);
  EXPECT_NE(c.reason().find("no token fits the scene"), std::string::npos) << c.reason();
}

// A robot lost for good (CoordinatorConfig::robot_lost_after_s): its segment fails while the
// tracker does not see it, and the run goes on without it -- the step is decided again and
// the request names it lost; a decision that still needs it aborts naming it, and so does a
// fixed order, which would name it again.
TEST(Redecide, ARobotLostForGoodIsLeftOutOfTheNextDecisionOrTheRunAbortsNamingIt) {
  const task::TaskDir dir = task4();
  const task::Demonstration& demo = dir.demos.front();
  CoordinatorConfig cfg;
  cfg.max_replans = 1;
  for (const bool reads_scene : {true, false}) {
    SCOPED_TRACE(reads_scene ? "reads the scene" : "a fixed order");
    Coordinator c{dir.spec, cfg, task::learnEndPoints(dir.spec, dir.demos), 1, {}, reads_scene};
    std::vector<Vector2d> at = demo.positions.front();
    c.onEntities(observe(at), 0.0);
    const auto s = c.start(0.0);
    EXPECT_TRUE(s.decision->lost.empty());
    const auto segs = answer(c, c.onDecision(s.decision->id, replayDecision(demo, s.decision->history), 0.1), 0.2);
    ASSERT_EQ(segs.size(), 2u);
    // R1's battery dies: the tracker loses it, its follower fails its segment.
    const int r1 = segs[0].entity;
    EntityObservation obs = observe(at);
    obs.tracked[static_cast<size_t>(r1)] = false;
    c.onEntities(obs, 1.0);
    const auto out = c.onSegmentStatus(r1, segs[0].segment_id, SegmentState::Failed, 0.3, "pose of R1 is stale", 1.2);
    ASSERT_EQ(c.lostRobots().size(), 1u);
    EXPECT_EQ(c.lostRobots()[0].rfind(dir.spec.entities[static_cast<size_t>(r1)].name + ": ", 0), 0u);
    if (!reads_scene) {
      EXPECT_EQ(c.state(), RunState::Aborted);
      EXPECT_NE(c.reason().find("is lost"), std::string::npos) << c.reason();
      EXPECT_NE(c.reason().find("fixed order"), std::string::npos) << c.reason();
      continue;
    }
    EXPECT_TRUE(c.running()) << c.reason();
    EXPECT_TRUE(stops(out, r1));
    ASSERT_TRUE(out.decision) << "the step is decided again without it";
    EXPECT_EQ(out.decision->lost, std::vector<int>{r1});
    // The policy still sends it: no decision without it.
    c.onDecision(out.decision->id, replayDecision(demo, out.decision->history), 1.3);
    EXPECT_EQ(c.state(), RunState::Aborted);
    EXPECT_NE(c.reason().find("is lost"), std::string::npos) << c.reason();
    EXPECT_NE(c.reason().find("no decision without it"), std::string::npos) << c.reason();
  }
}

// A robot untracked past robot_lost_after_s while it stands idle is lost too: the decision
// waiting for every entity to be tracked goes ahead without it.
TEST(Redecide, ARobotUntrackedPastItsLimitIsLostAndTheDecisionGoesAheadWithoutIt) {
  const task::TaskDir dir = task4();
  CoordinatorConfig cfg;
  cfg.max_replans = 1;
  cfg.robot_lost_after_s = 3;
  Coordinator c{dir.spec, cfg, task::learnEndPoints(dir.spec, dir.demos)};
  EntityObservation obs = observe(dir.demos.front().positions.front());
  const int r2 = dir.spec.entityIndex("R2");
  obs.tracked[static_cast<size_t>(r2)] = false;
  c.onEntities(obs, 0.0);
  EXPECT_FALSE(c.start(0.0).decision) << "waits for R2 to be tracked";
  EXPECT_FALSE(c.onEntities(obs, 2.9).decision);
  const auto out = c.onTick(3.0);
  ASSERT_TRUE(out.decision) << c.reason();
  EXPECT_EQ(out.decision->lost, std::vector<int>{r2});
  ASSERT_EQ(c.lostRobots().size(), 1u);
  EXPECT_NE(c.lostRobots()[0].find("not tracked for 3"), std::string::npos) << c.lostRobots()[0];
}

namespace {

/// Every segment of `segs` arrives at its goal.
CoordinatorOutput arriveAll(Coordinator& c, std::vector<Vector2d>& at, const std::vector<SegmentCommand>& segs,
                            double now) {
  for (const auto& s : segs) at[static_cast<size_t>(s.entity)] = s.goal;
  c.onEntities(observe(at), now);
  CoordinatorOutput last;
  for (const auto& s : segs) last = c.onSegmentStatus(s.entity, s.segment_id, SegmentState::Done, 1.0, "", now);
  return last;
}

/// Robot `e`'s battery dies under its segment `seg`: the tracker loses it, its follower fails.
CoordinatorOutput die(Coordinator& c, const std::vector<Vector2d>& at, const SegmentCommand& seg, double now) {
  EntityObservation obs = observe(at);
  obs.tracked[static_cast<size_t>(seg.entity)] = false;
  c.onEntities(obs, now);
  return c.onSegmentStatus(seg.entity, seg.segment_id, SegmentState::Failed, 0.4, "pose is stale", now + 0.1);
}

}  // namespace

// A carrier lost for good with its load mid-carry leaves the load where no demonstrated
// step continues from: the policy is asked for its first step again, from the scene as it
// is (a history of one snapshot), not for the withdrawn carry after the steps before. A
// robot lost without a load keeps the history: its step is decided again after the others.
TEST(Redecide, ACarrierLostWithItsLoadBeginsTheTaskAgainFromTheSceneAsItIs) {
  const task::TaskDir dir = generated("deliver");
  const task::Demonstration& demo = dir.demos.front();
  ASSERT_EQ(demo.steps.size(), 2u);
  Coordinator c{dir.spec, CoordinatorConfig{}, task::learnEndPoints(dir.spec, dir.demos)};  // reads the scene
  std::vector<Vector2d> at = demo.positions.front();
  c.onEntities(observe(at), 0.0);
  const auto s = c.start(0.0);
  const auto fetch = answer(c, c.onDecision(s.decision->id, replayDecision(demo, s.decision->history), 0.1), 0.2);
  ASSERT_EQ(fetch.size(), 1u);
  const auto next = arriveAll(c, at, fetch, 1.0);
  ASSERT_TRUE(next.decision);
  ASSERT_EQ(next.decision->history.size(), 2u);
  const auto carry = answer(c, c.onDecision(next.decision->id, replayDecision(demo, next.decision->history), 1.1), 1.2);
  ASSERT_EQ(carry.size(), 2u) << "the carrier and its load";
  const auto carrier = std::find_if(carry.begin(), carry.end(), [&](const SegmentCommand& g) {
    return dir.spec.entities[static_cast<size_t>(g.entity)].kind == task::EntityKind::Robot;
  });
  ASSERT_NE(carrier, carry.end());
  const int b1 = dir.spec.entityIndex("B1");
  at[static_cast<size_t>(carrier->entity)] += Vector2d(0.05, 0);  // under way, the load with it
  at[static_cast<size_t>(b1)] += Vector2d(0.05, 0);
  const auto out = die(c, at, *carrier, 2.0);
  EXPECT_TRUE(c.running()) << c.reason();
  ASSERT_TRUE(out.decision) << "decided again without the carrier";
  EXPECT_EQ(out.decision->lost, std::vector<int>{carrier->entity});
  ASSERT_EQ(out.decision->history.size(), 1u) << "the task begun again: the policy's first step";
  EXPECT_EQ(out.decision->history[0].row, 0);
  EXPECT_TRUE(out.decision->history[0].positions[static_cast<size_t>(b1)].isApprox(at[static_cast<size_t>(b1)]))
      << "from where the load lies now";
  EXPECT_EQ(c.steps().size(), 1u) << "the fetch that ran stays in the record";
  bool said = false;
  for (const std::string& l : out.log) said = said || l.find("was lost carrying B1") != std::string::npos;
  EXPECT_TRUE(said);

  // Task 4 read from the scene: R3 lost on its way to G1 carries nothing; step 2 is asked
  // for again after step 1.
  const task::TaskDir t4 = task4();
  Coordinator d{t4.spec, CoordinatorConfig{}, task::learnEndPoints(t4.spec, t4.demos)};
  at = t4.demos.front().positions.front();
  const auto first = firstStep(d, t4.demos.front(), at);
  const auto step2 = arriveAll(d, at, first, 1.0);
  ASSERT_TRUE(step2.decision);
  const auto legs =
      answer(d, d.onDecision(step2.decision->id, replayDecision(t4.demos.front(), step2.decision->history), 1.1), 1.2);
  ASSERT_EQ(legs.size(), 2u);
  const auto again = die(d, at, legs[0], 2.0);
  ASSERT_TRUE(again.decision) << d.reason();
  EXPECT_EQ(again.decision->history.size(), 2u) << "the step decided again after step 1";
}

/// `demo`'s decisions replayed from its first scene, every step before the one that moves
/// `b1` arriving: that step's decision output, its paths not yet answered, and `now` its
/// time; nullopt (a test failure) when no decision moves `b1` within 20.
std::optional<CoordinatorOutput> decideUntilItMoves(Coordinator& c, const task::Demonstration& demo,
                                                    std::vector<Vector2d>& at, int b1, double& now) {
  at = demo.positions.front();
  c.onEntities(observe(at), 0.0);
  CoordinatorOutput next = c.start(0.0);
  for (now = 0.1; next.decision && now < 20; now += 1) {  // a few steps, never a hang
    CoordinatorOutput out = c.onDecision(next.decision->id, replayDecision(demo, next.decision->history), now);
    if (std::any_of(out.paths.begin(), out.paths.end(), [&](const auto& p) { return p.token.entity == b1; }))
      return out;
    next = arriveAll(c, at, answer(c, out, now), now + 0.5);
  }
  ADD_FAILURE() << "no decision moves entity " << b1 << ": " << c.reason();
  return std::nullopt;
}

// A pushed load (loads not riding: the real table, its simulation) moves only with its
// carrier. Its carrier done and the load left short of its end, its own segment sent again
// would have the table move it by hand (mock robots: a box gliding on its own, into the
// robots): a fixed order aborts naming why. A riding load's segment is sent again.
TEST(PushedLoadReplan, IsNeverSentOnAlone) {
  const task::TaskDir dir = generated("fetch");
  const task::Demonstration& demo = dir.demos.front();
  const int b1 = dir.spec.entityIndex("B1");
  for (const bool ride : {true, false}) {
    SCOPED_TRACE(ride ? "riding" : "pushed");
    CoordinatorConfig cfg;
    cfg.loads_ride = ride;
    Coordinator c{dir.spec, cfg, task::learnEndPoints(dir.spec, dir.demos), 1, {}, /*policy_reads_scene=*/false};
    std::vector<Vector2d> at;
    double now = 0;
    const std::optional<CoordinatorOutput> decided = decideUntilItMoves(c, demo, at, b1, now);
    ASSERT_TRUE(decided);
    const std::vector<SegmentCommand> carry = answer(c, *decided, now);
    ASSERT_EQ(carry.size(), 2u) << c.reason();
    const SegmentCommand& robot = carry[0].entity == b1 ? carry[1] : carry[0];
    const SegmentCommand& load = carry[0].entity == b1 ? carry[0] : carry[1];
    at[static_cast<size_t>(robot.entity)] = robot.goal;  // done, its push broken: the box 20 cm short
    at[static_cast<size_t>(b1)] = load.goal + 0.2 * (load.path.points.front() - load.goal).normalized();
    c.onEntities(observe(at), 20.0);
    c.onSegmentStatus(robot.entity, robot.segment_id, SegmentState::Done, 1.0, "", 20.0);
    const auto out = c.onSegmentStatus(b1, load.segment_id, SegmentState::Failed, 0.5,
                                       "B1 is 20.0 cm from its end point when its carrier was done", 20.0);
    if (ride) {
      ASSERT_EQ(out.paths.size(), 1u) << "the riding load re-planned: " << c.reason();
      EXPECT_EQ(out.paths[0].token.entity, b1);
      continue;
    }
    EXPECT_TRUE(out.paths.empty()) << "no path for B1 alone";
    EXPECT_TRUE(out.segments.empty());
    EXPECT_EQ(c.state(), RunState::Aborted);
    const std::string carrier = dir.spec.entities[static_cast<size_t>(robot.entity)].name;
    EXPECT_NE(c.reason().find("nothing moves B1 but its carrier " + carrier), std::string::npos) << c.reason();
  }
}

namespace {

/// fetch, pushed: the path the coordinator sends R1 to push B1 to G1 with R2 standing half-way
/// between them, R2 either tracked there or last seen there (its battery dead, the tracker
/// lost it) when the push is planned.
std::vector<Vector2d> pushPastR2(bool r2_tracked, Vector2d& r2_at) {
  const task::TaskDir dir = generated("fetch");  // R1:move:B1, R1:carry:G1 B1:carry:G1, R2:move:R1
  const task::Demonstration& demo = dir.demos.front();
  const size_t r2 = static_cast<size_t>(dir.spec.entityIndex("R2"));
  const int b1 = dir.spec.entityIndex("B1");
  CoordinatorConfig cfg;
  cfg.loads_ride = false;
  Coordinator c{dir.spec, cfg, task::learnEndPoints(dir.spec, dir.demos), 1, {}, /*policy_reads_scene=*/false};
  std::vector<Vector2d> at;
  double now = 0;
  const std::optional<CoordinatorOutput> carry = decideUntilItMoves(c, demo, at, b1, now);
  if (!carry) return {};
  at[r2] = r2_at = (at[static_cast<size_t>(b1)] + at[static_cast<size_t>(dir.spec.entityIndex("G1"))]) / 2;
  EntityObservation obs = observe(at);
  c.onEntities(obs, now);
  obs.tracked[r2] = r2_tracked;
  c.onEntities(obs, now + 0.1);
  for (const SegmentCommand& s : answer(c, *carry, now + 0.2))
    if (s.entity != b1) return s.path.points;
  ADD_FAILURE() << "no segment for R1's push";
  return {};
}

}  // namespace

// A robot the tracker lost still stands where it was last seen: a push is planned round it
// as round a robot it sees.
TEST(PushedLoadReplan, GoesRoundARobotLastSeenOnItsWay) {
  Vector2d r2;
  const std::vector<Vector2d> seen = pushPastR2(true, r2), lost = pushPastR2(false, r2);
  ASSERT_FALSE(seen.empty());
  double closest = 1e9;
  for (const Vector2d& p : lost) closest = std::min(closest, (p - r2).norm());
  EXPECT_GT(closest, 0.044) << "R1's path keeps its body clear of R2's";
  ASSERT_EQ(lost.size(), seen.size());
  for (size_t i = 0; i < seen.size(); ++i) EXPECT_LT((lost[i] - seen[i]).norm(), 1e-9) << "point " << i;
}

// A decided step that moves what no demonstration moved -- a motion class without a learned
// end or path, such as a team bound without a lost robot carrying one box onto the other --
// is refused: the run aborts naming the motion (and the lost robot), never drives it.
TEST(Redecide, AStepWithAMotionNoDemonstrationHasAbortsNamingIt) {
  const task::TaskDir dir = generated("deliver");  // fetch (robot->object), carry (robot+load->goal, object->goal)
  const task::Demonstration& demo = dir.demos.front();
  const int r1 = dir.spec.entityIndex("R1"), r2 = dir.spec.entityIndex("R2"), g1 = dir.spec.entityIndex("G1");
  const auto started = [&](Coordinator& c) {
    c.onEntities(observe(demo.positions.front()), 0.0);
    return c.start(0.0);
  };
  {
    Coordinator c{dir.spec, CoordinatorConfig{}, task::learnEndPoints(dir.spec, dir.demos)};
    const auto s = started(c);
    const auto out = c.onDecision(s.decision->id, Decision{false, {task::Token{r1, "move", g1}}}, 0.1);
    EXPECT_EQ(c.state(), RunState::Aborted);
    EXPECT_TRUE(out.paths.empty() && out.segments.empty()) << "nothing is driven";
    EXPECT_NE(c.reason().find("R1:move:G1 (robot->goal)"), std::string::npos) << c.reason();
    EXPECT_NE(c.reason().find("no demonstration has such a motion"), std::string::npos) << c.reason();
  }
  {
    // The demonstrated step runs.
    Coordinator c{dir.spec, CoordinatorConfig{}, task::learnEndPoints(dir.spec, dir.demos)};
    const auto s = started(c);
    const auto out = c.onDecision(s.decision->id, replayDecision(demo, s.decision->history), 0.1);
    EXPECT_TRUE(c.running()) << c.reason();
    EXPECT_FALSE(out.paths.empty());
  }
  {
    // R2 lost for good; the step decided without it sends R1 to a goal with nothing to carry
    // (robot->goal): refused, naming R2.
    CoordinatorConfig cfg;
    cfg.robot_lost_after_s = 1;
    Coordinator c{dir.spec, cfg, task::learnEndPoints(dir.spec, dir.demos)};
    EntityObservation obs = observe(demo.positions.front());
    obs.tracked[static_cast<size_t>(r2)] = false;
    c.onEntities(obs, 0.0);
    c.start(0.0);
    const auto out = c.onTick(1.0);
    ASSERT_TRUE(out.decision) << c.reason();
    ASSERT_EQ(out.decision->lost, std::vector<int>{r2});
    c.onDecision(out.decision->id, Decision{false, {task::Token{r1, "move", g1}}}, 1.1);
    EXPECT_EQ(c.state(), RunState::Aborted);
    EXPECT_EQ(c.reason().rfind("R2 is lost and step 1 as decided without it moves R1:move:G1", 0), 0u) << c.reason();
    EXPECT_NE(c.reason().find("no decision without it"), std::string::npos) << c.reason();
  }
}

// The policy reads a step's motion from one decision's scene to the next, and never saw a
// robot stopped part-way at one place with a box it was not yet at. A box put down by a hand
// beside the robot driving to it: the step is decided again reading that robot where the
// step began (a robot part-way and at one place with nothing is read where it is), and the
// decision after it reads the re-decided step's motion from where the step began.
TEST(Redecide, ARobotAtOnePlaceWithItsMovedTargetIsReadWhereItsStepBegan) {
  const task::TaskDir dir = twoBoxes(1);
  const task::TaskSpec& spec = dir.spec;
  const task::Demonstration& demo = dir.demos.front();
  Coordinator c{spec, CoordinatorConfig{}, task::learnEndPoints(spec, dir.demos)};  // reads the scene
  const std::vector<Vector2d> begun = demo.positions.front();
  std::vector<Vector2d> at = begun;
  const auto segs = firstStep(c, demo, at);
  ASSERT_EQ(segs.size(), 2u) << "two robots fetch the two boxes";
  const auto a = static_cast<size_t>(segs[0].entity), b = static_cast<size_t>(segs[1].entity);
  const auto box = static_cast<size_t>(segs[0].token.target);
  // Both robots half-way; a hand puts robot a's box down 5 cm from it, on the side it came from.
  const auto out =
      boxPutBesideOneOfTwo(c, at, begun, a, segs[0].goal, b, segs[1].goal, box, a, 1.0, [](CoordinatorOutput) {});
  ASSERT_TRUE(out.decision) << c.reason();
  ASSERT_EQ(out.decision->history.size(), 1u);
  const std::vector<Vector2d>& read = out.decision->history.back().positions;
  EXPECT_TRUE(read[a].isApprox(begun[a])) << "read where its step began, not at one place with the box";
  EXPECT_TRUE(read[b].isApprox(at[b])) << "at one place with nothing: read where it is";
  EXPECT_TRUE(read[box].isApprox(at[box])) << "the box where the hand put it";
  // Decided again as before; both robots arrive, and step 2's history reads step 1's motion
  // from where step 1 began.
  const auto again = answer(c, c.onDecision(out.decision->id, replayDecision(demo, out.decision->history), 1.6), 1.7);
  ASSERT_EQ(again.size(), 2u);
  CoordinatorOutput next;
  for (const SegmentCommand& s : again) {
    at[static_cast<size_t>(s.entity)] = s.goal;
    c.onEntities(observe(at), 2.0);
    next = c.onSegmentStatus(s.entity, s.segment_id, SegmentState::Done, 1.0, "", 2.0);
  }
  ASSERT_TRUE(next.decision) << c.reason();
  ASSERT_EQ(next.decision->history.size(), 2u);
  EXPECT_TRUE(next.decision->history[0].positions[a].isApprox(begun[a]));
  EXPECT_TRUE(next.decision->history[0].positions[b].isApprox(begun[b]));
  EXPECT_TRUE(next.decision->history[0].positions[box].isApprox(at[box]));
}

// The same under async, for a step re-decided while a step before it still runs: the
// decision is asked ahead (from the scene the running step will leave), and it must read the
// re-decided step's mover where the step began all the same, and the step decided again must
// be recorded with it there once the scene settled. Step 1 fetches one box; step 2, decided
// ahead, sends another robot to the other box at once (it shares nothing with step 1); a
// hand puts that box down beside it while step 1's robot is still on its way.
TEST(Redecide, UnderAsyncAStepReDecidedWhileAnEarlierOneRunsReadsItsMoverWhereItBegan) {
  const task::TaskDir dir = twoBoxes(4);
  const task::TaskSpec& spec = dir.spec;
  const task::Demonstration& demo = dir.demos.front();
  CoordinatorConfig cfg;
  cfg.dispatch = DispatchMode::Async;
  Coordinator c{spec, cfg, task::learnEndPoints(spec, dir.demos), 1, graph::learnDependencies(spec, dir.demos)};
  const std::vector<task::Token>& fetches = demo.steps.front().tokens;
  ASSERT_EQ(fetches.size(), 2u) << "two robots fetch the two boxes";
  const task::Token first = fetches[0], second = fetches[1];
  const auto a = static_cast<size_t>(first.entity), b = static_cast<size_t>(second.entity);
  const auto box = static_cast<size_t>(second.target);
  const std::vector<Vector2d> begun = demo.positions.front();
  std::vector<Vector2d> at = begun;
  std::vector<DecisionRequest> asked;
  std::vector<SegmentCommand> running;
  // Decides `steps` in turn (then END), answers paths with straight ones.
  std::vector<std::vector<task::Token>> steps{{first}, {second}, {second}};
  double now = 0;
  const std::function<void(CoordinatorOutput)> handle = [&](CoordinatorOutput o) {
    for (int e : o.stop)
      running.erase(std::remove_if(running.begin(), running.end(), [&](const auto& s) { return s.entity == e; }),
                    running.end());
    running.insert(running.end(), o.segments.begin(), o.segments.end());
    for (const auto& p : o.paths) handle(c.onPath(p.id, {{p.start, p.goal}, {0, 0}}, "", now));
    if (o.decision) {
      asked.push_back(*o.decision);
      const bool end = asked.size() > steps.size();
      handle(
          c.onDecision(o.decision->id, Decision{end, end ? std::vector<task::Token>{} : steps[asked.size() - 1]}, now));
    }
  };
  const auto segmentOf = [&](size_t e) {
    const auto s = std::find_if(running.begin(), running.end(), [&](const auto& g) { return g.entity == int(e); });
    EXPECT_NE(s, running.end()) << spec.entities[e].name << " has no segment";
    return s == running.end() ? SegmentCommand{} : *s;
  };
  const auto arrive = [&](size_t e, double at_s) {
    now = at_s;
    const SegmentCommand s = segmentOf(e);
    at[e] = s.goal;
    handle(c.onEntities(observe(at), now));
    handle(c.onSegmentStatus(s.entity, s.segment_id, SegmentState::Done, 1.0, "", now));
  };
  c.onEntities(observe(at), 0.0);
  handle(c.start(0.0));
  ASSERT_EQ(asked.size(), 2u) << "step 2 asked ahead while step 1 runs";
  ASSERT_EQ(running.size(), 2u) << "step 2's robot left at once: " << c.reason();
  // Both half-way; the hand puts b's box down 5 cm from b, on the side it came from.
  now = 1.0;
  const CoordinatorOutput put =
      boxPutBesideOneOfTwo(c, at, begun, a, segmentOf(a).goal, b, segmentOf(b).goal, box, b, now, handle);
  now = 1.5;
  handle(put);
  ASSERT_EQ(c.redecisions(), 1) << c.reason();
  ASSERT_EQ(asked.size(), 3u);
  const DecisionRequest& again = asked[2];
  ASSERT_EQ(again.step, 1);
  const std::vector<int> active = c.activeEntities();
  ASSERT_NE(std::find(active.begin(), active.end(), int(a)), active.end()) << "step 1's robot still runs";
  const std::vector<Vector2d>& read = again.history.back().positions;
  EXPECT_TRUE(read[b].isApprox(begun[b])) << "read where its step began, not at one place with the box";
  EXPECT_TRUE(read[box].isApprox(at[box])) << "the box where the hand put it";
  EXPECT_FALSE(read[a].isApprox(at[a])) << "step 1's robot where its step will leave it";
  // b arrives at the box, then a at its own: the step decided again holds, and the decision
  // after it reads b's motion from where step 2 began.
  arrive(b, 2.0);
  arrive(a, 3.0);
  ASSERT_GE(asked.size(), 4u) << c.reason();
  EXPECT_EQ(c.withdrawnSteps().size(), 1u) << "only the re-decided step is withdrawn: the one decided again held";
  EXPECT_TRUE(asked[3].history[1].positions[b].isApprox(begun[b])) << asked[3].history[1].positions[b].transpose();
  EXPECT_EQ(c.dispatch()->violations(), 0);
}
