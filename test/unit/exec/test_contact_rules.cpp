// Contact rules that hold for any demonstration, on hand-made scenes (not the project's
// generator): a motion touches its target, a carrier its load, a receiving robot the box
// handed to it, a box is fetched with others standing near it, two pairs carry at once. Each scene runs step by step
// through the model with bodies (exec::BodiesExecution: the robots' own controller and filter on the Box2D table), end
// points from the task's end-point rule: the run finishes, no collision is counted for a contact the task demands, and
// one is for any other.
#include <gtest/gtest.h>

#include <cmath>

#include "ddace/exec/bodies_execution.h"
#include "ddace/exec/push_path.h"
#include "ddace/task/end_point.h"

using namespace ddace;
using namespace ddace::exec;
using Eigen::Vector2d;

namespace {

constexpr double kR = task::kDefaultRobotRadius, kO = task::kDefaultObjectRadius;

task::TaskSpec spec(const std::string& entities) {  // "R1 R2 O1 G1": kinds from the letters
  task::TaskSpec s;
  s.name = "contacts";
  std::string name;
  for (size_t i = 0; i <= entities.size(); ++i) {
    if (i < entities.size() && entities[i] != ' ') {
      name += entities[i];
      continue;
    }
    if (name.empty()) continue;
    const task::EntityKind kind = name[0] == 'R'   ? task::EntityKind::Robot
                                  : name[0] == 'O' ? task::EntityKind::Object
                                                   : task::EntityKind::Goal;
    s.entities.push_back({name, kind, ""});
    name.clear();
  }
  return s;
}

Path line(const Vector2d& a, const Vector2d& b) {
  Path p;
  const int n = std::max(2, static_cast<int>((b - a).norm() / 0.005) + 1);
  for (int i = 0; i < n; ++i) p.push_back(a + (b - a) * i / (n - 1.0));
  return p;
}

struct Outcome {
  std::vector<StepExecution> steps;
  BodyReport report;
  std::vector<Vector2d> positions;  ///< at the end
  bool finished() const {
    for (const StepExecution& s : steps)
      if (!s.failures.empty()) return false;
    return true;
  }
  std::string failures() const {
    std::string out;
    for (const StepExecution& s : steps)
      for (const std::string& f : s.failures) out += f + "; ";
    return out;
  }
};

/// Runs `steps` ("R1 move G1, O1 move G1" per step: entity action target) from `start`,
/// each motion on a straight path to its end point (task::stepEndPositions under `model`),
/// a carrier on its push path (exec::drivenPath), as the simulator plans them; entity
/// `unseen` is left out of the planning (put down after the paths were planned). A carried
/// load rides in front of its carrier, or with `pushed` is pushed by it, as on the real table.
Outcome run(const task::TaskSpec& s, const std::vector<Pose2D>& start, const std::vector<std::string>& steps,
            const task::EndPointModel& model = {}, double noise_m = 0.001, bool filter = true, int unseen = -1,
            bool pushed = false) {
  BodiesExecutionParams p;
  p.noise_m = noise_m;
  p.arrival_radius_m = s.arrival_radius;
  p.config.safety.enabled = filter;
  p.config.table.loads_ride = !pushed;
  BodiesExecution m(p);
  m.beginTrial(s, start);
  std::vector<Vector2d> at;
  for (const Pose2D& q : start) at.push_back(q.position());
  Outcome out;
  for (const std::string& text : steps) {
    std::vector<task::Token> tokens;
    std::string rest = text;
    while (!rest.empty()) {
      const size_t comma = rest.find(',');
      std::string one = rest.substr(0, comma);
      rest = comma == std::string::npos ? "" : rest.substr(comma + 1);
      char e[16], a[16], t[16];
      if (std::sscanf(one.c_str(), " %15s %15s %15s", e, a, t) != 3) ADD_FAILURE() << "bad token " << one;
      tokens.push_back({s.entityIndex(e), a, s.entityIndex(t)});
    }
    const std::vector<Vector2d> ends = task::stepEndPositions(s, model, tokens, at);
    std::vector<Vector2d> seen = at;
    if (unseen >= 0) seen[static_cast<size_t>(unseen)] = Vector2d::Constant(std::nan(""));
    std::vector<StepMotion> motions;
    for (size_t i = 0; i < tokens.size(); ++i) {
      const int e = tokens[i].entity;
      motions.push_back({i, e, tokens[i].target, s.entities[e].kind == task::EntityKind::Robot,
                         drivenPath(s, tokens, i, seen, ends, line(at[e], ends[e]))});
    }
    out.steps.push_back(m.executeStep(s, tokens, at, motions));
    at = out.steps.back().positions;
  }
  out.report = m.report();
  out.positions = at;
  return out;
}

std::string collisions(const task::TaskSpec& s, const BodyReport& r) {
  std::string out;
  for (const BodyContact& c : r.collisions)
    out += s.entities[c.a].name + "-" + s.entities[c.b].name + " at " + std::to_string(c.time_s) + " s; ";
  return out;
}

/// The same scene with robot R9 put down across a motion's path at `in_the_way` after the
/// paths were planned (a push would go round it) and the filter off: the motion drives into R9, and that contact -- one
/// no motion involves -- is counted; the contacts the task demands (`demanded`: carrier and load, receiver and the box
/// handed to it, a motion and its target) still are not.
void expectTheIntruderCountedAndNoDemandedContact(const std::string& entities, std::vector<Pose2D> start,
                                                  const std::vector<std::string>& steps, const Vector2d& in_the_way,
                                                  const std::vector<std::pair<std::string, std::string>>& demanded,
                                                  bool pushed = false) {
  SCOPED_TRACE("R9 in the way at " + std::to_string(in_the_way.x()) + ", " + std::to_string(in_the_way.y()));
  const auto s = spec(entities + " R9");
  start.push_back({in_the_way.x(), in_the_way.y(), 0});
  const int r9 = s.entityIndex("R9");
  const Outcome r = run(s, start, steps, {}, 0.001, /*filter=*/false, r9, pushed);
  bool hit = false;
  for (const BodyContact& c : r.report.collisions) hit = hit || c.a == r9 || c.b == r9;
  EXPECT_TRUE(hit) << "driving into R9 was not counted: " << collisions(s, r.report);
  for (const auto& [a, b] : demanded) {
    const int i = std::min(s.entityIndex(a), s.entityIndex(b)), j = std::max(s.entityIndex(a), s.entityIndex(b));
    for (const BodyContact& c : r.report.collisions)
      EXPECT_FALSE(c.a == i && c.b == j) << a << "-" << b << " is demanded, counted: " << collisions(s, r.report);
  }
}

}  // namespace

