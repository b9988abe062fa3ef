// Pure pursuit with a progress term, closed-loop against the unicycle model.
#include <gtest/gtest.h>

#include <cmath>

#include "ddace/common/error.h"
#include "ddace/exec/diff_drive.h"
#include "ddace/exec/path_follower.h"

using namespace ddace;
using namespace ddace::exec;
using Eigen::Vector2d;

namespace {

struct FollowRun {
  bool done = false;
  double time_s = 0;
  double max_cross_track_m = 0;
  Pose2D final_pose;
  std::vector<double> progress;
};

/// Closed loop at 50 Hz until done or `limit_s`.
FollowRun follow(const PlannedPath& path, Pose2D start, DiffDriveParams dp = {}, FollowerGains g = {},
                 double limit_s = 30) {
  DiffDriveModel robot(dp, start);
  PathFollower f(g);
  f.setPath(path);
  FollowRun r;
  while (robot.time() < limit_s) {
    const FollowerOutput o = f.compute(robot.measuredPose());
    r.progress.push_back(o.progress);
    r.max_cross_track_m = std::max(r.max_cross_track_m, o.cross_track_m);
    if (o.done) {
      r.done = true;
      break;
    }
    robot.command(o.wheels, robot.time());
    robot.step();
  }
  r.time_s = robot.time();
  r.final_pose = robot.truePose();
  return r;
}

PlannedPath line(Vector2d a, Vector2d b, int n = 50) {
  PlannedPath p;
  for (int i = 0; i <= n; ++i) p.points.push_back(a + (b - a) * i / double(n));
  return p;
}

/// Task 4's spiral-like shape (tasks/generators.cpp) between two points.
PlannedPath spiral(Vector2d a, Vector2d b, double amplitude = 0.25, int n = 200) {
  PlannedPath p;
  const Vector2d ex = b - a, ey(-ex.y(), ex.x());
  for (int i = 0; i <= n; ++i) {
    const double u = i / double(n), r = amplitude * std::sin(M_PI * u), th = 3 * M_PI * u;
    p.points.push_back(a + ex * (u + r * std::sin(th)) + ey * (r * (1 - std::cos(th))));
  }
  return p;
}

}  // namespace

TEST(PathFollower, ProgressOfIsArcLengthFraction) {
  const auto s = progressOf({{0, 0}, {1, 0}, {1, 3}});
  ASSERT_EQ(s.size(), 3u);
  EXPECT_DOUBLE_EQ(s[0], 0.0);
  EXPECT_DOUBLE_EQ(s[1], 0.25);
  EXPECT_DOUBLE_EQ(s[2], 1.0);
  EXPECT_EQ(progressOf({{1, 1}, {1, 1}}), (std::vector<double>{0, 0}));
}

TEST(PathFollower, FollowsAStraightLineAndArrives) {
  const FollowRun r = follow(line({0.1, 0.1}, {0.6, 0.4}), {0.1, 0.1, std::atan2(0.3, 0.5)});
  ASSERT_TRUE(r.done);
  EXPECT_LT((r.final_pose.position() - Vector2d(0.6, 0.4)).norm(), 0.03);
  EXPECT_LT(r.max_cross_track_m, 0.01);
  // ~0.58 m at 0.12 m/s with a slow-down at the end: well under 10 s.
  EXPECT_LT(r.time_s, 10.0);
}

TEST(PathFollower, TurnsOnTheSpotWhenFacingAway) {
  DiffDriveModel robot({}, {0.2, 0.2, M_PI});
  PathFollower f;
  f.setPath(line({0.2, 0.2}, {0.6, 0.2}));
  const FollowerOutput o = f.compute(robot.truePose());
  EXPECT_NEAR(o.wheels.left_mps, -o.wheels.right_mps, 1e-12) << "should turn in place";
  EXPECT_NE(o.wheels.left_mps, 0.0);
  const FollowRun r = follow(line({0.2, 0.2}, {0.6, 0.2}), {0.2, 0.2, M_PI});
  EXPECT_TRUE(r.done);
}

TEST(PathFollower, ProgressNeverDecreasesAndEndsAtOne) {
  const FollowRun r = follow(spiral({0.3, 0.3}, {0.8, 0.6}), {0.3, 0.3, 0});
  ASSERT_TRUE(r.done);
  for (size_t i = 1; i < r.progress.size(); ++i) ASSERT_GE(r.progress[i], r.progress[i - 1]) << "cycle " << i;
  EXPECT_DOUBLE_EQ(r.progress.back(), 1.0);
}

