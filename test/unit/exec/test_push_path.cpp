// A carrier moves its load by pushing it: its path goes round the load to the far side
// from the load's end point, and its controller (exec::RobotController, the path follower
// node's and the simulators' control cycle) steers the load along the push line on the
// simulated table with bodies (exec::SimTable: nothing carries the box, a disc pushes a
// disc), ending when the load is at its end point.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <random>
#include <string>

#include "ddace/exec/push_path.h"
#include "ddace/exec/robot_controller.h"
#include "ddace/exec/sim_table.h"
#include "ddace/task/end_point.h"

using namespace ddace;
using namespace ddace::exec;

namespace {

task::TaskSpec fetchTask() {
  task::TaskSpec spec;
  spec.name = "fetch";
  spec.entities = {{"R1", task::EntityKind::Robot, ""},
                   {"R2", task::EntityKind::Robot, ""},
                   {"B1", task::EntityKind::Object, ""},
                   {"G1", task::EntityKind::Goal, ""}};
  return spec;
}
constexpr int R1 = 0, B1 = 2, G1 = 3;

struct PushRun {
  bool done = false;
  double seconds = 0;
  Eigen::Vector2d box{0, 0}, carrier{0, 0};
  double travelled_m = 0;  ///< by the carrier, its back-off included
};

/// R1 at `carrier` (facing `yaw`) pushes B1 from `box` onto G1 at `goal` on the simulated
/// table: the push path (planned for the box at `planned_box`, default `box`), then the
/// controller's cycles on exact poses (with `noise_m`: every position measured with that
/// tracking noise, drawn from `seed`), at most 60 s.
PushRun push(const Eigen::Vector2d& carrier, double yaw, const Eigen::Vector2d& box, const Eigen::Vector2d& goal,
             std::optional<Eigen::Vector2d> planned_box = std::nullopt, double noise_m = 0, unsigned seed = 1) {
  const task::TaskSpec spec = fetchTask();
  SimTable sim(spec, {{carrier.x(), carrier.y(), yaw}, {0.9, 0.1, 0}, {box.x(), box.y(), 0}, {goal.x(), goal.y(), 0}},
               DiffDriveParams{});
  const double contact = spec.contactDistance(R1, B1);
  const Eigen::Vector2d u = (goal - box).normalized();
  const Eigen::Vector2d end = goal - contact * u;  // the carrier's end point: behind the load on its goal
  ControllerParams params;
  RobotController c("R1", params);
  const double stop = task::stopRadius(task::kDefaultArrivalRadius);
  c.start(PlannedPath{pushPath(carrier, planned_box.value_or(box), goal, contact, end, 50), {}}, "G1", stop, stop);
  MotionContacts contacts;
  contacts.load = "B1";
  contacts.load_end = goal;
  contacts.load_at = planned_box.value_or(box);
  c.setContacts(contacts);
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0, noise_m);
  const auto measured = [&](const Eigen::Vector2d& p) -> Eigen::Vector2d {
    return noise_m > 0 ? Eigen::Vector2d(p + Eigen::Vector2d(noise(rng), noise(rng))) : p;
  };
  PushRun out;
  out.carrier = carrier;
  for (; sim.time() < 60.0; sim.step()) {
    const auto e = sim.entities();
    std::vector<SafetyBody> others;
    for (size_t i = 1; i < e.size(); ++i) {
      const task::Footprint f = spec.footprint(static_cast<int>(i));
      if (f.obstacle) others.push_back({e[i].name, measured(e[i].pose.position()), f.radius_m, i == 1});
    }
    Pose2D pose = e[R1].pose;
    const Eigen::Vector2d at = measured(pose.position());
    pose.x = at.x(), pose.y = at.y();
    const ControlOutput o = c.cycle(pose, false, 0.0, spec.footprint(R1).radius_m, others, sim.time());
    sim.drive("R1", o.wheels, "test");
    if (sim.time() > 0) out.travelled_m += (e[R1].pose.position() - out.carrier).norm();
    out.carrier = e[R1].pose.position();
    if (o.state == MotionState::Done) {
      out.done = true;
      break;
    }
    if (o.state == MotionState::Failed) {
      std::printf("failed: %s\n", o.message.c_str());
      break;
    }
  }
  for (int k = 0; k < 50; ++k) sim.step();  // the box slides to rest
  const auto e = sim.entities();
  out.seconds = sim.time();
  out.box = e[B1].pose.position();
  out.carrier = e[R1].pose.position();
  return out;
}

}  // namespace

