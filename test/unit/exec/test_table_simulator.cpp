// The mock robot node's table: scenes by name, objects carried along their segments and
// released at the end, the segment reports, the e-stop, robots on their wheels.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "ddace/common/error.h"
#include "ddace/exec/scene.h"
#include "ddace/exec/table_simulator.h"
#include "ddace/task/end_point.h"

#include "../common/error_of.h"

using namespace ddace;
using namespace ddace::exec;
using ddace::test::errorOf;

namespace {

task::TaskSpec tableTask() {
  task::TaskSpec spec;
  spec.name = "carry";
  spec.entities = {
      {"R1", task::EntityKind::Robot, ""}, {"O1", task::EntityKind::Object, ""}, {"G1", task::EntityKind::Goal, ""}};
  return spec;
}
constexpr int R1 = 0, O1 = 1, G1 = 2;

/// R1 at the origin facing +x, O1 at (0.2, 0), G1 at (0.5, 0.3); 50 Hz, objects at 0.1 m/s;
/// with bodies (Box2D).
TableSimulator table(const std::vector<std::string>& stalled = {}) {
  TableSimulatorParams p;
  p.bodies = true;
  p.object_speed_mps = 0.1;
  return TableSimulator(tableTask(), {{0, 0, 0}, {0.2, 0, 0}, {0.5, 0.3, 0}}, DiffDriveParams{}, p, stalled);
}

/// Steps `n` times and returns every report in order.
std::vector<ObjectStatus> run(TableSimulator& sim, int n) {
  std::vector<ObjectStatus> all;
  for (int k = 0; k < n; ++k)
    for (auto& s : sim.step()) all.push_back(s);
  return all;
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

}  // namespace

TEST(SceneStartPoses, NamesGoOverTheDemonstrationsFirstRow) {
  const task::TaskSpec spec = tableTask();
  const std::vector<Pose2D> base{{0, 0, 0}, {1, 1, 0}, {2, 2, 0}};
  const auto poses = sceneStartPoses(spec, base, {{"G1", {0.5, 0.6, 0.7}, "scene/G1"}}, "");
  ASSERT_EQ(poses.size(), 3u);
  EXPECT_EQ(poses[O1].x, 1.0);
  EXPECT_EQ(poses[G1].x, 0.5);
  EXPECT_EQ(poses[G1].y, 0.6);
  EXPECT_EQ(poses[G1].yaw, 0.7);
}

TEST(SceneStartPoses, AnUnknownNameIsRefusedNamingWhereItCameFrom) {
  const std::string e = errorOf([] {
    sceneStartPoses(tableTask(), {}, {{"R1", {}, "scene/R1"}, {"R9", {}, "parameter '/mock/scene/R9'"}}, "");
  });
  EXPECT_EQ(e, "parameter '/mock/scene/R9': no entity 'R9' in task 'carry'");
}

TEST(SceneStartPoses, AnEntityWithoutAPoseIsRefusedWithTheHint) {
  const std::string e = errorOf([] {
    sceneStartPoses(tableTask(), {}, {{"R1", {}, "a"}, {"G1", {}, "b"}}, "set ~scene");
  });
  EXPECT_TRUE(contains(e, "no start pose for entity 'O1': set ~scene")) << e;
  EXPECT_THROW(sceneStartPoses(tableTask(), {{0, 0, 0}}, {}, ""), Error);  // a row of another task
  EXPECT_THROW(sceneStartPoses(tableTask(), {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}, {{"O1", {NAN, 0, 0}, "o"}}, ""), Error);
}

TEST(TableSimulator, AnObjectFollowsItsSegmentFromWhereItIsAndIsReleasedAtTheEnd) {
  TableSimulator sim = table();
  // The path's first point is replaced by where the object is: it never jumps.
  const auto accepted = sim.startSegment(O1, 7, {{0, 0}, {0.4, 0}, {0.4, 0.1}});
  ASSERT_TRUE(accepted);
  EXPECT_EQ(accepted->state, SegmentState::Accepted);
  EXPECT_EQ(accepted->segment_id, 7u);
  EXPECT_EQ(accepted->entity, O1);
  EXPECT_TRUE(sim.moving(O1));

  // 1 s at 0.1 m/s: 0.1 m along the path; a Running report every 5th step.
  const auto running = run(sim, 50);
  EXPECT_NEAR(sim.truePose(O1).x, 0.3, 1e-6);  // Box2D computes in float
  EXPECT_NEAR(sim.truePose(O1).y, 0.0, 1e-6);
  ASSERT_EQ(running.size(), 10u);
  for (const auto& s : running) EXPECT_EQ(s.state, SegmentState::Running);
  EXPECT_NEAR(running.back().progress, 0.1 / 0.3, 1e-9);
  EXPECT_NEAR(running.back().distance_to_goal_m, std::hypot(0.1, 0.1), 1e-6);

  // The rest of the path (0.2 m) takes 2 s; Done comes once, at the end.
  const auto rest = run(sim, 100);
  ASSERT_FALSE(rest.empty());
  EXPECT_EQ(rest.back().state, SegmentState::Done);
  EXPECT_EQ(rest.back().segment_id, 7u);
  EXPECT_NEAR(rest.back().progress, 1.0, 1e-12);
  EXPECT_NEAR(rest.back().distance_to_goal_m, 0.0, 1e-6);
  EXPECT_FALSE(sim.moving(O1));

  // Released: it stays at the end of its path and reports nothing more.
  EXPECT_TRUE(run(sim, 50).empty());
  EXPECT_NEAR(sim.truePose(O1).x, 0.4, 1e-6);
  EXPECT_NEAR(sim.truePose(O1).y, 0.1, 1e-6);
  EXPECT_NEAR(sim.measuredPose(O1).y, 0.1, 1e-6);  // objects are tracked exactly
}

TEST(TableSimulator, AResentSegmentChangesNothingAndANewIdReplacesIt) {
  TableSimulator sim = table();
  ASSERT_TRUE(sim.startSegment(O1, 1, {{0, 0}, {1.2, 0}}));
  run(sim, 10);
  const double x = sim.truePose(O1).x;
  EXPECT_FALSE(sim.startSegment(O1, 1, {{0, 0}, {1.2, 0}}));  // the coordinator's resend
  run(sim, 10);
  EXPECT_NEAR(sim.truePose(O1).x, x + 0.02, 1e-6);  // kept going, did not restart

  const auto replaced = sim.startSegment(O1, 2, {{0, 0}, {sim.truePose(O1).x, 0.1}});
  ASSERT_TRUE(replaced);
  EXPECT_EQ(replaced->state, SegmentState::Accepted);
  EXPECT_EQ(replaced->segment_id, 2u);
  const auto done = run(sim, 100);
  ASSERT_FALSE(done.empty());
  EXPECT_EQ(done.back().state, SegmentState::Done);
  EXPECT_EQ(done.back().segment_id, 2u);
  EXPECT_NEAR(sim.truePose(O1).y, 0.1, 1e-6);
}

TEST(TableSimulator, AStoppedOrRefusedSegmentLeavesTheObjectWhereItIs) {
  TableSimulator sim = table();
  const auto empty = sim.startSegment(O1, 3, {});
  ASSERT_TRUE(empty);
  EXPECT_EQ(empty->state, SegmentState::Failed);
  EXPECT_TRUE(contains(empty->message, "empty"));
  EXPECT_FALSE(sim.moving(O1));

  ASSERT_TRUE(sim.startSegment(O1, 4, {{0, 0}, {1, 0}}));
  run(sim, 25);
  const auto stopped = sim.stopSegment(O1);
  ASSERT_TRUE(stopped);
  EXPECT_EQ(stopped->state, SegmentState::Aborted);
  EXPECT_EQ(stopped->segment_id, 4u);
  EXPECT_FALSE(sim.stopSegment(O1));  // nothing is running any more
  EXPECT_TRUE(run(sim, 25).empty());
  EXPECT_NEAR(sim.truePose(O1).x, 0.25, 1e-6);

  ASSERT_TRUE(sim.startSegment(O1, 5, {{0, 0}, {1, 0}}));
  const ObjectStatus refused = sim.refuseSegment(O1, 6, "/robots/O1/segment: path point 2 is not finite");
  EXPECT_EQ(refused.state, SegmentState::Failed);
  EXPECT_EQ(refused.segment_id, 6u);
  EXPECT_EQ(refused.progress, 0.0);
  EXPECT_EQ(refused.message, "/robots/O1/segment: path point 2 is not finite");
  EXPECT_TRUE(run(sim, 25).empty());
  EXPECT_NEAR(sim.truePose(O1).x, 0.25, 1e-6);
}

TEST(TableSimulator, TheEstopAbortsRunningSegmentsAndRefusesNewOnesUntilReleased) {
  TableSimulator sim = table();
  ASSERT_TRUE(sim.startSegment(O1, 1, {{0, 0}, {1, 0}}));
  run(sim, 10);
  const auto aborted = sim.setEstop(true);
  ASSERT_EQ(aborted.size(), 1u);
  EXPECT_EQ(aborted[0].state, SegmentState::Aborted);
  EXPECT_EQ(aborted[0].segment_id, 1u);
  EXPECT_EQ(aborted[0].message, "e-stop");
  const double x = sim.truePose(O1).x;

  const auto refused = sim.startSegment(O1, 2, {{0, 0}, {1, 0}});
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->state, SegmentState::Aborted);
  EXPECT_EQ(refused->segment_id, 2u);
  EXPECT_TRUE(run(sim, 10).empty());
  EXPECT_EQ(sim.truePose(O1).x, x);

