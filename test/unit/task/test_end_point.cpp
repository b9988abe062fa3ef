// Where a motion ends (task/end_point.h): learned from where the demonstrations stopped,
// at contact or at centres alike, and the footprints' rule when nothing was demonstrated.
#include <gtest/gtest.h>

#include "ddace/task/end_point.h"

using namespace ddace;
using namespace ddace::task;
using Eigen::Vector2d;

namespace {

TaskSpec scene() {
  return parseTaskYaml(
      "format: ddace-task/1\nentities:\n  - {name: R1, kind: robot, type: hamster}\n"
      "  - {name: R2, kind: robot, type: hamster}\n  - {name: B1, kind: object}\n  - {name: G1, kind: goal}\n",
      "task.yaml");
}

/// One demonstration: R1 drives straight from `from` toward R2 (resting at `r2`) and stops
/// `stop` metres short of R2's centre (0: on it), then R2 drives onto G1.
Demonstration demo(const TaskSpec& spec, const Vector2d& from, const Vector2d& r2, double stop) {
  Demonstration d;
  d.has_label_columns = {true, true, false, false};
  const Vector2d b1(0.9, 0.9), g1(0.1, 0.9);
  const Vector2d end = r2 - stop * (r2 - from).normalized();
  auto row = [&](const Vector2d& p1, const Vector2d& p2, int a1, int a2) {
    d.t.push_back(0.05 * static_cast<double>(d.t.size()));
    d.positions.push_back({p1, p2, b1, g1});
    std::vector<Label> l(4);
    if (a1 >= 0) l[0] = {"move", a1};
    if (a2 >= 0) l[1] = {"move", a2};
    d.labels.push_back(l);
  };
  row(from, r2, -1, -1);
  for (int i = 0; i <= 20; ++i) row(from + (end - from) * (i / 20.0), r2, spec.entityIndex("R2"), -1);
  row(end, r2, -1, -1);
  for (int i = 0; i <= 20; ++i) row(end, r2 + (g1 - r2) * (i / 20.0), -1, spec.entityIndex("G1"));
  row(end, g1, -1, -1);
  d.analyze();
  return d;
}

std::vector<Demonstration> demos(const TaskSpec& spec, double stop) {
  std::vector<Demonstration> out;
  for (int k = 0; k < 5; ++k)
    out.push_back(demo(spec, Vector2d(0.1 + 0.05 * k, 0.1), Vector2d(0.5, 0.3 + 0.04 * k), stop));
  return out;
}

}  // namespace

TEST(EndPoint, LearnedFromDemonstrationsThatStopAtContact) {
  const TaskSpec spec = scene();
  const double contact = spec.contactDistance(0, 1);
  const EndPointModel m = learnEndPoints(spec, demos(spec, contact));
  ASSERT_TRUE(m.by_class.count("robot->robot"));
  EXPECT_NEAR(m.by_class.at("robot->robot").offset.x(), -contact, 1e-9);
  EXPECT_NEAR(m.by_class.at("robot->robot").offset.y(), 0.0, 1e-9);
  EXPECT_EQ(m.by_key.at("R1:move:R2").segments, 5);
  EXPECT_NEAR(m.by_class.at("robot->goal").offset.norm(), 0.0, 1e-9);
  // A new scene: R1 stops at contact with R2, on the side it comes from.
  const std::vector<Token> step = {{0, "move", 1}};
  const std::vector<Vector2d> at = {{0.2, 0.7}, {0.6, 0.4}, {0.9, 0.9}, {0.1, 0.9}};
  const Vector2d end = endPoint(spec, m, step, 0, at);
  EXPECT_NEAR((end - at[1]).norm(), contact, 1e-9);
  EXPECT_LT((end - at[0]).norm(), (at[1] - at[0]).norm());
}