TEST(ContactRules, AFetchWithTwoBystandersWithin5cmOfTheBoxFinishesWithoutACollision) {
  // R1, the farthest, fetches O1 past R2 and R3 standing 3 and 4 cm from the box, and
  // carries it to G1.
  const auto s = spec("R1 R2 R3 O1 G1");
  const Vector2d box(0.5, 0.4);
  const std::vector<Pose2D> start{{0.1, 0.4, 0},
                                  {box.x(), box.y() + kO + kR + 0.03, 0},
                                  {box.x(), box.y() - kO - kR - 0.04, 0},
                                  {box.x(), box.y(), 0},
                                  {0.8, 0.4, 0}};
  const Outcome r = run(s, start, {"R1 fetch O1", "R1 carry G1, O1 carry G1"});
  EXPECT_TRUE(r.finished()) << r.failures();
  EXPECT_TRUE(r.report.collisions.empty()) << collisions(s, r.report);
  EXPECT_TRUE(task::arrived(r.positions[3], {0.8, 0.4}, s.arrival_radius)) << r.positions[3].transpose();
  EXPECT_LT((r.positions[1] - start[1].position()).norm(), 1e-3) << "R2 was pushed";
  EXPECT_LT((r.positions[2] - start[2].position()).norm(), 1e-3) << "R3 was pushed";
  expectTheIntruderCountedAndNoDemandedContact("R1 R2 R3 O1 G1", start, {"R1 fetch O1", "R1 carry G1, O1 carry G1"},
                                               {0.68, 0.4}, {{"R1", "O1"}});
}

