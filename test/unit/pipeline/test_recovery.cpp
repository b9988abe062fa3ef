// Recovery from the scene as it is (CoordinatorConfig::max_replans): with a learned scene
// network as the policy, a box moved by hand under a running step makes the coordinator
// re-decide the step from the scene of now, and the network then sends the robot that the
// rule names for the box where it is.
#include <gtest/gtest.h>

#include <filesystem>

#include "ddace/common/error.h"
#include "ddace/exec/coordinator.h"
#include "ddace/pipeline/decisions_without.h"
#include "ddace/pipeline/evaluation.h"
#include "ddace/pipeline/perturbation.h"
#include "ddace/tasks/rule_zoo.h"

#include "../common/generated_task.h"
#include "shared_model.h"

using namespace ddace;
using ddace::test::generated;
using Eigen::Vector2d;
namespace fs = std::filesystem;

namespace {

exec::EntityObservation observe(const std::vector<Vector2d>& positions) {
  return {positions, std::vector<bool>(positions.size(), true)};
}

/// The coordinator driven by the model, on points that move instantly where they are sent.
struct ModelRun {
  const pipeline::Model& model;
  exec::Coordinator c;
  std::vector<Vector2d> at;
  std::vector<exec::SegmentCommand> running;
  std::vector<std::vector<task::Token>> decided;  ///< every decision's tokens, in order
  double now = 0;

  ModelRun(const pipeline::Model& m, const task::TaskSpec& spec, std::vector<Vector2d> start, int max_replans)
      : model(m),
        c(spec, config(max_replans), m.primitives->endPoints(), 1, {}, pipeline::policyReadsScene(m)),
        at(std::move(start)) {}
  static exec::CoordinatorConfig config(int max_replans) {
    exec::CoordinatorConfig cfg;
    cfg.max_replans = max_replans;
    return cfg;
  }
  /// Answers what the coordinator asked for: decisions from the model, straight paths.
  void handle(const exec::CoordinatorOutput& first) {
    std::vector<exec::CoordinatorOutput> pending{first};
    while (!pending.empty()) {
      const exec::CoordinatorOutput out = pending.back();
      pending.pop_back();
      for (int e : out.stop)
        running.erase(std::remove_if(running.begin(), running.end(), [&](const auto& s) { return s.entity == e; }),
                      running.end());
      running.insert(running.end(), out.segments.begin(), out.segments.end());
      for (const auto& p : out.paths) pending.push_back(c.onPath(p.id, {{p.start, p.goal}, {0, 0}}, "", now += 0.1));
      if (out.decision) {
        const tgn::Prediction p = model.sequence.predictNext(out.decision->history);
        decided.push_back(p.tokens);
        pending.push_back(c.onDecision(out.decision->id, exec::Decision{p.end, p.tokens}, now += 0.1));
      }
    }
  }
  /// Every running segment arrives at its end.
  void arriveAll() {
    const auto segs = running;
    running.clear();
    for (const auto& s : segs) at[static_cast<size_t>(s.entity)] = s.goal;
    handle(c.onEntities(observe(at), now += 0.1));
    for (const auto& s : segs)
      handle(c.onSegmentStatus(s.entity, s.segment_id, exec::SegmentState::Done, 1.0, "", now += 0.1));
  }
};

int nearest(const std::vector<Vector2d>& at, const std::vector<int>& among, const Vector2d& p) {
  int best = among.front();
  for (int e : among)
    if ((at[static_cast<size_t>(e)] - p).norm() < (at[static_cast<size_t>(best)] - p).norm()) best = e;
  return best;
}

/// One scene network trained on 20 deliver demonstrations for every test here (5 s).
struct DeliverModel {
  static constexpr const char* kDir = "ddace_recovery_deliver";
  static pipeline::Model train(const std::string& dir) {
    return pipeline::trainModel(generated("deliver", 20, 1), tgn::TrainOptions{}, dir, nullptr);
  }
};
using Recovery = ddace::test::SharedModel<DeliverModel>;

}  // namespace