TEST(PushPath, GoesRoundTheLoadToItsFarSideThenStraightThroughIt) {
  const Eigen::Vector2d from(0.3, 0.45), box(0.3, 0.4), load_end(0.8, 0.4), end(0.76, 0.4);
  const auto path = pushPath(from, box, load_end, 0.04, Eigen::Vector2d(0, 0), 60);
  ASSERT_EQ(path.size(), 60u);
  EXPECT_NEAR((path.front() - from).norm(), 0, 1e-9);
  EXPECT_NEAR((path.back() - end).norm(), 0, 1e-9);
  // Never closer to the load than contact before the run-up behind it; the run-up lies
  // on the push line behind the load.
  bool behind = false;
  for (const auto& p : path) {
    if (!behind) {
      EXPECT_GE((p - box).norm(), 0.04 - 1e-6) << p.transpose();
    }
    behind = behind || (p.x() < box.x() - 0.04 && std::abs(p.y() - box.y()) < 0.01);
  }
  EXPECT_TRUE(behind) << "the path never reaches the run-up behind the load";
  // A load already at its end point is not pushed: straight to the end.
  const auto still = pushPath(from, load_end, load_end, 0.04, end, 10);
  for (const auto& p : still)
    EXPECT_LT(std::abs((p - from).x() * (end - from).y() - (p - from).y() * (end - from).x()), 1e-9);
}

// The box lies elsewhere than where its push was planned (it moved since; on the real table,
// slid off its carrier's front): the carrier plans the push again from where things are
// and still brings it onto its goal, rather than driving its old path to its end alone.
TEST(PushPath, ABoxThatMovedSinceItsPushWasPlannedIsStillPushedOntoItsGoal) {
  const Eigen::Vector2d box(0.3, 0.4), goal(0.8, 0.4);
  for (const Eigen::Vector2d& moved : {Eigen::Vector2d(0, 0.06), Eigen::Vector2d(0.08, -0.05)}) {
    const PushRun r = push({0.1, 0.4}, 0.0, box + moved, goal, box);
    EXPECT_TRUE(r.done) << "moved by " << moved.transpose();
    EXPECT_LT((r.box - goal).norm(), task::kDefaultArrivalRadius)
        << "moved by " << moved.transpose() << ": the box at " << r.box.transpose() << " after " << r.seconds << " s";
  }
}

TEST(PushPath, TheCarrierPushesTheBoxOntoItsGoalFromAnySide) {
  // The fetch that failed on the simulated table: the carrier came from above the box and
  // its goal lies up and to the right; and from the goal's side, and from behind.
  struct Case {
    Eigen::Vector2d carrier;
    double yaw;
  };
  const Eigen::Vector2d box(0.256, 0.390), goal(0.871, 0.737);
  for (const Case& k : {Case{{0.262, 0.435}, -M_PI / 2}, Case{{0.296, 0.412}, M_PI}, Case{{0.217, 0.368}, 0.5}}) {
    const PushRun r = push(k.carrier, k.yaw, box, goal);
    EXPECT_TRUE(r.done) << "from " << k.carrier.transpose() << ": the box at " << r.box.transpose();
    EXPECT_LT((r.box - goal).norm(), task::kDefaultArrivalRadius)
        << "from " << k.carrier.transpose() << ": the box at " << r.box.transpose() << " after " << r.seconds << " s";
  }
}

namespace {

/// Robot `robot` of `sim` runs `c` until its motion ends (at most until `until_s`), every
/// other body of the table as its filter sees it (standing, with `others_stand`); the closest
/// the two robots came, centre to centre, is kept in `closest_robots_m`. Returns whether the
/// motion was done.
bool runMotion(SimTable& sim, const task::TaskSpec& spec, RobotController& c, int robot, double until_s,
               double& closest_robots_m, bool others_stand = false) {
  for (; sim.time() < until_s; sim.step()) {
    const auto e = sim.entities();
    closest_robots_m = std::min(closest_robots_m, (e[0].pose.position() - e[1].pose.position()).norm());
    std::vector<SafetyBody> others;
    for (size_t i = 0; i < e.size(); ++i) {
      const task::Footprint f = spec.footprint(static_cast<int>(i));
      if (static_cast<int>(i) != robot && f.obstacle)
        others.push_back({e[i].name, e[i].pose.position(), f.radius_m, spec.entities[i].kind == task::EntityKind::Robot,
                          0.0, false, false, false, others_stand});
    }
    const ControlOutput o = c.cycle(e[robot].pose, false, 0.0, spec.footprint(robot).radius_m, others, sim.time());
    sim.drive(e[robot].name, o.wheels, "test");
    if (o.state == MotionState::Done) return true;
    if (o.state == MotionState::Failed) {
      std::printf("failed: %s\n", o.message.c_str());
      return false;
    }
  }
  return false;
}

}  // namespace