TEST(EndPoint, DemonstrationsThatEndAtCentresAreReadTheSameWay) {
  // The same rule on recordings whose motions end at the target's centre (the generators
  // before bodies, or points without bodies) teaches centres.
  const TaskSpec spec = scene();
  const EndPointModel m = learnEndPoints(spec, demos(spec, 0.0));
  EXPECT_NEAR(m.by_class.at("robot->robot").offset.norm(), 0.0, 1e-9);
  const std::vector<Vector2d> at = {{0.2, 0.7}, {0.6, 0.4}, {0.9, 0.9}, {0.1, 0.9}};
  EXPECT_NEAR((endPoint(spec, m, {{0, "move", 1}}, 0, at) - at[1]).norm(), 0.0, 1e-9);
}

TEST(EndPoint, AKeyWithEnoughSegmentsUsesItsOwnOffsetRobustToASlip) {
  const TaskSpec spec = scene();
  std::vector<Demonstration> ds = demos(spec, 0.03);
  // Two demonstrations stopped far short (a slip, a hesitation): the median ignores them.
  ds.push_back(demo(spec, Vector2d(0.1, 0.5), Vector2d(0.5, 0.5), 0.10));
  ds.push_back(demo(spec, Vector2d(0.1, 0.5), Vector2d(0.5, 0.5), 0.25));
  const EndPointModel m = learnEndPoints(spec, ds);
  EXPECT_EQ(m.by_key.at("R1:move:R2").segments, 7);
  EXPECT_NEAR(m.by_key.at("R1:move:R2").offset.x(), -0.03, 1e-9);  // the median, not the mean
  const std::vector<Vector2d> at = {{0.2, 0.7}, {0.6, 0.4}, {0.9, 0.9}, {0.1, 0.9}};
  EXPECT_NEAR((endPoint(spec, m, {{0, "move", 1}}, 0, at) - at[1]).norm(), 0.03, 1e-9);
}

TEST(EndPoint, WithoutDemonstrationsTheFootprintsDecide) {
  const TaskSpec spec = scene();
  const EndPointModel none;
  const int r1 = 0, r2 = 1, b1 = 2, g1 = 3;
  // Toward a robot: contact; onto a goal: its centre.
  EXPECT_NEAR(endOffset(spec, none, {{r1, "move", r2}}, 0).x(), -spec.contactDistance(r1, r2), 1e-12);
  EXPECT_NEAR(endOffset(spec, none, {{r1, "move", g1}}, 0).norm(), 0.0, 1e-12);
  // A carrier and its load toward a goal: the load on it, the carrier behind the load.
  const std::vector<Token> carry = {{r1, "carry", g1}, {b1, "carry", g1}};
  EXPECT_EQ(carriedLoad(spec, carry, 0), 1);
  EXPECT_EQ(carriedLoad(spec, carry, 1), -1);
  EXPECT_EQ(motionClass(spec, carry, 0), "robot+load->goal");
  EXPECT_EQ(motionClass(spec, carry, 1), "object->goal");
  EXPECT_NEAR(endOffset(spec, none, carry, 1).norm(), 0.0, 1e-12);
  EXPECT_NEAR(endOffset(spec, none, carry, 0).x(), -spec.contactDistance(r1, b1), 1e-12);
  // Toward a robot with a load: the load at contact with it, the carrier behind the load.
  const std::vector<Token> hand_over = {{r1, "carry", r2}, {b1, "carry", r2}};
  EXPECT_NEAR(endOffset(spec, none, hand_over, 0).x(), -(spec.contactDistance(b1, r2) + spec.contactDistance(r1, b1)),
              1e-12);
  // A model of the old format: every motion ends at its target's centre.
  EndPointModel centres;
  centres.centres = true;
  EXPECT_NEAR(endOffset(spec, centres, {{r1, "move", r2}}, 0).norm(), 0.0, 1e-12);
  // In place, or already at the target: where it is.
  const std::vector<Vector2d> at = {{0.5, 0.5}, {0.5, 0.5 + 1e-3}, {0.9, 0.9}, {0.1, 0.9}};
  EXPECT_EQ(endPoint(spec, none, {{r1, "stop", -1}}, 0, at), at[0]);
  EXPECT_EQ(endPoint(spec, none, {{r1, "move", r2}}, 0, at), at[0]);
  EXPECT_THROW(endPoint(spec, none, {{7, "move", r2}}, 0, at), Error);
}