// deliver: the robot nearest B1 fetches it and carries it to the goal nearest it. B1 is
// moved by hand next to the other robot while the first one drives to it: the step is
// re-decided from the scene of now and the other robot fetches it, then carries it to the
// goal nearest where it is now, and the run finishes.
TEST_F(Recovery, ABoxMovedByHandIsFetchedByTheRobotTheRuleNamesWhereItIsNow) {
  const pipeline::Model& model = *model_;
  ASSERT_TRUE(pipeline::policyReadsScene(model));
  const task::TaskDir test = generated("deliver", 10, 77);
  const task::TaskSpec& spec = test.spec;
  const int r1 = spec.entityIndex("R1"), r2 = spec.entityIndex("R2"), b1 = spec.entityIndex("B1");
  const int g1 = spec.entityIndex("G1"), g2 = spec.entityIndex("G2");
  int tried = 0;
  for (const task::Demonstration& demo : test.demos) {
    ModelRun run(model, spec, demo.positions.front(), 1);
    run.handle(run.c.onEntities(observe(run.at), 0.0));
    run.handle(run.c.start(0.0));
    ASSERT_EQ(run.decided.size(), 1u);
    ASSERT_EQ(run.decided[0].size(), 1u);
    const int fetcher = run.decided[0][0].entity, other = fetcher == r1 ? r2 : r1;
    ASSERT_EQ(fetcher, nearest(run.at, {r1, r2}, run.at[static_cast<size_t>(b1)])) << "step 1 as the rule says";
    // Halfway there, B1 is put down 8 cm from the other robot, toward the table's middle.
    ASSERT_EQ(run.running.size(), 1u);
    auto& f = run.at[static_cast<size_t>(fetcher)];
    f = (f + run.running[0].goal) / 2;
    const Vector2d o = run.at[static_cast<size_t>(other)];
    const Vector2d moved = o + 0.08 * (Vector2d(0.3, 0.25) - o).normalized();
    // Only scenes where the other robot is now clearly the nearest (the rule's margin).
    if ((f - moved).norm() < 2 * (o - moved).norm()) continue;
    ++tried;
    run.at[static_cast<size_t>(b1)] = moved;
    const exec::CoordinatorOutput out = run.c.onEntities(observe(run.at), run.now += 0.1);
    EXPECT_NE(std::find(out.stop.begin(), out.stop.end(), fetcher), out.stop.end()) << "the fetcher stops";
    ASSERT_TRUE(out.decision) << "the step is asked for again";
    EXPECT_EQ(out.decision->history.size(), 1u) << "in place of the snapshot it was decided from";
    EXPECT_TRUE(out.decision->history.back().positions[static_cast<size_t>(b1)].isApprox(moved));
    run.handle(out);
    ASSERT_EQ(run.decided.size(), 2u);
    ASSERT_EQ(run.decided[1].size(), 1u);
    EXPECT_EQ(run.decided[1][0].entity, other) << "re-decided: the robot now nearest B1 fetches it";
    EXPECT_EQ(run.decided[1][0].target, b1);
    EXPECT_EQ(run.c.redecisions(), 1);
    for (int i = 0; i < 4 && run.c.running(); ++i) run.arriveAll();
    EXPECT_EQ(run.c.state(), exec::RunState::Finished) << run.c.reason();
    ASSERT_EQ(run.decided.size(), 4u) << "fetch, carry, END";
    const int goal =
        nearest(std::vector<Vector2d>(demo.positions.front().begin(), demo.positions.front().end()), {g1, g2}, moved);
    for (const task::Token& t : run.decided[2]) EXPECT_EQ(t.target, goal) << "carried to the goal nearest it now";
    EXPECT_LT((run.at[static_cast<size_t>(b1)] - run.at[static_cast<size_t>(goal)]).norm(), 0.05) << "B1 is on it";
    if (tried == 2) break;
  }
  EXPECT_EQ(tried, 2) << "no test scene leaves the other robot clearly nearest";
}