TEST(PathFollower, FollowsTask4SpiralInOrderWithoutShortCuts) {
  // The spiral loops back over itself; a plain nearest-point follower would jump ahead.
  const PlannedPath path = spiral({0.3, 0.3}, {0.8, 0.6});
  DiffDriveParams dp;
  dp.position_noise_m = 0.001;
  dp.latency_s = 0.04;
  const FollowRun r = follow(path, {0.3, 0.3, 0}, dp);
  ASSERT_TRUE(r.done);
  EXPECT_LT(r.max_cross_track_m, 0.03);
  // Following the whole loop takes at least its length at cruise speed.
  PathFollower f;
  f.setPath(path);
  EXPECT_GT(r.time_s, f.lengthM() / f.gains().cruise_speed_mps);
}

TEST(PathFollower, DoneIsNotDeclaredWhenPassingNearTheGoalEarly) {
  // A U-shaped path whose middle passes 2 cm from its end point.
  PlannedPath p;
  for (int i = 0; i <= 40; ++i) p.points.push_back({0.2 + 0.01 * i, 0.2});
  for (int i = 1; i <= 20; ++i) p.points.push_back({0.6, 0.2 + 0.01 * i});
  for (int i = 1; i <= 38; ++i) p.points.push_back({0.6 - 0.01 * i, 0.4});
  p.points.push_back({0.4, 0.22});  // end: 2 cm off the first leg
  PathFollower f;
  f.setPath(p);
  const FollowerOutput o = f.compute({0.4, 0.2, 0});
  EXPECT_FALSE(o.done);
  EXPECT_LT(o.progress, 0.5);
}

TEST(PathFollower, WheelSpeedsRespectTheLimit) {
  FollowerGains g;
  g.max_wheel_speed_mps = 0.13;
  g.cruise_speed_mps = 0.12;
  PathFollower f(g);
  f.setPath(spiral({0.3, 0.3}, {0.5, 0.35}, 0.4));
  DiffDriveModel robot({}, {0.3, 0.3, 0.5});
  for (int i = 0; i < 500; ++i) {
    const auto o = f.compute(robot.truePose());
    ASSERT_LE(std::abs(o.wheels.left_mps), 0.13 + 1e-12);
    ASSERT_LE(std::abs(o.wheels.right_mps), 0.13 + 1e-12);
    robot.command(o.wheels, robot.time());
    robot.step();
  }
}

TEST(PathFollower, DoneGivesZeroWheelsAndStaysDone) {
  PathFollower f;
  f.setPath(line({0.2, 0.2}, {0.21, 0.2}));
  const auto o = f.compute({0.205, 0.2, 0});
  EXPECT_TRUE(o.done);
  EXPECT_TRUE(o.wheels.isZero());
  EXPECT_TRUE(f.compute({0.5, 0.5, 0}).done);
}

TEST(PathFollower, NoPathMeansZeroWheels) {
  PathFollower f;
  EXPECT_TRUE(f.compute({0.2, 0.2, 0}).wheels.isZero());
  f.setPath(line({0.2, 0.2}, {0.6, 0.2}));
  f.clear();
  EXPECT_TRUE(f.compute({0.2, 0.2, 0}).wheels.isZero());
}

TEST(PathFollower, BadPathsAndGainsAreRefused) {
  PathFollower f;
  EXPECT_THROW(f.setPath({}), Error);
  PlannedPath p = line({0, 0}, {1, 1});
  p.points[3].x() = std::nan("");
  try {
    f.setPath(p);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("point 3"), std::string::npos) << e.what();
  }
  FollowerGains g;
  g.cruise_speed_mps = 0.5;
  g.max_wheel_speed_mps = 0.2;
  EXPECT_THROW(PathFollower{g}, Error);
  g = {};
  g.lookahead_m = -1;
  try {
    PathFollower bad(g);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("lookahead_m"), std::string::npos);
  }
}

TEST(PathFollower, ResampleByArcLengthKeepsEndsAndSpacing) {
  PlannedPath p{{{0, 0}, {0.1, 0}, {1, 0}}, {0, 0.1, 1.0}};
  const PlannedPath r = resampleByArcLength(p, 11);
  ASSERT_EQ(r.points.size(), 11u);
  for (int i = 0; i <= 10; ++i) EXPECT_NEAR(r.points[i].x(), 0.1 * i, 1e-12);
  EXPECT_NEAR(r.stddev_m[5], 0.5, 1e-12);
  EXPECT_THROW(resampleByArcLength(p, 1), Error);
  EXPECT_THROW(resampleByArcLength({}, 5), Error);
  EXPECT_EQ(resampleByArcLength({{{0.3, 0.3}}, {}}, 3).points.size(), 3u);
}