TEST(ContactRules, TheSecondNearestFetchesWhileTheNearestStandsCloseToTheBox) {
  // R2 stands 1 cm from O1 on the side R1 comes from, a little off its line: R1 goes round
  // it to the box and carries the box away.
  const auto s = spec("R1 R2 O1 G1");
  const std::vector<Pose2D> start{{0.2, 0.4, 0}, {0.5 - kO - kR - 0.01, 0.43, 0}, {0.5, 0.4, 0}, {0.5, 0.7, 0}};
  const Outcome r = run(s, start, {"R1 fetch O1", "R1 carry G1, O1 carry G1"});
  EXPECT_TRUE(r.finished()) << r.failures();
  EXPECT_TRUE(r.report.collisions.empty()) << collisions(s, r.report);
  EXPECT_TRUE(task::arrived(r.positions[2], {0.5, 0.7}, s.arrival_radius)) << r.positions[2].transpose();
}

TEST(ContactRules, AThreeHandRelayHandsTheBoxOnWithoutACollision) {
  // R1 brings O1 to R2, R2 brings it on to R3, R3 carries it to G1; each giver stays
  // where it handed the box on.
  const auto s = spec("R1 R2 R3 O1 G1");
  const std::vector<Pose2D> start{
      {0.1, 0.3, 0}, {0.4, 0.3, 0}, {0.4, 0.6, 0}, {0.1 + kR + kO + 0.002, 0.3, 0}, {0.8, 0.6, 0}};
  const std::vector<std::string> steps{"R1 pass R2, O1 pass R2", "R2 pass R3, O1 pass R3", "R3 carry G1, O1 carry G1"};
  const Outcome r = run(s, start, steps);
  EXPECT_TRUE(r.finished()) << r.failures();
  EXPECT_TRUE(r.report.collisions.empty()) << collisions(s, r.report);
  EXPECT_TRUE(task::arrived(r.positions[3], {0.8, 0.6}, s.arrival_radius)) << r.positions[3].transpose();
  expectTheIntruderCountedAndNoDemandedContact("R1 R2 R3 O1 G1", start, steps, {0.62, 0.6},
                                               {{"R1", "O1"}, {"R2", "O1"}, {"R3", "O1"}, {"R1", "R2"}, {"R2", "R3"}});
}

// The same relay with the box pushed, as on the real table: each carrier pushes it round to
// the next robot's side and backs off it; the receiver goes round the box and the giver
// standing beside it and pushes the box on.
TEST(ContactRules, AThreeHandRelayOfAPushedBoxHandsItOnWithoutACollision) {
  const auto s = spec("R1 R2 R3 O1 G1");
  const std::vector<Pose2D> start{
      {0.1, 0.3, 0}, {0.4, 0.3, 0}, {0.4, 0.6, 0}, {0.1 + kR + kO + 0.002, 0.3, 0}, {0.8, 0.6, 0}};
  const std::vector<std::string> steps{"R1 pass R2, O1 pass R2", "R2 pass R3, O1 pass R3", "R3 carry G1, O1 carry G1"};
  const Outcome r = run(s, start, steps, {}, 0.001, true, -1, /*pushed=*/true);
  EXPECT_TRUE(r.finished()) << r.failures();
  EXPECT_TRUE(r.report.collisions.empty()) << collisions(s, r.report);
  EXPECT_TRUE(task::arrived(r.positions[3], {0.8, 0.6}, s.arrival_radius)) << r.positions[3].transpose();
  expectTheIntruderCountedAndNoDemandedContact("R1 R2 R3 O1 G1", start, steps, {0.62, 0.6},
                                               {{"R1", "O1"}, {"R2", "O1"}, {"R3", "O1"}, {"R1", "R2"}, {"R2", "R3"}},
                                               /*pushed=*/true);
}

TEST(ContactRules, TwoPairsCarryAtOnceWithoutACollision) {
  // R1 carries O1 to G1 and R2 carries O2 to G2, side by side in one step.
  const auto s = spec("R1 O1 G1 R2 O2 G2");
  const double c = kR + kO + 0.002;
  const std::vector<Pose2D> start{{0.1, 0.3, 0},  {0.1 + c, 0.3, 0},  {0.7, 0.45, 0},
                                  {0.1, 0.45, 0}, {0.1 + c, 0.45, 0}, {0.7, 0.3, 0}};
  const std::vector<std::string> steps{"R1 carry G1, O1 carry G1, R2 carry G2, O2 carry G2"};
  const Outcome r = run(s, start, steps);
  EXPECT_TRUE(r.finished()) << r.failures();
  EXPECT_TRUE(r.report.collisions.empty()) << collisions(s, r.report);
  EXPECT_TRUE(task::arrived(r.positions[1], {0.7, 0.45}, s.arrival_radius)) << r.positions[1].transpose();
  EXPECT_TRUE(task::arrived(r.positions[4], {0.7, 0.3}, s.arrival_radius)) << r.positions[4].transpose();
  // R9 on the first pair's way before the pairs cross.
  expectTheIntruderCountedAndNoDemandedContact("R1 O1 G1 R2 O2 G2", start, steps, {0.25, 0.335},
                                               {{"R1", "O1"}, {"R2", "O2"}});
}