// A relay on the table of bodies: R1 pushes B1 to R2, then R2 pushes it on to G1. A robot
// is wider than a box: R1 left touching the box stands in R2's way round it (R2's filter
// holds it off R1: a deadlock); R1 backs off its load once its push is done, still at it,
// and both pushes finish with the robots never touching.
TEST(PushPath, AGiverBacksOffTheBoxItHandedOnSoTheReceiverPushesItOn) {
  const task::TaskSpec spec = fetchTask();
  constexpr int R2 = 1;
  const Eigen::Vector2d r2(0.45, 0.4);
  const double contact = spec.contactDistance(R1, B1), robots = 2 * spec.footprint(R1).radius_m;
  const double stop = task::stopRadius(task::kDefaultArrivalRadius);
  for (const Eigen::Vector2d& goal : {Eigen::Vector2d(0.5, 0.75), Eigen::Vector2d(0.7, 0.75)}) {
    SCOPED_TRACE("G1 at " + std::to_string(goal.x()) + ", " + std::to_string(goal.y()));
    SimTable sim(spec, {{0.1, 0.4, 0}, {r2.x(), r2.y(), M_PI}, {0.2, 0.4, 0}, {goal.x(), goal.y(), 0}},
                 DiffDriveParams{});
    double closest = 1e9;

    // R1 pushes B1 until it touches R2.
    const Eigen::Vector2d handed = r2 - Eigen::Vector2d(spec.contactDistance(R2, B1), 0);
    RobotController giver("R1", ControllerParams{});
    giver.start(
        PlannedPath{pushPath({0.1, 0.4}, {0.2, 0.4}, handed, contact, handed - Eigen::Vector2d(contact, 0), 40), {}},
        "R2", stop, stop);
    MotionContacts to_r2;
    to_r2.load = "B1", to_r2.load_end = handed, to_r2.load_at = {0.2, 0.4}, to_r2.load_ends_against = {"R2"};
    giver.setContacts(to_r2);
    ASSERT_TRUE(runMotion(sim, spec, giver, R1, 40.0, closest));
    const auto handed_on = sim.entities();
    EXPECT_LT((handed_on[B1].pose.position() - handed).norm(), task::kDefaultArrivalRadius);
    const double gap = (handed_on[R1].pose.position() - handed_on[B1].pose.position()).norm() - contact;
    EXPECT_GE(gap, kPushBackOffM - 0.002) << "R1 stayed against the box";
    EXPECT_TRUE(task::together(spec, R1, handed_on[R1].pose.position(), B1, handed_on[B1].pose.position()))
        << "R1 left its box";

    // R2 pushes B1 on to G1.
    const Eigen::Vector2d box = handed_on[B1].pose.position(), from = handed_on[R2].pose.position();
    const Eigen::Vector2d u = (goal - box).normalized();
    RobotController receiver("R2", ControllerParams{});
    receiver.start(PlannedPath{pushPath(from, box, goal, contact, goal - contact * u, 60), {}}, "G1", stop, stop);
    MotionContacts to_goal;
    to_goal.load = "B1", to_goal.load_end = goal, to_goal.load_at = box;
    receiver.setContacts(to_goal);
    EXPECT_TRUE(runMotion(sim, spec, receiver, R2, sim.time() + 60.0, closest));
    for (int k = 0; k < 50; ++k) sim.step();  // the box slides to rest
    const auto e = sim.entities();
    EXPECT_LT((e[B1].pose.position() - goal).norm(), task::kDefaultArrivalRadius) << e[B1].pose.position().transpose();
    EXPECT_GT(closest, robots) << "R1 and R2 touched";
  }
}

// A box pushed off its centre slides sideways; the carrier over-steers its drift
// (kPushLead) and brings it back toward its line within the push, without losing it and
// going round it again: from up to 40 degrees off the line the box is on its goal with the
// carrier driving about as far as in a straight push (a loop round the box adds more than
// half a turn at kPushClearanceM from it), on average within 2 cm of its line (kPushLead 0.5 left
// it 2.7 cm off).
TEST(PushPath, ABoxPushedOffItsCentreIsSteeredBackOntoItsLine) {
  const task::TaskSpec spec = fetchTask();
  const double contact = spec.contactDistance(R1, B1);
  const Eigen::Vector2d box(0.3, 0.4), goal(0.7, 0.4);
  const double straight_m = push(box - Eigen::Vector2d(contact + 0.001, 0), 0, box, goal).travelled_m;
  double off_line_m = 0;
  const std::vector<double> offs{0.35, -0.5, 0.7};
  for (const double off : offs) {
    const Eigen::Vector2d u(std::cos(off), std::sin(off));
    const PushRun r = push(box - (contact + 0.001) * u, off, box, goal);
    EXPECT_TRUE(r.done);
    EXPECT_LT((r.box - goal).norm(), task::kDefaultArrivalRadius) << r.box.transpose();
    EXPECT_LT(r.travelled_m, straight_m + M_PI * kPushClearanceM) << off << " rad off its line: lost and gone round";
    off_line_m += std::abs(r.box.y() - goal.y()) / offs.size();
  }
  EXPECT_LT(off_line_m, 0.02);
}

