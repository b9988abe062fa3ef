// What the path follower node knows of the table and the step (exec::FollowerView): the
// decisions it used to make itself -- the stop radius toward a target, what a motion may
// touch from where the step's bodies end, who stands, and when a robot decides again.
#include <gtest/gtest.h>

#include <cmath>

#include "ddace/exec/follower_view.h"
#include "ddace/task/body_geometry.h"

using namespace ddace;
using namespace ddace::exec;
using Eigen::Vector2d;

namespace {

std::map<std::string, task::Entity> kinds() {
  return {{"R1", {"R1", task::EntityKind::Robot, ""}},
          {"R2", {"R2", task::EntityKind::Robot, ""}},
          {"O1", {"O1", task::EntityKind::Object, ""}},
          {"G1", {"G1", task::EntityKind::Goal, ""}}};
}
constexpr double kArrival = 0.03, kMargin = 0.01;

}  // namespace

TEST(FollowerView, AMotionTowardABodyStopsWithinTheToleranceAndOneOntoAGoalOrWithALoadWithinTheStopRadius) {
  FollowerView v(kinds(), kArrival, kMargin);
  v.track("R1", task::EntityKind::Robot, {0.1, 0.3}, false, 1.0);
  v.track("R2", task::EntityKind::Robot, {0.5, 0.3}, false, 1.0);
  v.track("O1", task::EntityKind::Object, {0.14, 0.3}, false, 1.0);
  v.track("G1", task::EntityKind::Goal, {0.8, 0.3}, false, 1.0);
  const double stop = task::stopRadius(kArrival);
  const double tol = kArrival - stop;
  EXPECT_DOUBLE_EQ(v.stopToward("R1", 0, "go", "R2", stop), tol) << "ends where demonstrated against R2";
  EXPECT_DOUBLE_EQ(v.stopToward("R1", 0, "go", "G1", stop), stop) << "a goal is driven onto";
  // With O1's segment of the same step, action and target, O1 is R1's load: it is what ends
  // at R2.
  v.noteSegment("O1", 7, 0, "go", "R2", {0.5 - 0.04, 0.3});
  EXPECT_DOUBLE_EQ(v.stopToward("R1", 0, "go", "R2", stop), stop);
}

TEST(FollowerView, ACarrierMayTouchItsLoadAndWhatItsEndTouches) {
  FollowerView v(kinds(), kArrival, kMargin);
  v.track("R1", task::EntityKind::Robot, {0.1, 0.3}, false, 1.0);
  v.track("R2", task::EntityKind::Robot, {0.5, 0.3}, false, 1.0);
  v.track("O1", task::EntityKind::Object, {0.143, 0.3}, false, 1.0);
  const uint64_t before = v.stepVersion(2);
  v.noteSegment("R1", 1, 2, "carry", "R2", {0.5 - 0.042 - 0.044, 0.3});
  EXPECT_NE(v.stepVersion(2), before) << "the step's robots decide again";
  EXPECT_TRUE(v.contacts("R1", {0.1, 0.3}).load.empty()) << "its load's segment has not arrived yet";
  v.noteSegment("O1", 2, 2, "carry", "R2", {0.5 - 0.042, 0.3});
  const MotionContacts c = v.contacts("R1", {0.1, 0.3});
  EXPECT_EQ(c.load, "O1");
  EXPECT_TRUE(c.load_ends_against.count("R2")) << "the load ends touching R2";
  EXPECT_TRUE(v.contacts("R2", {0.5, 0.3}).load.empty()) << "R2 has no segment";
}

TEST(FollowerView, BodiesWithoutARunningSegmentStandAndAnEndedSegmentIsNotRevived) {
  FollowerView v(kinds(), kArrival, kMargin);
  v.track("R1", task::EntityKind::Robot, {0.1, 0.3}, false, 1.0);
  v.track("R2", task::EntityKind::Robot, {0.5, 0.3}, false, 1.5);
  v.track("G1", task::EntityKind::Goal, {0.8, 0.3}, false, 1.0);
  v.track("X9", std::nullopt, {0.3, 0.3}, false, 1.0);  // unknown: kept off as an object
  double self_age = 0;
  std::vector<SafetyBody> others = v.others("R1", 2.0, self_age);
  EXPECT_DOUBLE_EQ(self_age, 1.0);
  ASSERT_EQ(others.size(), 2u) << "goals have no body";
  for (const SafetyBody& b : others) EXPECT_TRUE(b.standing) << b.name;
  EXPECT_DOUBLE_EQ(others[0].age_s, 0.5);
  v.noteEnded("R2", 4);  // its end arrived before the segment (another connection)
  EXPECT_FALSE(v.noteSegment("R2", 4, 0, "go", "G1", {0.8, 0.3}));
  EXPECT_TRUE(v.noteSegment("R2", 5, 1, "go", "G1", {0.8, 0.3}));
  others = v.others("R1", 2.0, self_age);
  EXPECT_FALSE(others[0].standing) << "R2 runs a segment";
  v.noteEnded("R2", 5);
  others = v.others("R1", 2.0, self_age);
  EXPECT_TRUE(others[0].standing);
  v.track("R1", task::EntityKind::Robot, {NAN, NAN}, false, 3.0);
  v.others("R1", 3.0, self_age);
  EXPECT_GT(self_age, 1e6) << "a pose it cannot use is stale";
}