namespace {

/// A robot lost for good: without recovery the run does not finish; with it the run goes
/// on without that robot (deliver's rule is stated by the scene: the other robot fetches
/// and carries the box), which gets no token once lost.
void expectWentOnWithout(const task::TaskSpec& spec, const pipeline::CoordinatedRun& without,
                         const pipeline::CoordinatedRun& with) {
  EXPECT_FALSE(without.success);
  ASSERT_TRUE(with.perturbed);
  EXPECT_TRUE(with.success) << with.what << ": " << with.reason << " " << with.failure;
  ASSERT_EQ(with.lost.size(), 1u) << with.reason;
  const std::string name = with.lost[0].substr(0, with.lost[0].find(':'));
  const int robot = spec.entityIndex(name);
  ASSERT_GE(robot, 0) << with.lost[0];
  ASSERT_FALSE(with.trial.predicted.empty());
  for (const task::Token& t : with.trial.predicted.back().tokens)
    EXPECT_NE(t.entity, robot) << "the last step decided gives the lost robot no token";
}

}  // namespace

// `ddace eval --perturb`: each kind changes the table once mid-motion in every trial; with
// recovery the runs finish as the rule says, without they do not (a box moved: the robot
// went on to where it was; pushed: the failed segment aborts), and a robot lost for good is
// left out of the decisions after it.
TEST_F(Recovery, EachPerturbationIsRecoveredFromOrAbortsNamingWhy) {
  const task::TaskDir test = generated("deliver", 4, 77);
  const task::TaskSpec& spec = test.spec;
  const auto run = [&](const std::string& kind) {
    return pipeline::evaluatePerturbed(*model_, test, pipeline::parsePerturbation(kind, "--perturb"),
                                       exec::DispatchMode::Steps, 5);
  };
  for (const char* kind : {"box_moved:6", "robot_pushed:5"}) {
    const pipeline::PerturbationReport r = run(kind);
    for (size_t i = 0; i < r.demos.size(); ++i) {
      ASSERT_TRUE(r.with[i].perturbed) << kind << " " << r.demos[i];
      EXPECT_TRUE(r.unperturbed[i].success) << kind << " " << r.demos[i] << " " << r.unperturbed[i].failure;
      EXPECT_TRUE(r.with[i].success) << kind << " " << r.demos[i] << ": " << r.with[i].what << "; " << r.with[i].reason
                                     << " " << r.with[i].failure;
      EXPECT_FALSE(r.without[i].success) << kind << " " << r.demos[i];
      EXPECT_EQ(r.with[i].precedence_violations, 0);
    }
  }
  const pipeline::PerturbationReport moved = run("box_moved");
  for (size_t i = 0; i < moved.demos.size(); ++i) {
    EXPECT_EQ(moved.with[i].redecisions, 1) << moved.demos[i] << ": the box moved: the step is decided again";
    EXPECT_EQ(moved.without[i].stale_ends, 1) << moved.demos[i] << ": the robot went on to where the box was";
  }
  const pipeline::PerturbationReport lost = run("robot_lost");
  for (size_t i = 0; i < lost.demos.size(); ++i) expectWentOnWithout(spec, lost.without[i], lost.with[i]);
  const pipeline::PerturbationReport stalled = run("robot_stalled:5");
  for (size_t i = 0; i < stalled.demos.size(); ++i) {
    EXPECT_TRUE(stalled.with[i].success) << stalled.with[i].reason;
    EXPECT_NEAR(stalled.with[i].makespan_s - stalled.unperturbed[i].makespan_s, 5.0, 0.1) << "stands 5 s";
  }
  EXPECT_THROW(pipeline::parsePerturbation("box_nudged", "--perturb"), Error);
  EXPECT_THROW(pipeline::parsePerturbation("robot_stalled:-1", "--perturb"), Error);
}

