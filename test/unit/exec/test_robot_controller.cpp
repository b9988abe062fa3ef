// One robot's control cycle (exec::RobotController): what a motion may touch is decided
// once per step from where bodies end; the cycle stops a robot on a stale pose and fails
// the motion after stale_fail_s; a motion held at contact with what it ends against near
// its end point is done there.
#include <gtest/gtest.h>

#include <cmath>

#include "ddace/common/error.h"
#include "ddace/exec/robot_controller.h"
#include "ddace/task/end_point.h"

using namespace ddace;
using namespace ddace::exec;
using Eigen::Vector2d;

TEST(MotionContacts, AreDecidedFromWhereBodiesEndNotWhereTheyAreNow) {
  // R1 at the origin, its segment (step 2, move G1) ends at (0.3, 0). Robots of radius r,
  // objects of radius o.
  const double r = task::kDefaultRobotRadius, o = task::kDefaultObjectRadius;
  const Eigen::Vector2d end(0.3, 0);
  auto body = [](std::string name, Eigen::Vector2d now, Eigen::Vector2d final_at, double radius) {
    BodyAtStart b;
    b.name = std::move(name);
    b.position = now;
    b.final_position = final_at;
    b.radius_m = radius;
    return b;
  };
  std::vector<BodyAtStart> bodies{
      body("R2", {0.3, r + r}, {0.3, r + r}, r),                          // stands touching its end point
      body("R3", {0.3, 0.0}, {0.6, 0.6}, r),                              // on its end point now, leaving this step
      body("R4", {0.8, 0.8}, {0.3, -(r + r)}, r),                         // ends touching it this step
      body("R5", {0.3 + r + o + o + r, 0}, {0.3 + r + o + o + r, 0}, r),  // touches where the load ends
  };
  BodyAtStart load = body("O1", {r + o, 0}, {0.3 + r + o, 0}, o);
  load.object = true, load.step = 2, load.action = "move", load.target = "G1";
  BodyAtStart other = load;  // an object of another step beside it is no load
  other.name = "O2", other.position = {0, r + o}, other.final_position = other.position, other.step = 1;
  bodies.push_back(other);
  bodies.push_back(load);

  const MotionContacts c = motionContacts({0, 0}, r, end, 2, "move", "G1", bodies, 0.01, 0.03);
  EXPECT_EQ(c.load, "O1");
  EXPECT_EQ(c.ends_against, (std::set<std::string>{"R2", "R4"}));
  EXPECT_EQ(c.load_ends_against, (std::set<std::string>{"R5"}));

  bodies.back().position = {0.2, 0};  // out of reach: moves on its own, no load
  const MotionContacts far = motionContacts({0, 0}, r, end, 2, "move", "G1", bodies, 0.01, 0.03);
  EXPECT_EQ(far.load, "");
  EXPECT_TRUE(far.load_ends_against.empty());
}

// Robots meeting at R1: R2's end touches R1, R3's touches only R2's end, behind it. R3 is
// queued behind R2 (it stands until R2 stands); R2 is queued behind none; onto a flat goal
// nothing queues, nor behind a robot of another step or bound elsewhere.
TEST(MotionContacts, ARobotWhoseEndLiesBehindAnotherMoversOfItsStepIsQueuedBehindIt) {
  const double r = task::kDefaultRobotRadius;
  const auto body = [](std::string name, Vector2d now, Vector2d final_at, int step, std::string target) {
    BodyAtStart b;
    b.name = std::move(name), b.position = now, b.final_position = final_at, b.radius_m = task::kDefaultRobotRadius;
    b.step = step, b.action = "move", b.target = std::move(target);
    return b;
  };
  const Vector2d r1(0.5, 0.5), r2_end = r1 + Vector2d(2 * r, 0), r3_end = r2_end + Vector2d(2 * r, 0);
  BodyAtStart met = body("R1", r1, r1, -1, "");
  const BodyAtStart r2 = body("R2", {0.9, 0.9}, r2_end, 3, "R1"), r3 = body("R3", {0.6, 0.5}, r3_end, 3, "R1");
  const double reach = 0.02, arrival = 0.03;
  EXPECT_EQ(motionContacts(r3.position, r, r3_end, 3, "move", "R1", {met, r2}, reach, arrival).after,
            (std::set<std::string>{"R2"}));
  EXPECT_TRUE(motionContacts(r2.position, r, r2_end, 3, "move", "R1", {met, r3}, reach, arrival).after.empty());
  BodyAtStart elsewhere = r2;  // bound for another body, or in another step
  elsewhere.target = "R4";
  EXPECT_TRUE(motionContacts(r3.position, r, r3_end, 3, "move", "R1", {met, elsewhere}, reach, arrival).after.empty());
  elsewhere = r2, elsewhere.step = 2;
  EXPECT_TRUE(motionContacts(r3.position, r, r3_end, 3, "move", "R1", {met, elsewhere}, reach, arrival).after.empty());
  // G1, a flat goal, has no body: nothing is reached past it.
  BodyAtStart to_goal = r2;
  to_goal.target = "G1";
  EXPECT_TRUE(motionContacts(r3.position, r, r3_end, 3, "move", "G1", {to_goal}, reach, arrival).after.empty());
}

