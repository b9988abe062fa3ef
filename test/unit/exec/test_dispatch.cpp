// The coordinator's dispatch rule: include/ddace/exec/dispatch.h.
#include <gtest/gtest.h>

#include "ddace/common/error.h"
#include "ddace/exec/dispatch.h"
#include "ddace/tasks/generators.h"

using namespace ddace;
using exec::DispatchMode;
using exec::TokenRef;

namespace {

std::vector<task::Token> tokens(const task::TaskSpec& spec, const std::vector<std::string>& keys) {
  std::vector<task::Token> out;
  for (const auto& k : keys) out.push_back(task::parseTokenKey(k, spec));
  return out;
}

task::TaskDir task4(int demos) {
  tasks::GeneratorOptions o;
  o.family = "task4";
  o.demos = demos;
  return tasks::generate(o);
}

/// Every scheduled token started no earlier than each of its learned predecessors ended.
void expectNoTokenStartsBeforeItsPredecessorsEnded(const exec::Dispatch& d,
                                                   const std::vector<exec::ScheduledToken>& schedule) {
  const auto find = [&](TokenRef t) {
    for (const auto& s : schedule)
      if (s.token == t) return s;
    ADD_FAILURE() << "token not scheduled";
    return exec::ScheduledToken{};
  };
  for (const auto& s : schedule)
    for (const TokenRef& p : d.learnedPredecessors(s.token)) EXPECT_LE(find(p).end_s, s.start_s);
  EXPECT_EQ(d.violations(), 0);
}

}  // namespace

TEST(Dispatch, AsyncStartsATokenWhenItsOwnPredecessorsAreDone) {
  const task::TaskDir dir = task4(1);
  const task::TaskSpec& spec = dir.spec;
  graph::Dependencies deps;
  deps.learned = true;  // the entities only
  exec::Dispatch d(spec, DispatchMode::Async, deps);
  d.addStep(tokens(spec, {"R1:move:R3", "R2:move:R4"}), 0);
  d.addStep(tokens(spec, {"R3:move:G1", "R4:move:G1"}), 0);
  ASSERT_EQ(d.readyTokens().size(), 2u);
  d.start({0, 0}, 0);
  d.start({0, 1}, 0);
  EXPECT_FALSE(d.ready({1, 0}));
  EXPECT_THROW(d.start({1, 0}, 1), Error);  // R1 has not reached R3
  d.end({0, 0}, 2);                         // R1 at R3: R3 goes, R4 still waits for R2
  EXPECT_TRUE(d.ready({1, 0}));
  EXPECT_FALSE(d.ready({1, 1}));
  d.start({1, 0}, 2);
  d.end({0, 1}, 3);
  d.start({1, 1}, 3);
  d.end({1, 0}, 5);
  d.end({1, 1}, 5);
  EXPECT_EQ(d.violations(), 0);
  EXPECT_DOUBLE_EQ(d.makespan(), 5);
  const auto waits = d.waits();
  ASSERT_EQ(waits.size(), 2u);
  EXPECT_TRUE(waits[0].released_by == (TokenRef{0, 0}));  // R3 waited for R1
  EXPECT_TRUE(waits[1].released_by == (TokenRef{0, 1}));  // R4 for R2
  EXPECT_DOUBLE_EQ(waits[0].ready_s, 2);
  EXPECT_DOUBLE_EQ(waits[1].start_s, 3);
}