  EXPECT_TRUE(sim.setEstop(false).empty());
  const auto again = sim.startSegment(O1, 3, {{0, 0}, {1, 0}});
  ASSERT_TRUE(again);
  EXPECT_EQ(again->state, SegmentState::Accepted);
}

TEST(TableSimulator, RobotsDriveOnTheirWheelsGoalsNeverMove) {
  TableSimulator sim = table();
  for (int k = 0; k < 50; ++k) {
    sim.commandWheels(R1, {0.1, 0.1});
    sim.step();
  }
  EXPECT_NEAR(sim.truePose(R1).x, 0.1, 1e-6);
  EXPECT_NEAR(sim.truePose(R1).y, 0.0, 1e-6);
  EXPECT_NEAR(sim.time(), 1.0, 1e-9);
  EXPECT_EQ(sim.truePose(G1).x, 0.5);
  EXPECT_EQ(sim.truePose(G1).y, 0.3);
  EXPECT_NEAR(sim.truePose(O1).x, 0.2, 1e-6);  // untouched, an object stays where it is

  TableSimulator stuck = table({"R1"});
  for (int k = 0; k < 50; ++k) {
    stuck.commandWheels(R1, {0.1, 0.1});
    stuck.step();
  }
  EXPECT_NEAR(stuck.truePose(R1).x, 0.0, 1e-9);
}