// A short push -- a relay's receiver carrying the box on to the goal nearest it -- whose
// carrier comes round the box from any side, on poses measured with 2 mm of tracking noise:
// the push slows while the box heads off where it should, so the carrier's over-steer turns
// their contact back before the push drags the box on off its line. The box arrives on its
// line (0.9 cm off on average) and the carrier, backed off behind it, within the arrival
// radius of its end point in 9 pushes of 10 (pushed at full speed whatever the drift: the box
// 1.5 cm off its line, the carrier outside the arrival radius in 4 pushes of 10).
TEST(PushPath, AShortPushFromAnySideBringsTheBoxOnItsLineAndTheCarrierToItsEnd) {
  const task::TaskSpec spec = fetchTask();
  const double contact = spec.contactDistance(R1, B1);
  const Eigen::Vector2d box(0.5, 0.5);
  int pushes = 0, carrier_at_end = 0;
  double off_line_m = 0;
  unsigned seed = 1;
  for (const double length : {0.15, 0.2})
    for (const double heading : {0.0, 1.3, 2.5, -2.0})
      for (int side = 0; side < 12; ++side) {
        const Eigen::Vector2d u(std::cos(heading), std::sin(heading));
        const Eigen::Vector2d goal = box + length * u;
        const double from = heading + 2 * M_PI * side / 12;
        const Eigen::Vector2d carrier = box + 0.09 * Eigen::Vector2d(std::cos(from), std::sin(from));
        const PushRun r = push(carrier, from + M_PI, box, goal, std::nullopt, 0.002, seed++);
        SCOPED_TRACE("a push of " + std::to_string(length) + " m heading " + std::to_string(heading) +
                     " rad, the carrier from " + std::to_string(from) + " rad");
        EXPECT_TRUE(r.done);
        EXPECT_LT((r.box - goal).norm(), task::kDefaultArrivalRadius) << r.box.transpose();
        ++pushes;
        carrier_at_end += task::arrived(r.carrier, goal - contact * u, task::kDefaultArrivalRadius);
        off_line_m += std::abs((r.box - goal).x() * u.y() - (r.box - goal).y() * u.x());
      }
  EXPECT_LT(off_line_m / pushes, 0.011);
  EXPECT_GE(carrier_at_end, 0.85 * pushes);
}

namespace {

double distanceToSegment(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (a + t * ab - p).norm();
}

}  // namespace

// Task 3's screen: the ball lies behind the shooter, two robots stand between it and the
// hoop, too close together for the ball to pass between them. The ball's route goes round
// them (every leg keeps their reach; the one beside the ball kPushNearPassM beyond contact),
// the carrier pushes it along that route to behind the hoop, and a way that is free stays
// straight.
TEST(PushPath, TheRouteGoesRoundBodiesStandingInTheWayOfThePush) {
  const Eigen::Vector2d ball(0.377, 0.231), hoop(0.894, 0.812), shooter(0.419, 0.232);
  const Eigen::Vector2d defender(0.462, 0.285), screen(0.396, 0.294);  // 6.6 cm apart
  const double robot = task::kDefaultRobotRadius, contact_ball = robot + task::kDefaultObjectRadius;
  const double reach = 2 * robot + kPushPassM;  // the carrier's contact with a robot: the larger
  const std::vector<PushObstacle> standing = {{defender, reach}, {screen, reach}};
  ASSERT_LT(distanceToSegment(screen, ball, hoop), 2 * robot) << "the straight push runs into the screen";

  EXPECT_EQ(pushRoute(ball, hoop, {}).size(), 2u);
  EXPECT_EQ(pushRoute(ball, hoop, {{{0.2, 0.8}, reach}}).size(), 2u) << "a body off the way";
  const std::vector<Eigen::Vector2d> route = pushRoute(ball, hoop, standing);
  ASSERT_GT(route.size(), 2u);
  EXPECT_EQ(route.front(), ball);
  EXPECT_EQ(route.back(), hoop);
  const double near_screen = 2 * robot + kPushNearPassM;  // the screen stands within reach of the ball
  for (size_t k = 1; k < route.size(); ++k) {
    EXPECT_GE(distanceToSegment(defender, route[k - 1], route[k]), reach - 1e-9) << "leg " << k;
    EXPECT_GE(distanceToSegment(screen, route[k - 1], route[k]), near_screen - 1e-9) << "leg " << k;
  }

  const std::vector<Eigen::Vector2d> path = pushPathAlong(shooter, route, contact_ball, 400, standing);
  for (size_t k = 1; k + 1 < route.size(); ++k) {
    double nearest = 1e9;
    for (const Eigen::Vector2d& p : path) nearest = std::min(nearest, (p - route[k]).norm());
    EXPECT_LT(nearest, 0.005) << "the carrier drives the route's corner " << route[k].transpose();
  }
  const Eigen::Vector2d last = (route.back() - route[route.size() - 2]).normalized();
  EXPECT_LT((path.back() - (hoop - contact_ball * last)).norm(), 1e-6) << "behind the ball on the hoop";
}