TEST(BodyGeometry, ArrivedWithinTheRadiusAndFollowersStopInsideIt) {
  EXPECT_TRUE(arrived({0.03, 0}, {0, 0}, 0.03));
  EXPECT_FALSE(arrived({0.0301, 0}, {0, 0}, 0.03));
  // Inside the radius by the tracking noise, so a noisy stopped robot still counts.
  EXPECT_DOUBLE_EQ(stopRadius(0.03), 0.03 - kArrivalToleranceM);
  EXPECT_DOUBLE_EQ(stopRadius(0.03, 0.01), 0.02);
  EXPECT_DOUBLE_EQ(stopTolerance(0.001), kArrivalToleranceM);
  EXPECT_DOUBLE_EQ(stopTolerance(0.002), 0.006) << "three sigma";
  // A radius within the noise itself: half of it, never zero or below.
  EXPECT_DOUBLE_EQ(stopRadius(0.004), 0.002);
}

// Against a body a robot stops within the tracking noise of its end point, where the
// demonstrations stopped against it (touching, 4 mm, 1 cm), not anywhere within the stop
// radius (2.4 cm at 2 mm noise) short of it.
TEST(BodyGeometry, ARobotWhoseEndIsSetAgainstABodyStopsWithinTheToleranceOfIt) {
  const double tol = stopTolerance(0.002), stop = stopRadius(kDefaultArrivalRadius, tol);
  EXPECT_DOUBLE_EQ(stopRadiusAgainstBody(stop, tol), tol);
  EXPECT_LT(stopRadiusAgainstBody(stop, tol), stop);
  EXPECT_DOUBLE_EQ(stopRadiusAgainstBody(0.002, tol), 0.002) << "never above the stop radius";
}

// Goal conditions are judged within what bodies allow: a robot at a goal another robot
// stands on meets "at G1" touching that robot; one far short does not; with the goal free,
// the plain distance decides.
TEST(BodyGeometry, AGoalConditionOnAGoalAnotherBodyTakesIsJudgedFromWhereABodyCanStand) {
  task::TaskSpec spec;
  spec.entities = {{"R1", task::EntityKind::Robot, ""},
                   {"R2", task::EntityKind::Robot, ""},
                   {"R3", task::EntityKind::Robot, ""},
                   {"G1", task::EntityKind::Goal, ""}};
  const double contact = spec.contactDistance(0, 1);
  const Vector2d goal(0.5, 0.5), nowhere(0.9, 0.1);
  const GoalCondition r2_at_g1{"R2", "G1", 0.02};
  // R1 on G1 (a little off it), R2 touching R1 on the goal's left.
  std::vector<Vector2d> at = {goal + Vector2d(0.005, 0), goal - Vector2d(contact - 0.005, 0), nowhere, goal};
  EXPECT_NEAR(reachableDistance(spec, 1, 3, at), contact - 0.005, 1e-9);
  EXPECT_TRUE(goalConditionMet(spec, r2_at_g1, at)) << "touching the robot on the goal";
  at[1] = goal - Vector2d(contact + 0.01, 0);
  EXPECT_TRUE(goalConditionMet(spec, r2_at_g1, at)) << "1 cm short of touching";
  at[1] = goal - Vector2d(contact + 0.05, 0);
  EXPECT_FALSE(goalConditionMet(spec, r2_at_g1, at)) << "5 cm short of touching";
  // Queued behind: R3 touches R2, which touches R1 on the goal: the nearest place on its line.
  at[1] = goal - Vector2d(contact, 0);
  at[2] = goal - Vector2d(2 * contact + 0.002, 0);
  EXPECT_NEAR(reachableDistance(spec, 2, 3, at), 2 * contact, 1e-9);
  EXPECT_TRUE(goalConditionMet(spec, {"R3", "G1", 0.01}, at));
  // A gap narrower than a body is no place to stand; one as wide is.
  at[1] = goal - Vector2d(contact + 0.5 * contact, 0);
  at[2] = goal - Vector2d(4 * contact, 0);
  EXPECT_NEAR(reachableDistance(spec, 2, 3, at), 2.5 * contact, 1e-9);
  at[1] = goal - Vector2d(3 * contact, 0);
  EXPECT_NEAR(reachableDistance(spec, 2, 3, at), contact - 0.005, 1e-9);
  // The goal free: R2 reaches it; the condition is the plain distance.
  at = {nowhere, goal - Vector2d(0.03, 0), nowhere + Vector2d(0, 0.2), goal};
  EXPECT_EQ(reachableDistance(spec, 1, 3, at), 0.0);
  EXPECT_FALSE(goalConditionMet(spec, r2_at_g1, at));
  // Unknown: an entity not in the task, a position not tracked.
  EXPECT_FALSE(goalConditionMet(spec, {"R9", "G1", 1.0}, at));
  at[1] = Vector2d(NAN, NAN);
  EXPECT_FALSE(goalConditionMet(spec, r2_at_g1, at));
  EXPECT_THROW(goalConditionMet(spec, r2_at_g1, {goal}), Error);
}