// The record names who held a token past its release: Task 4's R4, released when R2 met it,
// starts only once R3 (ending nearer G1) started: places at one target from the inside out.
TEST(Dispatch, TheRecordNamesTheTokenOfItsStepAReleasedTokenWasHeldFor) {
  const task::TaskDir dir = task4(1);
  const task::TaskSpec& spec = dir.spec;
  graph::Dependencies deps;
  deps.learned = true;
  exec::Dispatch d(spec, DispatchMode::Async, deps);
  d.addStep(tokens(spec, {"R1:move:R3", "R2:move:R4"}), 0);
  d.addStep(tokens(spec, {"R3:move:G1", "R4:move:G1"}), 0, {{}, {0}});
  d.start({0, 0}, 0);
  d.start({0, 1}, 0);
  d.end({0, 1}, 2);  // R2 at R4: R4 released, held for R3
  EXPECT_FALSE(d.ready({1, 1}));
  d.end({0, 0}, 3);  // R1 at R3: R3 goes, then R4
  d.start({1, 0}, 3);
  d.start({1, 1}, 3);
  const auto waits = d.waits();
  ASSERT_EQ(waits.size(), 2u);
  EXPECT_FALSE(waits[0].held) << "R3 started as it was released";
  EXPECT_TRUE(waits[1].released_by == (TokenRef{0, 1}));
  EXPECT_DOUBLE_EQ(waits[1].ready_s, 2);
  EXPECT_TRUE(waits[1].held);
  EXPECT_TRUE(waits[1].held_by == (TokenRef{1, 0})) << "held for R3:move:G1";
  EXPECT_DOUBLE_EQ(waits[1].start_s, 3);
}

TEST(Dispatch, StepsWaitForEveryEarlierTokenAndAStepsRecordCanBeChecked) {
  const task::TaskDir dir = task4(1);
  graph::Dependencies deps;
  deps.learned = true;
  exec::Dispatch d(dir.spec, DispatchMode::Steps, deps);
  d.addStep(tokens(dir.spec, {"R1:move:R3", "R2:move:R4"}), 0);
  EXPECT_FALSE(d.mayDecide(false));  // steps: the next decision after every token ended
  d.addStep(tokens(dir.spec, {"R3:move:G1", "R4:move:G1"}), 0);
  d.start({0, 0}, 0);
  d.start({0, 1}, 0);
  d.end({0, 0}, 2);
  EXPECT_FALSE(d.ready({1, 0}));  // waits for R2 too
  d.end({0, 1}, 3);
  EXPECT_TRUE(d.ready({1, 0}));
  EXPECT_EQ(d.predecessors({1, 0}).size(), 2u);
  EXPECT_EQ(d.learnedPredecessors({1, 0}).size(), 1u);
  EXPECT_EQ(exec::parseDispatchMode("async", "--dispatch"), DispatchMode::Async);
  EXPECT_THROW(exec::parseDispatchMode("eager", "--dispatch"), Error);
}

TEST(Dispatch, AsyncFinishesTask4SoonerThanStepsAndNeverStartsATokenEarly) {
  // Each token takes its demonstrated path's length at the generators' speed: the robots
  // of a step differ in path length, as on a real table.
  const task::TaskDir dir = task4(10);
  const graph::Dependencies deps = graph::learnDependencies(dir.spec, dir.demos);
  double steps_total = 0, async_total = 0;
  for (const task::Demonstration& demo : dir.demos) {
    std::vector<std::vector<task::Token>> steps;
    std::vector<std::vector<double>> durations;
    for (const task::Step& s : demo.steps) {
      steps.push_back(s.tokens);
      durations.emplace_back();
      for (const task::Token& t : s.tokens)
        for (const task::Segment& seg : demo.segments)
          if (seg.token == t && &demo.steps[static_cast<size_t>(seg.step)] == &s) {
            double length = 0;
            const auto path = demo.segmentPath(seg);
            for (size_t i = 1; i < path.size(); ++i) length += (path[i] - path[i - 1]).norm();
            durations.back().push_back(length / tasks::kGeneratorSpeed);
          }
    }
    std::vector<exec::ScheduledToken> async_schedule, steps_schedule;
    const exec::Dispatch a =
        exec::scheduleSteps(dir.spec, deps, DispatchMode::Async, false, steps, durations, &async_schedule);
    const exec::Dispatch s =
        exec::scheduleSteps(dir.spec, deps, DispatchMode::Steps, false, steps, durations, &steps_schedule);
    expectNoTokenStartsBeforeItsPredecessorsEnded(a, async_schedule);
    expectNoTokenStartsBeforeItsPredecessorsEnded(s, steps_schedule);
    EXPECT_LE(a.makespan(), s.makespan() + 1e-9);
    steps_total += s.makespan();
    async_total += a.makespan();
  }
  EXPECT_LT(async_total, steps_total);
}