namespace {

/// Task 3's step 3 on the table of bodies (a test scene of `ddace generate task3`): the
/// defender R1 and the screen R2 stand between the ball B1 and the hoop G1; the shooter R3
/// lies beside the ball, facing `shooter_heading`.
struct ScreenScene {
  Eigen::Vector2d defender, screen, hoop, ball, shooter;
  double shooter_heading = 0;
};

task::TaskSpec screenTask() {
  task::TaskSpec spec;
  spec.name = "screen";
  spec.entities = {{"R1", task::EntityKind::Robot, ""},
                   {"R2", task::EntityKind::Robot, ""},
                   {"R3", task::EntityKind::Robot, ""},
                   {"B1", task::EntityKind::Object, ""},
                   {"G1", task::EntityKind::Goal, ""}};
  return spec;
}

/// The standing robots' reach for the ball's route: the carrier's contact with a robot.
std::vector<PushObstacle> screenStanding(const ScreenScene& s) {
  const double reach = 2 * task::kDefaultRobotRadius + kPushPassM;
  return {{s.defender, reach}, {s.screen, reach}};
}

/// The shooter pushes the ball along its route round the standing robots: the ball ends on
/// the hoop, and neither the ball nor the shooter touches a robot standing in the way.
void expectBallPushedOntoTheHoop(const ScreenScene& s, bool others_stand) {
  const task::TaskSpec spec = screenTask();
  constexpr int R3 = 2, Ball = 3;
  SimTable sim(spec,
               {{s.defender.x(), s.defender.y(), -2.3},
                {s.screen.x(), s.screen.y(), -0.6},
                {s.shooter.x(), s.shooter.y(), s.shooter_heading},
                {s.ball.x(), s.ball.y(), 0},
                {s.hoop.x(), s.hoop.y(), 0}},
               DiffDriveParams{});
  const double contact = spec.contactDistance(R3, Ball), stop = task::stopRadius(task::kDefaultArrivalRadius);
  RobotController shooter("R3", ControllerParams{});
  shooter.start(PlannedPath{pushPath(s.shooter, s.ball, s.hoop, contact, s.hoop, 200, screenStanding(s)), {}}, "G1",
                stop, stop);
  MotionContacts contacts;
  contacts.load = "B1", contacts.load_end = s.hoop, contacts.load_at = s.ball;
  shooter.setContacts(contacts);
  double closest = 1e9;
  EXPECT_TRUE(runMotion(sim, spec, shooter, R3, 40.0, closest, others_stand));
  for (int k = 0; k < 50; ++k) sim.step();  // the ball rolls to rest
  const auto e = sim.entities();
  EXPECT_LT((e[Ball].pose.position() - s.hoop).norm(), task::kDefaultArrivalRadius)
      << "the ball at " << e[Ball].pose.position().transpose() << " after " << sim.time() << " s";
  for (const BodyContact& c : sim.contacts())
    if (std::max(c.a, c.b) >= R3 && std::min(c.a, c.b) < R3)
      ADD_FAILURE() << spec.entities[c.a].name << " touched " << spec.entities[c.b].name << " at " << c.time_s << " s";
}

}  // namespace