// Together: one arrived where a motion toward the other ends (contact plus the arrival
// radius), or two on one goal (two radii).
TEST(TogetherDistance, IsContactPlusTheArrivalRadiusAndTwoRadiiOnAGoal) {
  task::TaskSpec spec;
  spec.arrival_radius = 0.03;
  spec.entities = {{"R1", task::EntityKind::Robot, "hamster"},
                   {"B1", task::EntityKind::Object, "box"},
                   {"G1", task::EntityKind::Goal, ""}};
  const double contact = spec.contactDistance(0, 1);
  EXPECT_DOUBLE_EQ(task::togetherDistance(spec, 0, 1), contact + 0.03);
  EXPECT_DOUBLE_EQ(task::togetherDistance(spec, 1, 0), contact + 0.03);
  EXPECT_DOUBLE_EQ(task::togetherDistance(spec, 0, 2), 0.06) << "a goal is driven onto";
  spec.entities[1].radius_m = 0.001;
  EXPECT_DOUBLE_EQ(task::togetherDistance(spec, 0, 1), 0.06) << "never less than two on one goal";
}

// Where a step's bodies end, together (stepEndPositions): two robots sent onto one goal end
// touching, one on it, the other short on its way; an end inside a standing body turns
// about the target and still touches the target only; a load rides where its carrier
// counts as at it (togetherDistance: where the follower stops, not only at contact).
TEST(StepEndPositions, BodiesOfAStepEndWhereTheyFit) {
  const TaskSpec spec = scene();
  const EndPointModel none;
  const int r1 = 0, r2 = 1, b1 = 2, g1 = 3;
  const double robots = spec.contactDistance(r1, r2);
  {
    const std::vector<Vector2d> at = {{0.1, 0.5}, {0.5, 0.1}, {0.9, 0.9}, {0.5, 0.5}};
    const auto ends = stepEndPositions(spec, none, {{r1, "move", g1}, {r2, "move", g1}}, at);
    EXPECT_NEAR((ends[r1] - at[g1]).norm(), 0.0, 1e-9) << "the first onto the goal";
    EXPECT_NEAR((ends[r2] - ends[r1]).norm(), robots, 0.002) << "the second touching it";
    EXPECT_NEAR((ends[r2] - at[g1]).normalized().dot((at[r2] - at[g1]).normalized()), 1.0, 1e-9) << "short on its way";
    // Each alone would end on the goal: the rule for one motion does not see the other.
    EXPECT_NEAR((endPoint(spec, none, {{r1, "move", g1}, {r2, "move", g1}}, 1, at) - at[g1]).norm(), 0.0, 1e-9);
  }
  {
    // R1 to R2 from the left, but B1 stands at R2's left: the end turns about R2.
    const std::vector<Vector2d> at = {{0.1, 0.5}, {0.5, 0.5}, {0.5 - spec.contactDistance(r2, b1), 0.5}, {0.9, 0.9}};
    const auto ends = stepEndPositions(spec, none, {{r1, "move", r2}}, at);
    EXPECT_NEAR((ends[r1] - at[r2]).norm(), robots, 1e-9) << "at contact with its target";
    EXPECT_GE((ends[r1] - at[b1]).norm(), spec.contactDistance(r1, b1) + kEndTurnGapM - 1e-9) << "clear of B1";
    EXPECT_EQ(ends[b1], at[b1]);
  }
  {
    // R1 stopped 2.4 cm short of contact with B1 (where the follower stops): B1 rides with it
    // and ends on G1, R1 behind it; farther than togetherDistance, B1 goes alone.
    const std::vector<Token> carry = {{r1, "carry", g1}, {b1, "carry", g1}};
    const double gap = spec.contactDistance(r1, b1) + 0.024;
    ASSERT_LT(gap, togetherDistance(spec, r1, b1));
    std::vector<Vector2d> at = {{0.2, 0.5}, {0.9, 0.1}, {0.2 + gap, 0.5}, {0.8, 0.5}};
    EXPECT_EQ(ridingLoad(spec, carry, 0, at), 1);
    auto ends = stepEndPositions(spec, none, carry, at);
    EXPECT_NEAR((ends[b1] - at[g1]).norm(), 0.0, 1e-9);
    EXPECT_NEAR((ends[r1] - ends[b1]).norm(), spec.contactDistance(r1, b1), 1e-9);
    at[b1].x() = 0.2 + togetherDistance(spec, r1, b1) + 0.001;
    EXPECT_EQ(ridingLoad(spec, carry, 0, at), -1) << "a load passed from afar moves on its own";
  }
  EXPECT_THROW(stepEndPositions(spec, none, {{r1, "move", 9}}, {{0, 0}, {1, 1}, {2, 2}, {3, 3}}), Error);
}

