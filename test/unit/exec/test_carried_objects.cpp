// Objects on the real table: a box's segment judged from tracking, done only when its
// carrier is done and the tracker sees the box at its end point; refused when nothing would
// move it.
#include <gtest/gtest.h>

#include "ddace/exec/carried_objects.h"
#include "ddace/tasks/generators.h"

using namespace ddace;
using Eigen::Vector2d;
using exec::CarriedObjects;
using exec::SegmentState;

namespace {

task::TaskSpec carryTask() {
  task::TaskSpec spec;
  spec.name = "carry";
  spec.entities = {{"R1", task::EntityKind::Robot, ""},
                   {"R2", task::EntityKind::Robot, ""},
                   {"B1", task::EntityKind::Object, "box"},
                   {"G1", task::EntityKind::Goal, ""}};
  return spec;
}
constexpr int R1 = 0, R2 = 1, B1 = 2, G1 = 3;
const Vector2d kGoal(0.5, 0.5);

/// R1 carries B1 to G1 in step 1 (segments 10 and 11); B1 at `box`, everything tracked.
struct Carry {
  CarriedObjects judge{carryTask(), exec::CarriedObjectParams{}};
  Carry() {
    judge.onRobotSegment(R1, 10, 1, {R1, "carry", G1});
    const auto accepted = judge.onObjectSegment(B1, 11, 1, {B1, "carry", G1}, kGoal, 0.0);
    EXPECT_EQ(accepted.size(), 1u);
    EXPECT_EQ(accepted.at(0).state, SegmentState::Accepted);
    EXPECT_EQ(judge.carrierOf(B1), R1);
  }
  void see(const Vector2d& box) { judge.onPositions({{0.1, 0.1}, {0.9, 0.9}, box, kGoal}, {true, true, true, true}); }
};

}  // namespace

TEST(CarriedObjects, DoneWhenTheBoxIsAtItsEndAndItsCarrierIsDone) {
  Carry c;
  c.see({0.2, 0.2});
  EXPECT_TRUE(c.judge.update(1.0).empty());
  // At its end point, but the carrier is still driving: not done yet.
  c.see(kGoal + Vector2d(0.01, 0));
  EXPECT_TRUE(c.judge.update(2.0).empty());
  // Another robot's DONE, or the carrier's DONE of another segment, changes nothing.
  EXPECT_TRUE(c.judge.onRobotStatus(R2, 10, SegmentState::Done, 2.5).empty());
  EXPECT_TRUE(c.judge.onRobotStatus(R1, 9, SegmentState::Done, 2.5).empty());
  EXPECT_TRUE(c.judge.update(2.6).empty());
  EXPECT_TRUE(c.judge.onRobotStatus(R1, 10, SegmentState::Done, 3.0).empty());
  const auto done = c.judge.update(3.0);
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].entity, B1);
  EXPECT_EQ(done[0].segment_id, 11u);
  EXPECT_EQ(done[0].state, SegmentState::Done);
  EXPECT_NEAR(done[0].distance_to_goal_m, 0.01, 1e-12);
  EXPECT_TRUE(c.judge.update(4.0).empty()) << "reported once";
}

TEST(CarriedObjects, CarrierDoneButTheBoxElsewhereFailsNamingTheBox) {
  Carry c;
  c.see({0.4, 0.5});  // 10 cm short: the carrier lost its box on the way
  EXPECT_TRUE(c.judge.onRobotStatus(R1, 10, SegmentState::Done, 5.0).empty());
  EXPECT_TRUE(c.judge.update(5.0).empty()) << "it may still be sliding, or the tracker a frame late";
  EXPECT_TRUE(c.judge.update(6.9).empty());
  const auto failed = c.judge.update(7.1);
  ASSERT_EQ(failed.size(), 1u);
  EXPECT_EQ(failed[0].state, SegmentState::Failed);
  EXPECT_EQ(failed[0].segment_id, 11u);
  EXPECT_NE(failed[0].message.find("B1 is 10.0 cm from its end point"), std::string::npos) << failed[0].message;
  EXPECT_NE(failed[0].message.find("carrier R1"), std::string::npos) << failed[0].message;

  // Not seen at all when its carrier is done: the same, saying so.
  Carry unseen;
  unseen.judge.onPositions({{0.1, 0.1}, {0.9, 0.9}, kGoal, kGoal}, {true, true, false, true});
  unseen.judge.onRobotStatus(R1, 10, SegmentState::Done, 1.0);
  const auto lost = unseen.judge.update(3.5);
  ASSERT_EQ(lost.size(), 1u);
  EXPECT_EQ(lost[0].state, SegmentState::Failed);
  EXPECT_NE(lost[0].message.find("B1 is not seen by the tracker"), std::string::npos) << lost[0].message;
}