TEST(Dispatch, APolicyThatReadsTheSceneIsAskedAheadOnceEveryStepBeforeTheLatestEnded) {
  const task::TaskDir dir = task4(1);
  graph::Dependencies deps;
  deps.learned = true;
  const std::vector<std::vector<task::Token>> steps{tokens(dir.spec, {"R1:move:R3", "R2:move:R4"}),
                                                    tokens(dir.spec, {"R3:move:G1", "R4:move:G1"})};
  const std::vector<std::vector<double>> durations{{2, 3}, {3, 2}};
  const auto scene = exec::scheduleSteps(dir.spec, deps, DispatchMode::Async, true, steps, durations, nullptr);
  const auto fixed = exec::scheduleSteps(dir.spec, deps, DispatchMode::Async, false, steps, durations, nullptr);
  const auto stepwise = exec::scheduleSteps(dir.spec, deps, DispatchMode::Steps, false, steps, durations, nullptr);
  EXPECT_DOUBLE_EQ(stepwise.makespan(), 6);
  EXPECT_DOUBLE_EQ(fixed.makespan(), 5);  // R3 left at 2 s, when R1 reached it
  EXPECT_DOUBLE_EQ(scene.makespan(), 5);  // step 2 decided ahead, from where step 1 ends

  // Asked ahead by one step only: step 3 waits until every token of step 1 ended.
  exec::Dispatch d(dir.spec, DispatchMode::Async, deps);
  d.addStep(steps[0], 0);
  EXPECT_TRUE(d.mayDecide(true)) << "step 2, ahead of step 1's ends";
  d.addStep(steps[1], 0);
  EXPECT_TRUE(d.mayDecide(false)) << "a fixed order: always";
  EXPECT_FALSE(d.mayDecide(true)) << "step 3 would read step 1's ends, not yet settled";
  d.start({0, 0}, 0);
  d.start({0, 1}, 0);
  d.end({0, 0}, 2);
  EXPECT_FALSE(d.mayDecide(true));
  EXPECT_FALSE(d.settledBefore(1));
  d.end({0, 1}, 3);
  EXPECT_TRUE(d.settledBefore(1));
  EXPECT_TRUE(d.mayDecide(true));
  exec::Dispatch s(dir.spec, DispatchMode::Steps, deps);
  s.addStep(steps[0], 0);
  EXPECT_FALSE(s.mayDecide(true)) << "steps: once every token ended";
}

TEST(Dispatch, WhatPeopleShowedItWaitingForHoldsItBack) {
  // The same run with dependencies learned from a person who held R3 until R2 had
  // reached R4: R3 waits for R2 as well.
  const task::TaskDir dir = task4(1);
  graph::Dependencies deps;
  deps.learned = true;
  deps.demonstrations = 1;
  deps.evidence.push_back({"R3:move:G1", "R2:move:R4", 1, 0});
  const std::vector<std::vector<task::Token>> steps{tokens(dir.spec, {"R1:move:R3", "R2:move:R4"}),
                                                    tokens(dir.spec, {"R3:move:G1", "R4:move:G1"})};
  std::vector<exec::ScheduledToken> schedule;
  const auto d = exec::scheduleSteps(dir.spec, deps, DispatchMode::Async, false, steps, {{2, 3}, {3, 2}}, &schedule);
  expectNoTokenStartsBeforeItsPredecessorsEnded(d, schedule);
  EXPECT_DOUBLE_EQ(d.makespan(), 6);
}