// Task 3's screen on the table of bodies: the shooter pushes the ball round the defender
// and the screen standing between it and the hoop. The ball follows its carrier's whole
// route, bend and all (exec::loadRoute): it reaches the hoop, and neither the ball nor the
// shooter touches a robot standing in the way. (Steered only along the route's last leg, the
// ball was aimed through the screen and the shooter, never behind it by that leg, was held
// at the ball: a deadlock.)
TEST(PushPath, ABallPushedRoundRobotsStandingInTheWayReachesTheHoop) {
  // As the step begins: the ball passed to the shooter lies at its side, the defender
  // touches the shooter, the screen the defender.
  ScreenScene s;
  s.defender = {0.440, 0.253}, s.screen = {0.385, 0.289}, s.hoop = {0.845, 0.886};
  s.ball = {0.357, 0.219}, s.shooter = {0.400, 0.205}, s.shooter_heading = -2.78;
  ASSERT_GT(pushRoute(s.ball, s.hoop, screenStanding(s)).size(), 2u) << "the straight push runs into the screen";
  expectBallPushedOntoTheHoop(s, /*others_stand=*/false);
}

// Task 3's step 3 where the ball lies beside the screen: the straight push to the hoop runs
// into the defender and the screen, and the ball starts 1.3 cm beyond contact with the
// screen. The route may pass the screen that near only while leaving it; once round the
// defender's corner it keeps the screen at its reach. Before, the leg from the defender's
// corner ran along the screen at 1.4 cm beyond contact for the carrier as well, where the
// filter held the carrier off the screen and the ball, pushed round the corner, drifted
// into it: the push broke again and again and the ball stayed where it lay.
TEST(PushPath, ARouteLeavingABodyItStartsBesidePassesItAtItsReachOnceAway) {
  ScreenScene s;
  s.defender = {0.442, 0.295}, s.screen = {0.390, 0.294}, s.hoop = {0.797, 0.903};
  s.ball = {0.374, 0.241}, s.shooter = {0.415, 0.252}, s.shooter_heading = -3.01;
  const std::vector<Eigen::Vector2d> route = pushRoute(s.ball, s.hoop, screenStanding(s));
  ASSERT_GT(route.size(), 2u) << "the straight push runs into the screen";
  const double reach = screenStanding(s)[1].reach_m;
  for (size_t k = 2; k < route.size(); ++k)
    EXPECT_GE(distanceToSegment(s.screen, route[k - 1], route[k]), reach - 1e-9)
        << "leg " << k << " runs along the screen";
  expectBallPushedOntoTheHoop(s, /*others_stand=*/true);
}

// A pushed relay's hand-over leaves the box between the two robots: the giver behind it,
// backed off, the receiver in front. Where the goal lies beyond the receiver, the giver
// stands where the receiver would push from; the receiver's filter holds it off the giver
// short of there (it was held against the giver, or passed the box and left it where it
// was handed on). The push goes out from beside the giver first: the receiver's path keeps
// the giver beyond the filter's margin everywhere, the box's route keeps it at its reach,
// and the box still ends on its goal, the carrier behind it. Where the run-up is free (the
// goal to the side), the push is planned as before.
TEST(PushPath, AReceiverWhoseRunUpTheGiverStandsInPushesTheBoxOutFromBesideItFirst) {
  const double robot = task::kDefaultRobotRadius, contact = robot + task::kDefaultObjectRadius;
  const Eigen::Vector2d box(0.405, 0.4), receiver(box.x() + contact + 0.004, 0.4);
  const Eigen::Vector2d giver(box.x() - contact - kPushBackOffM, 0.402);
  const std::vector<PushObstacle> standing{{giver, 2 * robot + kPushPassM}};
  for (const Eigen::Vector2d& goal : {Eigen::Vector2d(0.805, 0.4), Eigen::Vector2d(0.78, 0.26)}) {
    SCOPED_TRACE("G1 at " + std::to_string(goal.x()) + ", " + std::to_string(goal.y()));
    const Eigen::Vector2d u = (goal - box).normalized();
    ASSERT_EQ(pushRoute(box, goal, standing).size(), 2u) << "nothing stands in the box's way";
    ASSERT_LT((box - contact * u - giver).norm(), 2 * robot + kPushNearPassM) << "the giver stands at the run-up";

    const std::vector<Eigen::Vector2d> path = pushPath(receiver, box, goal, contact, goal - contact * u, 400, standing);
    double nearest = 1e9;
    for (size_t k = 1; k < path.size(); ++k)
      nearest = std::min(nearest, distanceToSegment(giver, path[k - 1], path[k]));
    EXPECT_GE(nearest, 2 * robot + kPushNearPassM) << "the receiver is sent into the giver's margin";
    const std::vector<Eigen::Vector2d> route = loadRoute(path, box, box, goal);
    for (size_t k = 1; k < route.size(); ++k)
      EXPECT_GE(distanceToSegment(giver, route[k - 1], route[k]), contact + kPushNearPassM - 1e-9) << "leg " << k;
    const Eigen::Vector2d last = (route.back() - route[route.size() - 2]).normalized();
    EXPECT_LT((route.back() - goal).norm(), 1e-9);
    EXPECT_LT((path.back() - (goal - contact * last)).norm(), 1e-6) << "behind the box on its goal";
  }
  const Eigen::Vector2d side(0.5, 0.75);
  EXPECT_EQ(pushPath(receiver, box, side, contact, side, 100, standing),
            pushPathAlong(receiver, pushRoute(box, side, standing), contact, 100, standing))
      << "a free run-up: the push as before";
}