TEST(ContactRules, TouchingABodyNoMotionInvolvesIsACollision) {
  // R1's path to G1 runs through R2, standing: without the filter it drives into R2 (a
  // collision), with it R1 goes round.
  const auto s = spec("R1 R2 G1");
  const std::vector<Pose2D> start{{0.1, 0.3, 0}, {0.3, 0.3, 0}, {0.5, 0.3, 0}};
  const Outcome without = run(s, start, {"R1 go G1"}, {}, 0.001, /*filter=*/false);
  ASSERT_FALSE(without.report.collisions.empty());
  EXPECT_EQ(collisions(s, without.report).substr(0, 5), "R1-R2");
  const Outcome with = run(s, start, {"R1 go G1"});
  EXPECT_TRUE(with.finished()) << with.failures();
  EXPECT_TRUE(with.report.collisions.empty()) << collisions(s, with.report);
}

// Two and three robots sent to one goal in the same step: one ends on it, the others at the
// robots before them (within the arrival radius of touching), and each meets "at G1"; touching is
// no collision, the run finishes.
TEST(ContactRules, RobotsSentToOneGoalAtOnceEndAtEachOtherWithoutACollision) {
  for (const int robots : {2, 3}) {
    SCOPED_TRACE(std::to_string(robots) + " robots");
    const auto s = spec(robots == 2 ? "R1 R2 G1" : "R1 R2 R3 G1");
    const Vector2d goal(0.6, 0.4);
    std::vector<Pose2D> start{{0.2, 0.4, 0}, {0.2, 0.6, 0}, {0.2, 0.2, 0}};
    start.resize(static_cast<size_t>(robots));
    start.push_back({goal.x(), goal.y(), 0});
    std::string step;
    for (int i = 0; i < robots; ++i) step += (i ? ", R" : "R") + std::to_string(i + 1) + " move G1";
    const Outcome r = run(s, start, {step});
    EXPECT_TRUE(r.finished()) << r.failures();
    EXPECT_TRUE(r.report.collisions.empty()) << collisions(s, r.report);
    // R9 on R2's way (from 0.2, 0.6 to the goal): counted; the robots ending at each other not.
    std::vector<std::pair<std::string, std::string>> demanded;
    for (int i = 1; i <= robots; ++i)
      for (int j = i + 1; j <= robots; ++j) demanded.push_back({"R" + std::to_string(i), "R" + std::to_string(j)});
    expectTheIntruderCountedAndNoDemandedContact(robots == 2 ? "R1 R2 G1" : "R1 R2 R3 G1", {start.begin(), start.end()},
                                                 {step}, {0.4, 0.5}, demanded);
    EXPECT_TRUE(task::arrived(r.positions[0], goal, s.arrival_radius)) << r.positions[0].transpose();
    for (int i = 1; i < robots; ++i) {
      double gap = 1e9;  // to the nearest robot before it
      for (int j = 0; j < i; ++j) gap = std::min(gap, (r.positions[i] - r.positions[j]).norm() - 2 * kR);
      EXPECT_LT(gap, s.arrival_radius) << "R" << i + 1 << " ends " << 100 * gap << " cm off";
      // "Ri at G1" is judged from where its body can stand (task::goalConditionMet): met
      // where it ended; 10 cm further back on its line, not.
      task::GoalCondition at_goal;  // the default tolerance
      at_goal.entity = "R" + std::to_string(i + 1), at_goal.at = "G1";
      EXPECT_TRUE(task::goalConditionMet(s, at_goal, r.positions)) << (r.positions[i] - goal).norm();
      std::vector<Vector2d> short_of = r.positions;
      short_of[i] += 0.1 * (r.positions[i] - goal).normalized();
      EXPECT_FALSE(task::goalConditionMet(s, at_goal, short_of));
    }
  }
}