// A robot the tracker lost stops every robot that comes within the filter's range (its
// pose is stale); once the coordinator declared it lost for good it is an obstacle where
// it was last seen, and a robot near it drives on, kept clear of it.
TEST(FollowerView, ARobotLostForGoodStandsWhereItWasLastSeenInsteadOfStoppingItsNeighbours) {
  FollowerView v(kinds(), kArrival, kMargin);
  v.track("R1", task::EntityKind::Robot, {0.1, 0.3}, false, 1.0);
  v.track("R2", task::EntityKind::Robot, {0.2, 0.3}, false, 1.0);
  v.track("R2", task::EntityKind::Robot, {0.2, 0.3}, true, 1.0);  // the tracker holds it, stale
  v.track("R1", task::EntityKind::Robot, {0.1, 0.3}, false, 9.0);
  SafetyFilter filter({}, 0.03, 0.2, 4.0);
  const Pose2D r1{0.1, 0.3, M_PI / 2};  // heading past R2, 10 cm away
  const auto drive = [&] {
    double self_age = 0;
    const std::vector<SafetyBody> others = v.others("R1", 9.0, self_age);
    return filter.filter("R1", r1, task::kDefaultRobotRadius, self_age, {0.1, 0.1}, 0.0, others, "", 9.0);
  };
  const SafetyCommand before = drive();
  EXPECT_TRUE(before.stale) << "a stale body in range stops the robot";
  EXPECT_NE(before.reason.find("R2"), std::string::npos) << before.reason;

  EXPECT_EQ(v.setLost({"R2", "G1", "R9"}), (std::vector<std::string>{"G1", "R9"})) << "only robots of the task";
  double self_age = 0;
  const std::vector<SafetyBody> others = v.others("R1", 9.0, self_age);
  ASSERT_EQ(others.size(), 1u);
  EXPECT_FALSE(others[0].stale);
  EXPECT_TRUE(others[0].standing);
  EXPECT_DOUBLE_EQ(others[0].age_s, 0.0);
  EXPECT_TRUE(others[0].position.isApprox(Vector2d(0.2, 0.3)));
  const SafetyCommand after = drive();
  EXPECT_FALSE(after.stale) << after.reason;
  EXPECT_GT(after.wheels.left_mps + after.wheels.right_mps, 0.1) << "drives on past it";
  EXPECT_NEAR(after.clearance_m, 0.1 - 2 * task::kDefaultRobotRadius, 1e-9) << "measured against where R2 stands";

  v.setLost({});  // a new run
  EXPECT_TRUE(v.others("R1", 9.0, self_age)[0].stale);
}

// The node's answer to whom a robot is queued behind is the simulator's (motionContacts):
// R3's segment ends behind R2's at R1, so R3 waits while R2's segment runs; once R2's has
// ended R2 stands, and R3 decides again with nobody to wait for.
TEST(FollowerView, ARobotWhosePlaceIsBehindAnothersWaitsWhileThatOnesSegmentRuns) {
  auto k = kinds();
  k["R3"] = {"R3", task::EntityKind::Robot, ""};
  FollowerView v(k, kArrival, 0.02);
  const double contact = 2 * task::kDefaultRobotRadius;
  v.track("R1", task::EntityKind::Robot, {0.5, 0.5}, false, 1.0);
  v.track("R2", task::EntityKind::Robot, {0.9, 0.5}, false, 1.0);
  v.track("R3", task::EntityKind::Robot, {0.7, 0.6}, false, 1.0);
  v.noteSegment("R2", 1, 4, "move", "R1", {0.5 + contact, 0.5});
  v.noteSegment("R3", 2, 4, "move", "R1", {0.5 + 2 * contact, 0.5});
  EXPECT_EQ(v.contacts("R3", {0.7, 0.6}).after, (std::set<std::string>{"R2"}));
  EXPECT_TRUE(v.contacts("R2", {0.9, 0.5}).after.empty());
  double age = 0;
  const auto standing = [&](const std::string& name) {
    for (const SafetyBody& b : v.others("R3", 1.0, age))
      if (b.name == name) return b.standing;
    return false;
  };
  EXPECT_FALSE(standing("R2"));
  v.noteEnded("R2", 1);
  EXPECT_TRUE(standing("R2"));
  EXPECT_TRUE(v.contacts("R3", {0.7, 0.6}).after.empty());
}