TEST(CarriedObjects, ACarrierThatFailsOrIsStoppedEndsItsLoad) {
  Carry failing;
  failing.see({0.3, 0.3});
  const auto failed = failing.judge.onRobotStatus(R1, 10, SegmentState::Failed, 1.0);
  ASSERT_EQ(failed.size(), 1u);
  EXPECT_EQ(failed[0].state, SegmentState::Failed);
  EXPECT_NE(failed[0].message.find("B1: its carrier R1's segment failed"), std::string::npos) << failed[0].message;
  Carry stopped;
  const auto aborted = stopped.judge.stopObject(B1);
  ASSERT_EQ(aborted.size(), 1u);
  EXPECT_EQ(aborted[0].state, SegmentState::Aborted);
  EXPECT_TRUE(stopped.judge.stopObject(B1).empty());
}

TEST(CarriedObjects, AnObjectNoRobotCarriesFailsNamingItsToken) {
  CarriedObjects judge(carryTask(), exec::CarriedObjectParams{});
  // R1 goes to G1 in step 1, B1 is sent to G1 too -- but with another action: no carry.
  judge.onRobotSegment(R1, 20, 0, {R1, "move", G1});
  judge.onObjectSegment(B1, 21, 0, {B1, "carry", G1}, kGoal, 0.0);
  judge.onPositions({{0.1, 0.1}, {0.9, 0.9}, {0.3, 0.3}, kGoal}, {true, true, true, true});
  EXPECT_EQ(judge.carrierOf(B1), -1);
  EXPECT_TRUE(judge.update(0.5).empty()) << "its carrier's segment may come a moment later";
  const auto failed = judge.update(1.5);
  ASSERT_EQ(failed.size(), 1u);
  EXPECT_EQ(failed[0].state, SegmentState::Failed);
  EXPECT_NE(failed[0].message.find("B1:carry:G1 (step 1): no robot carries it"), std::string::npos)
      << failed[0].message;
  // The carrier's segment arriving after the object's pairs them.
  CarriedObjects late(carryTask(), exec::CarriedObjectParams{});
  late.onObjectSegment(B1, 31, 2, {B1, "carry", G1}, kGoal, 0.0);
  late.onRobotSegment(R2, 30, 2, {R2, "carry", G1});
  EXPECT_EQ(late.carrierOf(B1), R2);
}

TEST(CarriedObjects, ATaskMovingAnObjectWithNoCarrierIsRefusedNamingTheToken) {
  // The fetch family: every motion of B1 carried by its fetcher -- runs.
  tasks::GeneratorOptions o;
  o.family = "fetch";
  o.demos = 3;
  task::TaskDir fetch = tasks::generate(o);
  EXPECT_FALSE(exec::uncarriedObjectMotion(fetch).has_value());
  // The same demonstrations with the carrier's token of one step dropped: B1 moves alone.
  task::TaskDir alone = fetch;
  auto& step = alone.demos[1].steps[1].tokens;
  ASSERT_EQ(step.size(), 2u);
  const auto robot = std::find_if(step.begin(), step.end(), [&](const task::Token& t) {
    return alone.spec.entities[static_cast<size_t>(t.entity)].kind == task::EntityKind::Robot;
  });
  ASSERT_NE(robot, step.end());
  step.erase(robot);
  const auto refused = exec::uncarriedObjectMotion(alone);
  ASSERT_TRUE(refused.has_value());
  EXPECT_EQ(*refused, "task '" + alone.spec.name +
                          "': B1:carry:G1 (demonstration 2, step 2) moves an object with no robot carrying it in its "
                          "step; on the real table nothing moves it (run it on mock robots: execute_sim.launch)");
}

TEST(CarriedObjects, InvalidParametersAreNamed) {
  exec::CarriedObjectParams p;
  p.settle_s = -1;
  try {
    CarriedObjects judge(carryTask(), p);
    ADD_FAILURE() << "taken";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("settle_s"), std::string::npos) << e.what();
  }
}