namespace {

/// R1, R2, R3 and G1; R3 stands still.
TaskSpec meeting() {
  return parseTaskYaml(
      "format: ddace-task/1\nentities:\n  - {name: R1, kind: robot, type: hamster}\n"
      "  - {name: R2, kind: robot, type: hamster}\n  - {name: R3, kind: robot, type: hamster}\n"
      "  - {name: G1, kind: goal}\n",
      "task.yaml");
}

/// One demonstration of one step: every robot in `ends` drives straight from `from` to its
/// end (ends[e], same index as from) toward R3, standing at `r3`, all at once.
Demonstration meetingDemo(const std::vector<Vector2d>& from, const std::vector<Vector2d>& ends, const Vector2d& r3,
                          const std::vector<int>& movers) {
  Demonstration d;
  d.has_label_columns = {true, true, false, false};
  const Vector2d g1(0.1, 0.9);
  auto row = [&](double u, bool labelled) {
    d.t.push_back(0.05 * static_cast<double>(d.t.size()));
    std::vector<Vector2d> p = {from[0], from[1], r3, g1};
    std::vector<Label> l(4);
    for (int e : movers) {
      p[static_cast<size_t>(e)] = from[static_cast<size_t>(e)] + u * (ends[static_cast<size_t>(e)] - from[e]);
      if (labelled) l[static_cast<size_t>(e)] = {"move", 2};
    }
    d.positions.push_back(p);
    d.labels.push_back(l);
  };
  row(0, false);
  for (int i = 0; i <= 20; ++i) row(i / 20.0, true);
  row(1, false);
  d.analyze();
  return d;
}

}  // namespace

