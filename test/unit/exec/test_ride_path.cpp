// A carrier whose load rides drives the path it was shown where that path passes the bodies
// standing in the step, and pushes round them (push_path.h) where it does not.
#include <gtest/gtest.h>

#include <cmath>

#include "ddace/eval/frechet.h"
#include "ddace/exec/bodies_execution.h"
#include "ddace/exec/replay.h"
#include "ddace/exec/ride_path.h"
#include "ddace/tasks/generators.h"

using namespace ddace;
using namespace ddace::exec;
using Eigen::Vector2d;

namespace {

constexpr double kRide = 0.042;  // a Hamster and a box touching
constexpr double kReach = kRide + kPushPassM;

std::vector<Vector2d> line(Vector2d a, Vector2d b, int n = 40) {
  std::vector<Vector2d> p;
  for (int i = 0; i < n; ++i) p.push_back(a + (b - a) * i / (n - 1.0));
  return p;
}

/// The mean normalised Fréchet distance of the carriers' carry motions (a robot whose load
/// moves with it in the step) from the demonstrated segments, over the fetch family's
/// demonstrations replayed with bodies.
double carrierFd(bool loads_ride) {
  tasks::GeneratorOptions o;
  o.family = "fetch";
  o.demos = 6;
  o.seed = 3;
  const task::TaskDir dir = tasks::generate(o);
  const task::EndPointModel ends = task::learnEndPoints(dir.spec, dir.demos);
  const DemonstrationPaths paths(dir.spec, dir.demos);
  const auto gen = [&](const task::Token& t, const Vector2d& a, const Vector2d& b) {
    return paths.generate(t, a, b).points;
  };
  double sum = 0;
  int n = 0;
  for (const task::Demonstration& demo : dir.demos) {
    BodiesExecutionParams p;
    p.noise_m = 0.001;
    p.config.table.loads_ride = loads_ride;
    BodiesExecution with(p);
    const auto policy = [&](const std::vector<task::Snapshot>& h) { return replayDecision(demo, h); };
    const Trial trial = runTrial(dir.spec, demo, policy, gen, with, ends);
    EXPECT_TRUE(trial.failures.empty()) << trial.failures.front();
    for (const ExecutedToken& ex : trial.executed) {
      const task::Step& step = trial.predicted[static_cast<size_t>(ex.step)];
      for (size_t i = 0; i < step.tokens.size(); ++i) {
        if (!(step.tokens[i] == ex.token) || task::carriedLoad(dir.spec, step.tokens, i) < 0) continue;
        if (dir.spec.entities[ex.token.entity].kind != task::EntityKind::Robot) continue;
        for (const task::Segment& seg : demo.segments)
          if (seg.token == ex.token) {
            sum += eval::normalisedFrechet(ex.executed, demo.segmentPath(seg));
            ++n;
          }
      }
    }
  }
  EXPECT_GT(n, 0);
  return n ? sum / n : 0;
}

}  // namespace

TEST(RidePath, AStraightRideIsClearOfBodiesOffItsWay) {
  const auto path = line({0, 0}, {0.4, 0});
  EXPECT_TRUE(rideIsClear(path, {kRide, 0}, kRide, {{{0.2, 0.15}, kReach}}));
}

TEST(RidePath, ABodyBesideTheWayMakesTheCarrierPush) {
  const auto path = line({0, 0}, {0.4, 0});
  EXPECT_FALSE(rideIsClear(path, {kRide, 0}, kRide, {{{0.2, 0.05}, kReach}}));
}

TEST(RidePath, ALoadSwingingRoundIntoABodyIsNotClear) {
  // The carrier faces its load at +x and drives off at 120 degrees: the load swings round
  // its front the shorter way, through 60 degrees, not through -60.
  const double a = 2 * M_PI / 3;
  const auto path = line({0, 0}, {0.4 * std::cos(a), 0.4 * std::sin(a)});
  const Vector2d on_swing = (kRide + 0.02) * Vector2d(std::cos(M_PI / 3), std::sin(M_PI / 3));
  const Vector2d off_swing = (kRide + 0.02) * Vector2d(std::cos(-M_PI / 3), std::sin(-M_PI / 3));
  EXPECT_FALSE(rideIsClear(path, {kRide, 0}, kRide, {{on_swing, kReach}}));
  EXPECT_TRUE(rideIsClear(path, {kRide, 0}, kRide, {{off_swing, 0.03}}));
}

TEST(RidePath, ABodyTheLoadStartsOrEndsBesideIsPassedNoNearer) {
  // A relay: the giver stands touching the load; the receiver drives off sideways with it.
  const Vector2d giver{kRide + 0.046, 0};
  EXPECT_TRUE(rideIsClear(line({0, 0}, {0, -0.4}), {kRide, 0}, kRide, {{giver, kReach}}));
  // Driven back through the giver, it is not.
  EXPECT_FALSE(rideIsClear(line({0, 0}, {0.3, 0}), {kRide, 0}, kRide, {{giver, kReach}}));
  // Handed to a robot: the load ends touching it.
  const Vector2d receiver{0.4 + kRide + 0.046, 0};
  EXPECT_TRUE(rideIsClear(line({0, 0}, {0.4, 0}), {kRide, 0}, kRide, {{receiver, kReach}}));
}

TEST(RidePath, APathOfOnePointIsNotDriven) {
  EXPECT_FALSE(rideIsClear({{0, 0}}, {kRide, 0}, kRide, {}));
}

TEST(RidePath, ARidingLoadsCarrierDrivesTheShownPathAPushingOneGoesRoundItsLoad) {
  // Riding, the carriers drive what the demonstrations show (their carries start facing
  // the load and head off to the goal); pushed, each first goes round its load to behind
  // it, a loop the demonstrations do not have.
  const double riding = carrierFd(true), pushed = carrierFd(false);
  EXPECT_LT(riding, 0.1);
  EXPECT_GT(pushed, 3 * riding);
}