TEST(TableSimulator, ARobotPushesAnObjectAndTheContactIsCounted) {
  TableSimulator sim = table();  // R1 at the origin facing O1, 0.2 m ahead
  EXPECT_TRUE(sim.contacts().empty());
  EXPECT_NEAR(sim.closestApproach().clearance_m, 0.2 - sim.radiusM(R1) - sim.radiusM(O1), 1e-6);
  for (int k = 0; k < 150; ++k) {  // 3 s at 0.1 m/s: 0.3 m, through where O1 was
    sim.commandWheels(R1, {0.1, 0.1});
    sim.step();
  }
  EXPECT_GT(sim.truePose(O1).x, 0.2 + 0.05) << "the pushed object did not move";
  EXPECT_GT(sim.truePose(O1).x, sim.truePose(R1).x);  // ahead of its pusher, not passed through
  ASSERT_GE(sim.contacts().size(), 1u);
  EXPECT_EQ(sim.contacts().front().a, R1);
  EXPECT_EQ(sim.contacts().front().b, O1);
  EXPECT_NEAR(sim.contacts().front().time_s, (0.2 - 0.042) / 0.1, 0.1);  // when the discs met
  EXPECT_LT(sim.closestApproach().clearance_m, 0.001);
  EXPECT_GT(sim.closestApproach().clearance_m, -0.003) << "bodies overlap: no physics";
  EXPECT_EQ(sim.closestApproach().a, R1);
  EXPECT_EQ(sim.closestApproach().b, O1);

  // Without bodies (the paper's points) the robot drives through it, measured all the same.
  TableSimulatorParams points;
  points.bodies = false;
  TableSimulator ghost(tableTask(), {{0, 0, 0}, {0.2, 0, 0}, {0.5, 0.3, 0}}, DiffDriveParams{}, points);
  for (int k = 0; k < 150; ++k) {
    ghost.commandWheels(R1, {0.1, 0.1});
    ghost.step();
  }
  EXPECT_NEAR(ghost.truePose(O1).x, 0.2, 1e-12);
  EXPECT_TRUE(ghost.contacts().empty());
  EXPECT_LT(ghost.closestApproach().clearance_m, -0.04);
}