// Two robots bound for one flat goal (Task 4's step 2): the one whose place beside the goal
// lies on the other's way in waits until that one stands; the other does not wait. Without
// the wait, the first there seals the goal: the second, held off it by the filter, never
// ends (seen on the simulated table through the real-robot graph).
TEST(MotionContacts, OntoAFlatGoalARobotWhosePlaceLiesOnAnothersWayInWaitsForIt) {
  const double r = task::kDefaultRobotRadius;
  const auto straight = [](Vector2d a, Vector2d b) {
    std::vector<Vector2d> way;
    for (int i = 0; i <= 50; ++i) way.push_back(a + (b - a) * i / 50.0);
    return way;
  };
  const auto body = [&](std::string name, Vector2d now, std::vector<Vector2d> way) {
    BodyAtStart b;
    b.name = std::move(name), b.position = now, b.final_position = way.back(), b.radius_m = task::kDefaultRobotRadius;
    b.step = 1, b.action = "move", b.target = "G1", b.way = std::move(way);
    return b;
  };
  const Vector2d g1(0.906, 0.475), r3_at(0.471, 0.269), r4_at(0.491, 0.745);
  const BodyAtStart r3 = body("R3", r3_at, straight(r3_at, g1));
  const BodyAtStart r4 = body("R4", r4_at, straight(r4_at, g1 + Vector2d(-0.038, 0.024)));
  const double reach = 0.02, arrival = 0.03;
  const auto after = [&](const BodyAtStart& self, const BodyAtStart& other) {
    return motionContacts(self.position, r, self.final_position, 1, "move", "G1", {other}, reach, arrival, self.way)
        .after;
  };
  EXPECT_EQ(after(r4, r3), (std::set<std::string>{"R3"}));
  EXPECT_TRUE(after(r3, r4).empty());
  // R3, awaited by R4, ends at its own place: R4 is not beside it (stopping short, R3 would
  // stand in R4's place).
  const MotionContacts awaited =
      motionContacts(r3.position, r, r3.final_position, 1, "move", "G1", {r4}, reach, arrival, r3.way);
  EXPECT_EQ(awaited.awaited_by, (std::set<std::string>{"R4"}));
  EXPECT_TRUE(awaited.beside.empty());
  // R3 coming in from the other side of the goal: R4's place is off its way.
  std::vector<Vector2d> round = straight(r3_at, {0.95, 0.3});
  for (const Vector2d& p : straight({0.95, 0.3}, g1)) round.push_back(p);
  EXPECT_TRUE(after(r4, body("R3", r3_at, round)).empty());
  // Its place off the other's way (beside the goal on its own side): no wait.
  EXPECT_TRUE(after(body("R4", r4_at, straight(r4_at, g1 + Vector2d(0, 2 * r + 0.01))), r3).empty());
  // The other's way unknown (a segment without a path): no wait.
  BodyAtStart unknown = r3;
  unknown.way.clear();
  EXPECT_TRUE(after(r4, unknown).empty());
}