// Ends demonstrated round the target at several sides, all at contact: the learned end is
// at contact too (a component-wise median of ends at -60, 0 and +60 degrees would lie
// inside the target, 2.2 cm from its centre).
TEST(EndPoint, EndsDemonstratedAtSeveralSidesOfTheTargetAreLearnedAtTheirDistance) {
  const TaskSpec spec = meeting();
  const double contact = spec.contactDistance(0, 2);
  const Vector2d r3(0.5, 0.5);
  std::vector<Demonstration> ds;
  for (const double side : {-M_PI / 3, 0.0, M_PI / 3, -M_PI / 3, M_PI / 3 + 0.1}) {
    const Vector2d from(0.1, 0.5);  // approaching along +x: behind R3 is -x
    const Vector2d end = r3 + contact * Vector2d(-std::cos(side), std::sin(side));
    ds.push_back(meetingDemo({from, {0.9, 0.1}}, {end, {0.9, 0.1}}, r3, {0}));
  }
  const EndPointModel m = learnEndPoints(spec, ds);
  ASSERT_EQ(m.by_key.at("R1:move:R3").segments, 5);
  EXPECT_NEAR(m.by_key.at("R1:move:R3").offset.norm(), contact, 1e-9);
  EXPECT_TRUE(stopGaps(spec, m, ds).empty()) << stopGaps(spec, m, ds).front().str();
}

// Robots meeting at one robot take the places found round it by the least total travel round
// it: no robot's way to its place crosses another's. Here R1 (from the left) is placed
// first, R4 (from below) next; R2, coming from between them, finds its own side taken and
// its place turned to the far side of R1 -- across R1's way in, each to be held in the
// other's place. The places are the same; R1 takes the far one and R2 R1's.
TEST(StepEndPositions, RobotsMeetingAtOneRobotTakeThePlacesThereWithoutCrossing) {
  const TaskSpec spec = parseTaskYaml(
      "format: ddace-task/1\nentities:\n  - {name: R1, kind: robot, type: hamster}\n"
      "  - {name: R2, kind: robot, type: hamster}\n  - {name: R3, kind: robot, type: hamster}\n"
      "  - {name: R4, kind: robot, type: hamster}\n  - {name: G1, kind: goal}\n",
      "task.yaml");
  const int r1 = 0, r2 = 1, r3 = 2, r4 = 3;
  const Vector2d met(0.5, 0.5);
  const auto from = [&](double degrees) {
    const double a = degrees * M_PI / 180;
    return Vector2d(met + 0.3 * Vector2d(std::cos(a), std::sin(a)));
  };
  const std::vector<Vector2d> at = {from(180), from(190), met, from(250), {0.9, 0.9}};
  const std::vector<Token> step = {{r1, "move", r3}, {r4, "move", r3}, {r2, "move", r3}};
  const auto ends = stepEndPositions(spec, EndPointModel{}, step, at);
  const double contact = spec.contactDistance(r1, r3);
  for (const int e : {r1, r2, r4}) {
    EXPECT_NEAR((ends[e] - met).norm(), contact, 1e-9) << spec.entities[e].name << " touches R3";
    for (const int o : {r1, r2, r4})
      if (o != e) {
        EXPECT_GE((ends[e] - ends[o]).norm(), spec.contactDistance(e, o) - 1e-9) << "places overlap";
      }
  }
  for (const int a : {r1, r2, r4})
    for (const int b : {r1, r2, r4})
      if (a < b) {
        EXPECT_GE((at[a] - at[b]).dot(ends[a] - ends[b]), 0.0)
            << spec.entities[a].name << " and " << spec.entities[b].name << " cross each other's way to their places";
      }
  EXPECT_NEAR((ends[r2] - met).normalized().dot(Vector2d(-1, 0)), 1.0, 1e-9) << "R2 takes the place left of R3";
}