// The same on the table with bodies (`--execution diffdrive`): each robot's own control
// cycle; a box put down elsewhere is fetched where it is, a robot whose battery died is left
// standing where it died and the run goes on without it, without a collision.
TEST_F(Recovery, WithBodiesAMovedBoxAndALostRobotAreRecoveredFrom) {
  const task::TaskDir test = generated("deliver", 3, 77);
  pipeline::EvalOptions o;
  o.execution = "diffdrive";
  const exec::BodiesExecutionParams table = pipeline::bodiesParams(o, test.spec);
  const auto run = [&](const std::string& kind) {
    return pipeline::evaluatePerturbed(*model_, test, pipeline::parsePerturbation(kind, "--perturb"),
                                       exec::DispatchMode::Steps, 5, &table);
  };
  const pipeline::PerturbationReport moved = run("box_moved");
  const pipeline::PerturbationReport lost = run("robot_lost");
  for (size_t i = 0; i < moved.demos.size(); ++i) {
    ASSERT_TRUE(moved.with[i].trial.bodies);
    EXPECT_TRUE(moved.unperturbed[i].success) << moved.unperturbed[i].reason << " " << moved.unperturbed[i].failure;
    ASSERT_TRUE(moved.with[i].perturbed);
    EXPECT_TRUE(moved.with[i].success) << moved.with[i].what << ": " << moved.with[i].reason << " "
                                       << moved.with[i].failure;
    EXPECT_FALSE(moved.without[i].success);
    EXPECT_EQ(moved.with[i].redecisions, 1);
    EXPECT_EQ(moved.with[i].collisions + lost.with[i].collisions, 0);
    // A carrier lost mid-carry: the task is begun again from the scene as it is, so the
    // other robot fetches the box where it was left and carries it on (the run is judged by
    // where the demonstration left the box: the task states no goal condition).
    const pipeline::CoordinatedRun& with = lost.with[i];
    EXPECT_FALSE(lost.without[i].success);
    ASSERT_EQ(with.lost.size(), 1u) << with.reason;
    EXPECT_TRUE(with.success) << with.what << ": " << with.reason << " " << with.failure;
  }
  // Some trial loses its carrier mid-carry (in step 2, the carry).
  int mid_carry = 0;
  for (size_t i = 0; i < lost.demos.size(); ++i) mid_carry += lost.with[i].what.rfind("step 2", 0) == 0;
  EXPECT_GE(mid_carry, 1) << "a carrier is lost mid-carry in some trial";
}

// The decisions for the team without a lost robot (the sequence node's and `ddace eval`'s):
// deliver's rule sends the robot nearest the box; with that robot lost the other goes, and
// its tokens name the task's entities.
TEST_F(Recovery, WithoutALostRobotTheOtherIsSentAndTokensNameTheTasksEntities) {
  const task::TaskDir test = generated("deliver", 4, 77);
  const task::TaskSpec& spec = test.spec;
  const int r1 = spec.entityIndex("R1"), r2 = spec.entityIndex("R2"), b1 = spec.entityIndex("B1");
  pipeline::DecisionsWithout decisions(model_->sequence);
  for (const task::Demonstration& demo : test.demos) {
    const std::vector<task::Snapshot> history{{0, false, demo.positions.front()}};
    const tgn::Prediction all = decisions.predict(history, {});
    ASSERT_EQ(all.tokens.size(), 1u);
    const int nearest = all.tokens[0].entity, other = nearest == r1 ? r2 : r1;
    const tgn::Prediction without = decisions.predict(history, {nearest});
    ASSERT_EQ(without.tokens.size(), 1u);
    EXPECT_EQ(without.tokens[0].entity, other);
    EXPECT_EQ(without.tokens[0].target, b1);
  }
  EXPECT_THROW(decisions.predict({{0, false, test.demos[0].positions.front()}}, {42}), Error);
}