namespace {

ControllerParams params() {
  ControllerParams p;
  p.stale_fail_s = 0.5;
  return p;
}

PlannedPath straight(Vector2d a, Vector2d b) {
  PlannedPath p;
  for (int i = 0; i <= 20; ++i) p.points.push_back(a + (b - a) * i / 20.0);
  return p;
}

}  // namespace

TEST(RobotController, IdleGivesZeroWheelsAndRunningDrivesTowardTheEnd) {
  RobotController c("R1", params());
  std::vector<SafetyBody> none;
  ControlOutput o = c.cycle({0, 0, 0}, false, 0, 0.022, none, 0);
  EXPECT_EQ(o.state, MotionState::Idle);
  EXPECT_TRUE(o.wheels.isZero());
  c.start(straight({0, 0}, {0.3, 0}), "", 0.025, 0.025);
  o = c.cycle({0, 0, 0}, false, 0, 0.022, none, 0.02);
  EXPECT_EQ(o.state, MotionState::Running);
  EXPECT_GT(o.wheels.left_mps + o.wheels.right_mps, 0.0);
}

TEST(RobotController, AStalePoseZeroesTheWheelsAtOnceAndFailsTheMotionAfterStaleFailS) {
  RobotController c("R1", params());
  std::vector<SafetyBody> none;
  c.start(straight({0, 0}, {0.3, 0}), "", 0.025, 0.025);
  ControlOutput o = c.cycle({0, 0, 0}, true, 1e9, 0.022, none, 1.0);
  EXPECT_EQ(o.state, MotionState::Running);
  EXPECT_TRUE(o.waiting_stale);
  EXPECT_TRUE(o.wheels.isZero());
  o = c.cycle({0, 0, 0}, false, 0, 0.022, none, 1.2);  // fresh again: drives, the clock restarts
  EXPECT_FALSE(o.waiting_stale);
  EXPECT_FALSE(o.wheels.isZero());
  c.cycle({0, 0, 0}, true, 1e9, 0.022, none, 2.0);
  o = c.cycle({0, 0, 0}, true, 1e9, 0.022, none, 2.4);
  EXPECT_EQ(o.state, MotionState::Running) << "not stale for stale_fail_s yet";
  o = c.cycle({0, 0, 0}, true, 1e9, 0.022, none, 2.6);
  EXPECT_EQ(o.state, MotionState::Failed);
  EXPECT_NE(o.message.find("pose of R1"), std::string::npos) << o.message;
  EXPECT_TRUE(o.wheels.isZero());
  EXPECT_FALSE(c.running());
}

TEST(RobotController, AStaleBodyNearbyStopsTheRobotAsItsOwnPoseWould) {
  RobotController c("R1", params());
  c.start(straight({0, 0}, {0.3, 0}), "", 0.025, 0.025);
  std::vector<SafetyBody> others{{"R2", {0.1, 0}, 0.022, true}};
  others[0].stale = true;
  const ControlOutput o = c.cycle({0, 0, 0}, false, 0, 0.022, others, 0);
  EXPECT_TRUE(o.waiting_stale);
  EXPECT_TRUE(o.wheels.isZero());
  EXPECT_NE(o.message.find("R2"), std::string::npos) << o.message;
}

TEST(RobotController, AMotionHeldOffItsEndPointFailsAsADeadlockNamingWhatHoldsIt) {
  // R2 stands on R1's end point, and R1's motion does not end against it: held off it,
  // R1 fails within deadlock_after_s (and the time it goes round), wheels zero, R2 named.
  const double r = 0.022;
  RobotController c("R1", params());
  c.start(straight({0, 0}, {0.2, 0}), "G1", 0.025, 0.025);
  std::vector<SafetyBody> others{{"R2", {0.2, 0}, r, true}};
  others[0].standing = true;
  Pose2D pose{0, 0, 0};
  ControlOutput o;
  double t = 0;
  for (; t < 20 && o.state != MotionState::Failed; t += 0.02) {
    o = c.cycle(pose, false, 0, r, others, t);
    const double v = (o.wheels.left_mps + o.wheels.right_mps) / 2;
    pose = integrateUnicycle(pose, v, (o.wheels.right_mps - o.wheels.left_mps) / c.params().gains.wheel_base_m, 0.02);
    ASSERT_NE(o.state, MotionState::Done) << "arrived inside R2 at t = " << t;
  }
  ASSERT_EQ(o.state, MotionState::Failed) << "still running after 20 s";
  EXPECT_NE(o.message.find("deadlock: R1"), std::string::npos) << o.message;
  EXPECT_NE(o.message.find("R2"), std::string::npos) << o.message;
  EXPECT_TRUE(o.wheels.isZero());
  EXPECT_GT((pose.position() - Vector2d(0.2, 0)).norm(), 2 * r) << "R1 pushed into R2";
}