TEST(TableSimulator, TwoRobotsDrivingIntoEachOtherDoNotPassThrough) {
  task::TaskSpec spec;
  spec.name = "two";
  spec.entities = {{"R1", task::EntityKind::Robot, ""}, {"R2", task::EntityKind::Robot, ""}};
  TableSimulatorParams bodies;
  bodies.bodies = true;
  TableSimulator sim(spec, {{0, 0, 0}, {0.2, 0, M_PI}}, DiffDriveParams{}, bodies);
  double min_gap = 1;
  for (int k = 0; k < 150; ++k) {
    sim.commandWheels(0, {0.1, 0.1});
    sim.commandWheels(1, {0.1, 0.1});
    sim.step();
    min_gap = std::min(min_gap, sim.truePose(1).x - sim.truePose(0).x - sim.radiusM(0) - sim.radiusM(1));
  }
  EXPECT_GT(min_gap, -0.003);
  EXPECT_EQ(sim.contacts().size(), 1u);  // they met once and stayed in contact
}

TEST(TableSimulator, ALoadPlacedOnItsCarrierIsNoCollision) {
  task::TaskSpec spec = tableTask();
  TableSimulatorParams bodies;
  bodies.bodies = true;
  TableSimulator sim(spec, {{0, 0, 0}, {0, 0, 0}, {0.5, 0.3, 0}}, DiffDriveParams{}, bodies);
  ASSERT_EQ(sim.loadedPairs().size(), 1u);
  EXPECT_EQ(sim.loadedPairs()[0], std::make_pair(R1, O1));
  for (int k = 0; k < 50; ++k) {
    sim.commandWheels(R1, {0.1, 0.1});
    sim.step();
  }
  EXPECT_TRUE(sim.contacts().empty());
  EXPECT_NEAR(sim.truePose(O1).x, 0.0, 1e-6);  // the robot drove off from under it
}

// A scene's start is tracked: a load placed touching its carrier (Task 1's cargo in front of
// R1) reads overlapping it by a few millimetres. It is touching, not placed on the carrier:
// the carrier pushes it (before, the two were a loaded pair and R1 drove through its load),
// and bodies touching at the start begin no contact when they part (Task 3's ball leaving
// the passer).
TEST(TableSimulator, ALoadTouchingItsCarrierAtTheStartIsPushedAndPartingIsNoContact) {
  task::TaskSpec spec = tableTask();
  const double contact = task::kDefaultRobotRadius + task::kDefaultObjectRadius;
  TableSimulatorParams p;
  p.bodies = true;
  p.loads_ride = false;
  TableSimulator sim(spec, {{0, 0, 0}, {contact - 0.003, 0, 0}, {0.5, 0.3, 0}}, DiffDriveParams{}, p);
  EXPECT_TRUE(sim.loadedPairs().empty());
  ASSERT_TRUE(sim.carry(R1, O1));
  for (int k = 0; k < 100; ++k) {
    sim.commandWheels(R1, {0.1, 0.1});
    sim.step();
  }
  EXPECT_GT(sim.truePose(O1).x, 0.12) << "R1 drove through its load";
  EXPECT_NEAR(sim.truePose(O1).x - sim.truePose(R1).x, contact, 0.003) << "in front of its carrier, touching";

  TableSimulator parting(spec, {{0, 0, 0}, {contact - 0.003, 0, 0}, {0.5, 0.3, 0}}, DiffDriveParams{}, p);
  ASSERT_TRUE(parting.startSegment(O1, 1, {{contact - 0.003, 0}, {0.2, 0}}));
  run(parting, 50);
  EXPECT_GT(parting.truePose(O1).x, 0.1);
  EXPECT_TRUE(parting.contacts().empty()) << "a contact began at " << parting.contacts()[0].time_s << " s";
}