// A run that lost a robot is judged by the task's own ends; deliver states no goal
// condition, so by the demonstration's: a box left mid-table is named, not counted as done.
TEST(RobotLostJudgement, ABoxNotWhereTheDemonstrationLeftItIsNamed) {
  const task::TaskDir dir = generated("deliver", 1, 77);
  const task::TaskSpec& spec = dir.spec;
  ASSERT_TRUE(spec.goal_conditions.empty());
  const task::Demonstration& demo = dir.demos.front();
  const int b1 = spec.entityIndex("B1");
  int goal = -1;
  for (const task::Step& s : demo.steps)
    for (const task::Token& t : s.tokens)
      if (t.entity == b1 && t.isMotion()) goal = t.target;
  ASSERT_GE(goal, 0) << "the demonstration carries B1 somewhere";
  std::vector<Vector2d> end = demo.positions.back();
  EXPECT_EQ(pipeline::objectNotWhereDemonstrated(spec, demo, end, {}), "") << "B1 where the demonstration left it";
  end[static_cast<size_t>(b1)] = demo.positions.front()[static_cast<size_t>(b1)];  // never carried
  EXPECT_EQ(pipeline::objectNotWhereDemonstrated(spec, demo, end, {}),
            "B1 did not end at " + spec.entities[static_cast<size_t>(goal)].name + ", where the demonstration left it");
  EXPECT_EQ(pipeline::objectNotWhereDemonstrated(spec, demo, end, {goal}), "")
      << "an object the demonstration left at an entity that is lost is not asked for";
}

// Pushed loads (mock_robots/loads_ride false: the real table's way) through the
// coordinator's steps dispatch run as the simulator runs them: with the same noise, every
// trial the simulator counts a success succeeds through the coordinator, and no
// coordinated trial has a collision. A box its carrier left short of its end fails the
// trial in both (the relay states no goal condition); the coordinator does not send the box
// on alone, which the table did by hand, into the robots standing at the goal.
TEST(PushedLoads, ARelayThroughTheCoordinatorRunsAsInTheSimulator) {
  const std::string dir = ::testing::TempDir() + "/ddace_pushed_relay";
  fs::remove_all(dir);
  const pipeline::Model model = pipeline::trainModel(tasks::generateZoo(87, 20, 1), tgn::TrainOptions{}, dir, nullptr);
  const task::TaskDir test = tasks::generateZoo(87, 8, 2);
  pipeline::EvalOptions o;
  o.execution = "diffdrive";
  o.noise_m = 0.002;
  o.config.table.loads_ride = false;
  const pipeline::Evaluation sim = pipeline::evaluate(model, test, o);
  o.coordinated = true;
  o.dispatch = exec::DispatchMode::Steps;
  const pipeline::Evaluation coordinated = pipeline::evaluate(model, test, o);
  fs::remove_all(dir);
  ASSERT_EQ(sim.scores.size(), coordinated.scores.size());
  for (size_t i = 0; i < sim.scores.size(); ++i) {
    SCOPED_TRACE(sim.scores[i].demo);
    EXPECT_TRUE(!sim.scores[i].success || coordinated.scores[i].success) << coordinated.first_difference[i];
    EXPECT_EQ(coordinated.scores[i].collisions, 0);
    EXPECT_TRUE(sim.scores[i].objectsArrived() || !sim.scores[i].success);
  }
}