// A relay's receiver standing within the cone behind the box it is handed (zoo:87, seed 9,
// demonstration 4, step 3), their contact normal pointing 13 degrees off the giver backed
// off beside the box: pushed from where it stands, the box goes first along that normal,
// into the giver (the replay's "R4 touched B1"). It goes round the box to behind it first
// (exec::pushMayStartHere) and the box reaches its goal without touching the giver.
TEST(PushPath, AReceiverWhoseContactNormalPointsAtTheGiverGoesRoundTheBoxFirst) {
  const task::TaskSpec spec = fetchTask();
  constexpr int R2 = 1;
  const Eigen::Vector2d giver(0.388, 0.416), box(0.343, 0.457), goal(0.917, 0.575);
  const double contact = spec.contactDistance(R1, B1), robots = 2 * spec.footprint(R1).radius_m;
  const Eigen::Vector2d receiver = box + (contact + 0.002) * Eigen::Vector2d(-0.0366, 0.0206).normalized();
  const std::vector<PushObstacle> standing{{giver, robots + kPushPassM}};
  const std::vector<Eigen::Vector2d> route = pushRoute(box, goal, standing);
  ASSERT_TRUE(pushMayStartHere(receiver, box, route, contact, {})) << "within the cone behind the box";
  EXPECT_FALSE(pushMayStartHere(receiver, box, route, contact, standing));

  const double stop = task::stopRadius(task::kDefaultArrivalRadius);
  const Eigen::Vector2d u = (goal - box).normalized();
  SimTable sim(spec,
               {{receiver.x(), receiver.y(), std::atan2(u.y(), u.x())},
                {giver.x(), giver.y(), 0},
                {box.x(), box.y(), 0},
                {goal.x(), goal.y(), 0}},
               DiffDriveParams{});
  RobotController c("R1", ControllerParams{});
  c.start(PlannedPath{pushPath(receiver, box, goal, contact, goal - contact * u, 200, standing), {}}, "G1", stop, stop);
  MotionContacts to_goal;
  to_goal.load = "B1", to_goal.load_end = goal, to_goal.load_at = box;
  c.setContacts(to_goal);
  double closest = 1e9;
  EXPECT_TRUE(runMotion(sim, spec, c, R1, 60.0, closest, /*others_stand=*/true));
  for (int k = 0; k < 50; ++k) sim.step();  // the box slides to rest
  for (const BodyContact& k : sim.contacts())
    EXPECT_FALSE(k.a == R2 || k.b == R2) << spec.entities[k.a].name << " touched " << spec.entities[k.b].name << " at "
                                         << k.time_s << " s";
  EXPECT_LT((sim.entities()[B1].pose.position() - goal).norm(), task::kDefaultArrivalRadius);
}