TEST(TableSimulator, RefusesWhatDoesNotFitTheTask) {
  TableSimulator sim = table();
  EXPECT_TRUE(contains(errorOf([&] { sim.commandWheels(O1, {0.1, 0.1}); }), "'O1' is not a robot"));
  EXPECT_TRUE(contains(errorOf([&] { sim.startSegment(R1, 1, {{0, 0}, {1, 0}}); }), "'R1' is not an object"));
  EXPECT_THROW(sim.stopSegment(G1), Error);
  EXPECT_THROW(sim.truePose(3), Error);
  EXPECT_TRUE(contains(errorOf([] { table({"O1"}); }), "stalled 'O1' is not a robot"));
  EXPECT_THROW(TableSimulator(tableTask(), {{0, 0, 0}}, DiffDriveParams{}), Error);
  TableSimulatorParams slow;
  slow.object_speed_mps = 0;
  EXPECT_THROW(TableSimulator(tableTask(), {{}, {}, {}}, DiffDriveParams{}, slow), Error);
}

TEST(TableSimulator, ALoadRidesInFrontOfItsCarrierAndEndsOnItsGoal) {
  // R1 at the origin facing +x, O1 at its left side touching it; O1's segment to (0.4, 0).
  task::TaskSpec spec = tableTask();
  TableSimulatorParams p;
  p.bodies = true;
  const double contact = task::kDefaultRobotRadius + task::kDefaultObjectRadius;
  TableSimulator sim(spec, {{0, 0, 0}, {0, contact, 0}, {0.5, 0.3, 0}}, DiffDriveParams{}, p);
  ASSERT_TRUE(sim.startSegment(O1, 7, {{0, contact}, {0.4, 0}}));
  ASSERT_TRUE(sim.carry(R1, O1));
  EXPECT_EQ(sim.carrierOf(O1), R1);
  for (int k = 0; k < 100; ++k) {  // 2 s at 0.1 m/s
    sim.commandWheels(R1, {0.1, 0.1});
    for (const ObjectStatus& s : sim.step()) EXPECT_NE(s.state, SegmentState::Done) << "done before its carrier";
  }
  const Eigen::Vector2d r = sim.truePose(R1).position(), o = sim.truePose(O1).position();
  EXPECT_NEAR(o.x() - r.x(), contact, 0.002) << "in front of its carrier";
  EXPECT_NEAR(o.y(), r.y(), 0.002);
  EXPECT_TRUE(sim.contacts().empty());
  for (int k = 0; k < 10; ++k) {  // the carrier stops; the load goes on to its end alone
    sim.commandWheels(R1, {});
    sim.step();
  }
  sim.endCarry(O1);
  EXPECT_EQ(sim.carrierOf(O1), -1);
  bool done = false;
  for (int k = 0; k < 100 && !done; ++k)
    for (const ObjectStatus& s : sim.step()) done = done || (s.segment_id == 7 && s.state == SegmentState::Done);
  EXPECT_TRUE(done);
  EXPECT_LT((sim.truePose(O1).position() - Eigen::Vector2d(0.4, 0)).norm(), 0.005) << "on its goal";

  // A load out of reach does not ride; a robot's segment carries an object's of its step
  // with the same action and target only.
  TableSimulator far(spec, {{0, 0, 0}, {0.2, 0, 0}, {0.5, 0.3, 0}}, DiffDriveParams{}, p);
  EXPECT_FALSE(far.carry(R1, O1));
  // A carrier that stopped where the path follower stops (the stop radius short of contact)
  // is at its load: task::togetherDistance, as the network reads it.
  const double stopped = contact + task::stopRadius(spec.arrival_radius);
  ASSERT_LT(stopped, task::togetherDistance(spec, R1, O1));
  TableSimulator near(spec, {{0, 0, 0}, {stopped, 0, 0}, {0.5, 0.3, 0}}, DiffDriveParams{}, p);
  EXPECT_TRUE(near.carry(R1, O1));
  EXPECT_TRUE(carries(spec, 2, {R1, "move", G1}, 2, {O1, "move", G1}));
  EXPECT_FALSE(carries(spec, 2, {R1, "move", G1}, 3, {O1, "move", G1}));
  EXPECT_FALSE(carries(spec, 2, {R1, "move", G1}, 2, {O1, "push", G1}));
  EXPECT_FALSE(carries(spec, 2, {O1, "move", G1}, 2, {R1, "move", G1}));
}