// Riding loads (the eval default, mock robots) through the coordinator: a carrier drives
// the path it was shown where that passes the bodies standing, as the simulator decides it
// (exec::drivesShownPath), not a loop round its box to push it; every trial's paths and
// outcome agree with the simulator's.
TEST(RidingLoads, ACarryThroughTheCoordinatorDrivesThePathTheSimulatorDrives) {
  const std::string dir = ::testing::TempDir() + "/ddace_riding_fetch";
  fs::remove_all(dir);
  const pipeline::Model model = pipeline::trainModel(generated("fetch", 10, 1), tgn::TrainOptions{}, dir, nullptr);
  const task::TaskDir test = generated("fetch", 6, 2);
  pipeline::EvalOptions o;
  o.execution = "diffdrive";
  o.noise_m = 0.002;
  o.config.table.loads_ride = true;
  const pipeline::Evaluation sim = pipeline::evaluate(model, test, o);
  o.coordinated = true;
  o.dispatch = exec::DispatchMode::Steps;
  const pipeline::Evaluation coordinated = pipeline::evaluate(model, test, o);
  fs::remove_all(dir);
  ASSERT_EQ(sim.scores.size(), coordinated.scores.size());
  const auto mean = [](const std::vector<double>& v) {
    double sum = 0;
    for (double x : v) sum += x;
    return v.empty() ? 0.0 : sum / static_cast<double>(v.size());
  };
  for (size_t i = 0; i < sim.scores.size(); ++i) {
    SCOPED_TRACE(sim.scores[i].demo);
    EXPECT_EQ(sim.scores[i].success, coordinated.scores[i].success) << coordinated.first_difference[i];
    EXPECT_NEAR(mean(coordinated.scores[i].fd), mean(sim.scores[i].fd), 0.01);
    EXPECT_LT(mean(coordinated.scores[i].fd), 0.1);
  }
}

namespace {

/// zoo:two-pairs, as `ddace generate zoo:two-pairs --train 10 --seed 1`: two carrier-load
/// pairs, trained on teams of two robots only.
struct TwoPairsModel {
  static constexpr const char* kDir = "ddace_recovery_two_pairs";
  static task::TaskDir demos(int n, uint64_t seed) {
    uint64_t rule = 0;
    tasks::ZooMotion motion;
    if (!tasks::parseZooFamily("zoo:two-pairs", rule, &motion)) throw Error("zoo:two-pairs is not a zoo family");
    return tasks::generateZoo(rule, n, seed, motion);
  }
  static pipeline::Model train(const std::string& dir) {
    return pipeline::trainModel(demos(10, 1), tgn::TrainOptions{}, dir, nullptr);
  }
};
using TwoPairsLost = ddace::test::SharedModel<TwoPairsModel>;

}  // namespace

// A robot lost for good where the model, trained on teams of two, cannot go on for the one
// left: it decides a motion no demonstration has (carrying one box onto the other), or END
// with a box left where every demonstration ended with both boxes at goals. The run aborts
// naming the lost robot and why; it never finishes with a box left where the task does not end.
TEST_F(TwoPairsLost, ARobotLostWhereTheModelCannotGoOnAbortsNamingIt) {
  const task::TaskDir test = TwoPairsModel::demos(3, 2654435761ULL + 0x7e57);
  const pipeline::PerturbationReport lost = pipeline::evaluatePerturbed(
      *model_, test, pipeline::parsePerturbation("robot_lost", "--perturb"), exec::DispatchMode::Steps, 5);
  for (size_t i = 0; i < lost.demos.size(); ++i) {
    const pipeline::CoordinatedRun& with = lost.with[i];
    EXPECT_TRUE(lost.unperturbed[i].success) << lost.demos[i] << " " << lost.unperturbed[i].failure;
    ASSERT_TRUE(with.perturbed) << lost.demos[i];
    ASSERT_EQ(with.lost.size(), 1u) << with.reason;
    if (with.success) continue;  // went on without it and did the task
    EXPECT_FALSE(with.finished) << lost.demos[i] << ": finished with the task undone: " << with.failure;
    const std::string name = with.lost[0].substr(0, with.lost[0].find(':'));
    EXPECT_NE(with.reason.find(name + " is lost"), std::string::npos) << with.reason;
    EXPECT_TRUE(
        with.reason.find("no demonstration has such a motion") != std::string::npos ||
        (with.reason.find("would leave the task undone: every demonstration ended with ") != std::string::npos &&
         with.reason.find("2 object:box with goal (1 here)") != std::string::npos))
        << with.reason;
    EXPECT_EQ(with.by_rule, 1) << "the rule needs both robots: aborting naming the lost one is what it says";
  }
}