// Queued behind R2 (MotionContacts::after), R3 stands while R2 is on its way and drives
// once R2 stands; the wait is no deadlock however long it lasts.
TEST(RobotController, ARobotQueuedBehindAnotherStandsUntilThatOneStands) {
  const double r = 0.022;
  RobotController c("R3", params());
  c.start(straight({0, 0}, {0.3, 0}), "R1", 0.025, 0.025);
  MotionContacts queued;
  queued.after = {"R2"};
  c.setContacts(queued);
  std::vector<SafetyBody> others{{"R2", {0.0, 0.5}, r, true}};
  ControlOutput o;
  for (double t = 0; t < 12; t += 0.02) {
    o = c.cycle({0, 0, 0}, false, 0, r, others, t);
    ASSERT_EQ(o.state, MotionState::Running) << o.message << " at t = " << t;
    ASSERT_TRUE(o.wheels.isZero()) << "drove at t = " << t;
  }
  EXPECT_EQ(o.waiting_for, "R2");
  EXPECT_NE(o.message.find("waits for R2"), std::string::npos) << o.message;
  others[0].standing = true;  // R2 arrived: R3 goes
  o = c.cycle({0, 0, 0}, false, 0, r, others, 12.04);
  EXPECT_EQ(o.waiting_for, "");
  EXPECT_GT(o.wheels.left_mps + o.wheels.right_mps, 0.0);
}

// A carrier touches the load it pushes only from behind it (exec::behindLoad), so that it
// never shoves the load off its line from the side: run into from behind, the load is
// pushed; come at from its side, it is a body like any other, kept off by the filter.
TEST(RobotController, ACarrierTouchesItsLoadOnlyFromBehind) {
  const double r = task::kDefaultRobotRadius, o = task::kDefaultObjectRadius, gap0 = 0.008;
  const Vector2d load(r + o + gap0, 0);
  for (const bool from_behind : {true, false}) {
    SCOPED_TRACE(from_behind ? "from behind" : "from its side");
    RobotController c("R1", params());
    // From its side: the push turns at the load, its route beyond it heads across the
    // carrier's way in.
    const Vector2d load_end = from_behind ? Vector2d(0.3, 0) : Vector2d(load.x(), 0.3);
    c.start(PlannedPath{{Vector2d(0, 0), load, load_end}, {}}, "G1", 0.025, 0.025);
    MotionContacts contacts;
    contacts.load = "O1";
    contacts.load_end = load_end;
    contacts.load_at = load;
    c.setContacts(contacts);
    std::vector<SafetyBody> others{{"O1", load, o, false}};
    others[0].standing = true;
    Pose2D pose{0, 0, 0};
    double closest = gap0;
    for (double t = 0; t < 1.0; t += 0.02) {
      const ControlOutput out = c.cycle(pose, false, 0, r, others, t);
      const double v = (out.wheels.left_mps + out.wheels.right_mps) / 2;
      pose = integrateUnicycle(pose, v, (out.wheels.right_mps - out.wheels.left_mps) / c.params().gains.wheel_base_m,
                               0.02);
      closest = std::min(closest, (pose.position() - load).norm() - r - o);
    }
    // (The load stands still here: a carrier that drives into it overlaps it.)
    if (from_behind) EXPECT_LT(closest, -0.01) << "it did not drive into the load it pushes";
    else EXPECT_GT(closest, -0.002) << "it ran into its load from the side";
  }
}