// Without loads_ride a load goes where its carrier pushes it, nowhere by itself, on a table
// of bodies (Box2D) and of points alike; done when its carrier is done with it at its end
// point, failed naming how far when not.
TEST(TableSimulator, APushedLoadMovesOnlyAsItsCarrierPushesItAndIsJudgedWhereItLies) {
  // R1 at the origin facing +x, O1 just in front of it; O1's segment to (0.2, 0).
  task::TaskSpec spec = tableTask();
  const double contact = task::kDefaultRobotRadius + task::kDefaultObjectRadius;
  for (const bool bodies : {true, false}) {
    SCOPED_TRACE(bodies ? "bodies" : "points");
    TableSimulatorParams p;
    p.bodies = bodies;
    p.loads_ride = false;
    TableSimulator sim(spec, {{0, 0, 0}, {contact + 0.002, 0, 0}, {0.5, 0.3, 0}}, DiffDriveParams{}, p);
    ASSERT_TRUE(sim.startSegment(O1, 7, {{contact + 0.002, 0}, {0.2, 0}}));
    ASSERT_TRUE(sim.carry(R1, O1));
    EXPECT_EQ(sim.carrierOf(O1), R1);
    for (int k = 0; k < 25; ++k)  // its carrier stands: it stays where it is
      for (const ObjectStatus& s : sim.step()) EXPECT_EQ(s.state, SegmentState::Running);
    EXPECT_NEAR(sim.truePose(O1).x, contact + 0.002, 1e-6) << "it moved by itself";
    // Pushed straight ahead until it is on its end point.
    for (int k = 0; k < 200 && sim.truePose(O1).x < 0.2; ++k) {
      sim.commandWheels(R1, {0.1, 0.1});
      for (const ObjectStatus& s : sim.step()) EXPECT_EQ(s.state, SegmentState::Running) << "done before its carrier";
    }
    const Eigen::Vector2d r = sim.truePose(R1).position(), o = sim.truePose(O1).position();
    EXPECT_GT(o.x(), 0.19);
    EXPECT_NEAR(o.x() - r.x(), contact, 0.003) << "in front of its carrier, touching";
    EXPECT_NEAR(o.y(), 0, 0.003);
    sim.commandWheels(R1, {});
    sim.endCarry(O1);
    EXPECT_EQ(sim.carrierOf(O1), -1);
    const std::vector<ObjectStatus> ended = sim.step();
    ASSERT_EQ(ended.size(), 1u);
    EXPECT_EQ(ended[0].segment_id, 7u);
    EXPECT_EQ(ended[0].state, SegmentState::Done) << ended[0].message;

    // Its carrier done with it short of its end point: the segment fails, saying how far.
    TableSimulator short_of(spec, {{0, 0, 0}, {contact + 0.002, 0, 0}, {0.5, 0.3, 0}}, DiffDriveParams{}, p);
    ASSERT_TRUE(short_of.startSegment(O1, 8, {{contact + 0.002, 0}, {0.2, 0}}));
    ASSERT_TRUE(short_of.carry(R1, O1));
    short_of.endCarry(O1);
    const std::vector<ObjectStatus> failed = short_of.step();
    ASSERT_EQ(failed.size(), 1u);
    EXPECT_EQ(failed[0].state, SegmentState::Failed);
    EXPECT_NE(failed[0].message.find("O1 is 15.6 cm from its end point when its carrier R1 was done"),
              std::string::npos)
        << failed[0].message;
  }
}