namespace {

/// zoo:two-boxes as `ddace generate zoo:two-boxes --train 10 --test 10 --seed 1` makes it.
struct TwoBoxesModel {
  static constexpr const char* kDir = "ddace_recovery_two_boxes";
  static uint64_t rule() {
    uint64_t id = 0;
    if (!tasks::parseZooFamily("zoo:two-boxes", id)) throw Error("no zoo rule two-boxes");
    return id;
  }
  static pipeline::Model train(const std::string& dir) {
    return pipeline::trainModel(tasks::generateZoo(rule(), 10, 1), tgn::TrainOptions{}, dir, nullptr);
  }
};
using RecoveryTwoBoxes = ddace::test::SharedModel<TwoBoxesModel>;

/// Ten fresh zoo:two-boxes scenes with bodies (2 mm tracking noise), each perturbed by `kind`;
/// loads pushed (the default) or riding.
pipeline::PerturbationReport perturbedWithBodies(const pipeline::Model& model, const char* kind,
                                                 bool loads_ride = false) {
  const task::TaskDir test = tasks::generateZoo(TwoBoxesModel::rule(), 10, 1 * 2654435761ULL + 0x7e57);
  pipeline::EvalOptions o;
  o.execution = "diffdrive";
  o.noise_m = 0.002;
  o.config.table.loads_ride = loads_ride;
  const exec::BodiesExecutionParams table = pipeline::bodiesParams(o, test.spec);
  return pipeline::evaluatePerturbed(model, test, pipeline::parsePerturbation(kind, "--perturb"),
                                     exec::DispatchMode::Steps, 1, &table);
}

}  // namespace

// zoo:two-boxes with bodies, each box moved 10 cm by a hand while a robot drives to it: the
// re-decided step and those after it are the rule's on the scene after the hand. Among these
// ten scenes are a box put down beside the robot driving to it (the step re-decided with
// that robot read where it stood at one place with the box sent the robots to the other
// boxes) and a robot that then barely moved to its box (read as not having fetched it).
TEST_F(RecoveryTwoBoxes, ABoxMovedBesideItsFetcherIsStillFetchedAsTheRuleSays) {
  const pipeline::PerturbationReport r = perturbedWithBodies(*model_, "box_moved:10");
  int judged = 0;
  for (size_t i = 0; i < r.demos.size(); ++i) {
    if (!r.unperturbed[i].success || r.with[i].by_rule < 0) continue;
    ++judged;
    EXPECT_EQ(r.with[i].by_rule, 1) << "trial " << i << ": " << r.with[i].what << "; " << r.with[i].rule_failure << " ("
                                    << r.with[i].failure << ")";
  }
  EXPECT_GE(judged, 8);
}

// zoo:two-boxes with bodies, a robot lost for good on each of ten scenes: a run that goes on
// is judged by what the rule decides for the two robots left on the scene at the loss (where
// each box ends), not by the demonstration of the team of three; here every one does it with
// the loads riding. Pushed, one of these ten does not (scene 8: the carrier sent on stops
// short beside the lost robot standing behind the box; docs/bodies-log.md).
TEST_F(RecoveryTwoBoxes, ARobotLostForGoodIsJudgedByTheRuleForTheTeamLeft) {
  const pipeline::PerturbationReport r = perturbedWithBodies(*model_, "robot_lost", /*loads_ride=*/true);
  int judged = 0;
  for (size_t i = 0; i < r.demos.size(); ++i) {
    const pipeline::CoordinatedRun& with = r.with[i];
    if (!r.unperturbed[i].success || with.by_rule < 0) continue;
    ++judged;
    ASSERT_EQ(with.lost.size(), 1u) << "trial " << i << ": " << with.reason;
    EXPECT_TRUE(with.finished) << "trial " << i << ": two robots are left for two boxes: " << with.reason;
    EXPECT_EQ(with.by_rule, 1) << "trial " << i << ": " << with.what << "; " << with.rule_failure;
    EXPECT_EQ(with.success, with.by_rule == 1) << "a run that went on succeeds as the rule judges it";
  }
  EXPECT_GE(judged, 8);
}