namespace {

struct PlannedAgain {
  bool done = false;
  int held_by_r2 = 0;  ///< cycles in which the filter held R1 against R2
  int touched_r2 = 0;  ///< contacts anybody made with R2
  Eigen::Vector2d box{0, 0};
};

/// R1 at `carrier` (facing up) pushes B1 onto G1 at `goal`, its push planned for B1 at
/// `planned_box` with R2 standing at `stander`, but B1 lies at `box`: the controller plans the
/// push again at once, R2 seen standing; at most 60 s.
PlannedAgain pushPlannedAgain(const Eigen::Vector2d& carrier, const Eigen::Vector2d& planned_box,
                              const Eigen::Vector2d& box, const Eigen::Vector2d& goal, const Eigen::Vector2d& stander) {
  const task::TaskSpec spec = fetchTask();
  constexpr int R2 = 1;
  const double contact = spec.contactDistance(R1, B1);
  const std::vector<PushObstacle> standing{{stander, spec.contactDistance(R1, R2) + kPushPassM}};
  const double stop = task::stopRadius(task::kDefaultArrivalRadius);
  SimTable sim(spec,
               {{carrier.x(), carrier.y(), M_PI / 2},
                {stander.x(), stander.y(), 0},
                {box.x(), box.y(), 0},
                {goal.x(), goal.y(), 0}},
               DiffDriveParams{});
  RobotController c("R1", ControllerParams{});
  const Eigen::Vector2d end = goal - contact * (goal - planned_box).normalized();
  c.start(PlannedPath{pushPath(carrier, planned_box, goal, contact, end, 200, standing), {}}, "G1", stop, stop);
  MotionContacts to_goal;
  to_goal.load = "B1", to_goal.load_end = goal, to_goal.load_at = planned_box;
  c.setContacts(to_goal);
  PlannedAgain out;
  for (; sim.time() < 60.0 && !out.done; sim.step()) {
    const auto e = sim.entities();
    std::vector<SafetyBody> others;
    for (const int i : {R2, B1}) {
      others.push_back({e[i].name, e[i].pose.position(), spec.footprint(i).radius_m, i == R2});
      others.back().standing = true;
    }
    const ControlOutput o = c.cycle(e[R1].pose, false, 0.0, spec.footprint(R1).radius_m, others, sim.time());
    sim.drive("R1", o.wheels, "test");
    out.held_by_r2 += std::count(o.blocking.begin(), o.blocking.end(), "R2") > 0 ? 1 : 0;
    out.done = o.state == MotionState::Done;
    if (o.state == MotionState::Failed) break;
  }
  for (int k = 0; k < 50; ++k) sim.step();  // the box slides to rest
  for (const BodyContact& k : sim.contacts()) out.touched_r2 += k.a == R2 || k.b == R2 ? 1 : 0;
  out.box = sim.entities()[B1].pose.position();
  return out;
}

/// The push planned again ended with B1 on its goal, R1 never held against R2, nobody touching R2.
void expectPushedPastTheStander(const PlannedAgain& r, const Eigen::Vector2d& goal) {
  EXPECT_TRUE(r.done);
  EXPECT_EQ(r.held_by_r2, 0) << "cycles in which the filter held R1 against R2";
  EXPECT_EQ(r.touched_r2, 0);
  EXPECT_LT((r.box - goal).norm(), task::kDefaultArrivalRadius) << "the box at " << r.box.transpose();
}

}  // namespace

// The box moved since its push was planned (a hand, or it slid off its carrier's front):
// the carrier plans its push again from where things are, and a robot stands on the short
// way round the box. The push planned again goes round the bodies standing as the first
// plan did -- here the long way, below the box: the robot standing there never holds the
// carrier, and the box ends on its goal with nobody touching that robot. (Planned again
// with no standing bodies, the path went over the top through the robot, and the filter
// held the carrier against it for 30 cycles before passing it.)
TEST(PushPath, APushPlannedAgainGoesRoundTheRobotsStandingAsTheFirstPlanDid) {
  const Eigen::Vector2d goal(0.8, 0.4);
  const PlannedAgain r = pushPlannedAgain({0.38, 0.43}, {0.3, 0.37}, {0.3, 0.4}, goal, {0.3, 0.5});
  expectPushedPastTheStander(r, goal);
}

// As above, the robot standing behind the box where its push planned again would take its
// run-up: the push planned again leads the box out from beside that robot first, as a first
// plan does (exec::withRunUp), and the box ends on its goal. (Along the rest of the old route
// the carrier was held against the robot for 54 cycles and its motion ended with the box 48
// cm short of its goal.)
TEST(PushPath, APushPlannedAgainWhoseRunUpARobotStandsInLeadsTheBoxOutFirst) {
  const Eigen::Vector2d goal(0.8, 0.4);
  const PlannedAgain r = pushPlannedAgain({0.38, 0.34}, {0.3, 0.34}, {0.3, 0.4}, goal, {0.22, 0.38});
  expectPushedPastTheStander(r, goal);
}

// Task 3's step 3 with the shooter boxed in (test scene 1 of `ddace generate task3`): the
// ball lies west of the shooter at contact, the defender stands north-east of the shooter
// 7.6 mm beyond contact and the screen north of the ball. The push heads the ball east, so
// the run-up lies west of the ball, and every way round the ball starts through the
// defender's margin: the filter lets the shooter neither drive on nor turn. The shooter
// pushes the ball out west first, straight on from where it stands, then goes round it and
// pushes it on: the ball reaches the hoop and nobody touches the defender or the screen.
// (Planned round the ball from where it stood, north through both robots, the shooter was
// held at once: a deadlock against the defender and the ball.)
TEST(PushPath, ACarrierBoxedInBesideItsLoadPushesItOutFirst) {
  ScreenScene s;
  s.defender = {0.480, 0.253}, s.screen = {0.432, 0.276}, s.hoop = {0.860, 0.791};
  s.ball = {0.420, 0.214}, s.shooter = {0.461, 0.205}, s.shooter_heading = -3.08;
  expectBallPushedOntoTheHoop(s, /*others_stand=*/true);
}
