// The simulated table of execute_real/record with sim:=true: wheels move robot bodies,
// a robot pushes a box it drives into, the watchdog stops a robot whose wheel speeds
// stop, bad input is refused by name, and a scene is laid out when none is given.
#include <gtest/gtest.h>

#include <cmath>
#include <algorithm>
#include <limits>
#include <string>

#include "ddace/common/error.h"
#include "ddace/exec/sim_table.h"

#include "../common/error_of.h"

using namespace ddace;
using namespace ddace::exec;
using ddace::test::errorOf;

namespace {

task::TaskSpec boxTask() {
  task::TaskSpec spec;
  spec.name = "push";
  spec.entities = {{"R1", task::EntityKind::Robot, ""},
                   {"R2", task::EntityKind::Robot, ""},
                   {"B1", task::EntityKind::Object, ""},
                   {"G1", task::EntityKind::Goal, ""}};
  return spec;
}
constexpr int R1 = 0, R2 = 1, B1 = 2, G1 = 3;

/// R1 at (0.2, 0.5) facing +x with B1 10 cm ahead of it; R2 and G1 out of the way.
SimTable table() {
  return SimTable(boxTask(), {{0.2, 0.5, 0}, {0.2, 0.2, 0}, {0.3, 0.5, 0}, {0.8, 0.8, 0}}, DiffDriveParams{});
}

void run(SimTable& sim, double seconds, const std::string& robot, const WheelSpeeds& wheels) {
  for (double t = 0; t < seconds; t += sim.periodS()) {
    sim.drive(robot, wheels, "test");
    sim.step();
  }
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

}  // namespace

TEST(SimTable, WheelsMoveTheRobotAndItPushesTheBoxItMeets) {
  SimTable sim = table();
  run(sim, 3.0, "R1", {0.1, 0.1});  // 30 cm straight ahead at 10 cm/s
  const auto e = sim.entities();
  EXPECT_GT(e[R1].pose.x, 0.35) << "R1 drove";
  EXPECT_NEAR(e[R1].pose.y, 0.5, 0.01);
  // The box is pushed ahead of R1, never through it: at least their contact distance apart.
  EXPECT_GT(e[B1].pose.x, e[R1].pose.x);
  EXPECT_GE(e[B1].pose.x - e[R1].pose.x, sim.spec().contactDistance(R1, B1) - 0.002);
  ASSERT_FALSE(sim.contacts().empty());
  EXPECT_EQ(sim.contacts().front().a, R1);
  EXPECT_EQ(sim.contacts().front().b, B1);
  // Nothing else moved.
  EXPECT_DOUBLE_EQ(e[R2].pose.x, 0.2);
  EXPECT_DOUBLE_EQ(e[G1].pose.x, 0.8);
}

TEST(SimTable, ARobotWhoseWheelSpeedsStopComingStops) {
  SimTable sim = table();
  sim.drive("R2", {0.1, 0.1}, "test");
  for (int k = 0; k < 150; ++k) sim.step();  // 3 s; the watchdog (0.25 s) stops it after ~2.5 cm
  EXPECT_LT(sim.entities()[R2].pose.x, 0.2 + 0.1 * (DiffDriveParams{}.command_timeout_s + 0.05));
  EXPECT_GT(sim.entities()[R2].pose.x, 0.2 + 0.1 * 0.1);
}

TEST(SimTable, RefusesWheelsOfWhatIsNoRobotNamingTheSource) {
  SimTable sim = table();
  EXPECT_TRUE(contains(errorOf([&] { sim.drive("B1", {0.1, 0.1}, "/sim/wheels"); }), "/sim/wheels: 'B1' is no robot"));
  EXPECT_TRUE(contains(errorOf([&] { sim.drive("R9", {0.1, 0.1}, "/sim/wheels"); }), "'R9' is no robot"));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(contains(errorOf([&] { sim.drive("R1", {nan, 0.1}, "/sim/wheels"); }), "R1 are not finite"));
  for (int k = 0; k < 50; ++k) sim.step();
  EXPECT_DOUBLE_EQ(sim.entities()[R1].pose.x, 0.2) << "a refused speed moves nothing";
}

TEST(LayoutScene, RowsOfEachKindThatDoNotTouchOnTheTable) {
  const task::TaskSpec spec = boxTask();
  const auto poses = layoutScene(spec, {0.1, 0.2}, {1.1, 1.0});  // 1.0 x 0.8 m
  ASSERT_EQ(poses.size(), 4u);
  EXPECT_NEAR(poses[R1].y, poses[R2].y, 1e-12);
  EXPECT_LT(poses[R1].y, poses[B1].y);
  EXPECT_LT(poses[B1].y, poses[G1].y);
  for (size_t i = 0; i < poses.size(); ++i) {
    const double r = spec.footprint(static_cast<int>(i)).radius_m;
    EXPECT_GE(poses[i].x - r, 0.1);
    EXPECT_LE(poses[i].x + r, 1.1);
    EXPECT_GE(poses[i].y - r, 0.2);
    EXPECT_LE(poses[i].y + r, 1.0);
  }
  EXPECT_GT(std::abs(poses[R1].x - poses[R2].x), spec.contactDistance(R1, R2));
  // The laid-out scene is a valid start: the table takes it.
  EXPECT_NO_THROW(SimTable(spec, poses, DiffDriveParams{}));
}

TEST(LayoutScene, SaysWhenARowDoesNotFit) {
  task::TaskSpec spec;
  spec.name = "crowd";
  for (int k = 1; k <= 30; ++k) spec.entities.push_back({"R" + std::to_string(k), task::EntityKind::Robot, ""});
  const std::string e = errorOf([&] { layoutScene(spec, {0, 0}, {1.0, 1.0}); });
  EXPECT_TRUE(contains(e, "30 robots do not fit")) << e;
  EXPECT_TRUE(contains(e, "give their start poses")) << e;
}

namespace {

/// Steps until no drag is left (or `limit_s`); the largest distance any entity moved in one period.
double stepDrags(SimTable& sim, double limit_s, std::vector<double>* largest_step = nullptr) {
  double t = 0;
  auto any = [&] {
    for (const auto& target : sim.dragTargets())
      if (target) return true;
    return false;
  };
  for (; t < limit_s && any(); t += sim.periodS()) {
    const auto before = sim.entities();
    sim.step();
    const auto after = sim.entities();
    if (largest_step)
      for (size_t i = 0; i < after.size(); ++i)
        (*largest_step)[i] =
            std::max((*largest_step)[i], (after[i].pose.position() - before[i].pose.position()).norm());
  }
  return t;
}

}  // namespace

// A dragged robot is not teleported: it turns and drives to where it was dropped on its
// wheels, never faster than they go, and stops there.
TEST(SimTable, ADraggedRobotDrivesToWhereItWasDroppedOnItsWheels) {
  SimTable sim = table();
  const Eigen::Vector2d target(0.1, 0.32);  // behind it, to its left: it turns first
  sim.drag("R2", target, "rviz");
  std::vector<double> largest(4, 0.0);
  const double took_s = stepDrags(sim, 15.0, &largest);
  EXPECT_LT(took_s, 15.0) << "the drag never ended";
  const auto e = sim.entities();
  EXPECT_LT((e[R2].pose.position() - target).norm(), SimTable::kDragStopM + 0.003);
  EXPECT_LE(largest[R2], DiffDriveParams{}.max_wheel_speed_mps * sim.periodS() + 1e-9);
  EXPECT_DOUBLE_EQ(e[R1].pose.x, 0.2);
  EXPECT_DOUBLE_EQ(e[B1].pose.x, 0.3);
  EXPECT_TRUE(sim.takeDragNotes().empty());
  for (int k = 0; k < 50; ++k) sim.step();
  EXPECT_LT((sim.entities()[R2].pose.position() - e[R2].pose.position()).norm(), 1e-3) << "it stands";
}

// A hand carries a box or a goal at hand speed; a goal has no body and passes under a robot.
TEST(SimTable, ADraggedBoxOrGoalIsCarriedByHand) {
  SimTable sim = table();
  sim.drag("B1", {0.5, 0.7}, "rviz");
  sim.drag("G1", {0.2, 0.2}, "rviz");  // onto R2
  std::vector<double> largest(4, 0.0);
  stepDrags(sim, 10.0, &largest);
  const auto e = sim.entities();
  EXPECT_LT((e[B1].pose.position() - Eigen::Vector2d(0.5, 0.7)).norm(), 1e-6);
  EXPECT_LT((e[G1].pose.position() - Eigen::Vector2d(0.2, 0.2)).norm(), 1e-6);
  EXPECT_LE(largest[B1], SimTable::kHandSpeedMps * sim.periodS() + 1e-6);  // (Box2D keeps floats)
  EXPECT_DOUBLE_EQ(e[R2].pose.x, 0.2);
  EXPECT_TRUE(sim.takeDragNotes().empty());
}

// A box dragged onto a robot stops at contact with it, and the drag ends there saying so.
TEST(SimTable, ABoxDraggedOntoARobotStopsAtContactSayingSo) {
  SimTable sim = table();
  sim.drag("B1", {0.2, 0.2}, "rviz");  // R2 stands there
  stepDrags(sim, 20.0);
  const auto e = sim.entities();
  const double gap = (e[B1].pose.position() - e[R2].pose.position()).norm();
  EXPECT_GE(gap, sim.spec().contactDistance(B1, R2) - 1e-3) << "the box went into the robot";
  EXPECT_LT(gap, sim.spec().contactDistance(B1, R2) + 0.005) << "it stopped short of contact";
  const auto notes = sim.takeDragNotes();
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_TRUE(contains(notes[0], "B1 stopped ")) << notes[0];
  EXPECT_TRUE(contains(notes[0], "drag it around")) << notes[0];
}

// The teleop idles on its robot with zero wheels: that does not stop a drag; keys pressed do.
TEST(SimTable, TheKeysTakeOverFromADrag) {
  SimTable sim = table();
  sim.drag("R2", {0.6, 0.2}, "rviz");
  for (int k = 0; k < 25; ++k) {
    sim.drive("R2", {0, 0}, "teleop");
    sim.step();
  }
  EXPECT_TRUE(sim.dragTargets()[R2].has_value());
  EXPECT_GT(sim.entities()[R2].pose.x, 0.21);
  sim.drive("R2", {-0.05, 0.05}, "teleop");
  EXPECT_FALSE(sim.dragTargets()[R2].has_value());
}

TEST(SimTable, RefusesADragOfWhatIsNotOnTheTableNamingTheSource) {
  SimTable sim = table();
  EXPECT_TRUE(contains(errorOf([&] {
                         sim.drag("R9", {0.5, 0.5}, "/sim_table/drag");
                       }),
                       "/sim_table/drag: 'R9' is no entity"));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(contains(errorOf([&] { sim.drag("R1", {nan, 0.5}, "rviz"); }), "R1 dragged to a non-finite"));
  EXPECT_FALSE(sim.dragTargets()[R1].has_value());
}
