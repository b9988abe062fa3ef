// Per-entity filtering: what a consumer of /ddace/entities relies on.
#include <gtest/gtest.h>

#include <cmath>

#include "ddace/vision/pose_filter.h"

using namespace ddace::vision;

TEST(PoseFilter, StaleUntilFirstSeen) {
  PoseFilter f;
  EXPECT_FALSE(f.everSeen());
  EXPECT_TRUE(f.staleAt(0.0));
  EXPECT_TRUE(f.update({0.1, 0.2, 0.3}, 0.0));
  EXPECT_TRUE(f.visibleAt(0.0));
  EXPECT_FALSE(f.staleAt(0.0));
  EXPECT_DOUBLE_EQ(f.pose().x, 0.1);
}

TEST(PoseFilter, RejectsAJumpFasterThanTheRobotCanMove) {
  FilterConfig c;
  c.max_speed_mps = 0.5;
  c.gate_margin_m = 0.01;
  c.position_gain = 1.0;
  PoseFilter f(c);
  f.update({0.5, 0.5, 0}, 0.0);
  EXPECT_TRUE(f.update({0.51, 0.5, 0}, 1.0 / 30));  // 0.3 m/s: fine
  EXPECT_FALSE(f.update({0.8, 0.5, 0}, 2.0 / 30));  // 9 m/s: a wrong decode or a reflection
  EXPECT_DOUBLE_EQ(f.pose().x, 0.51);
  EXPECT_FALSE(f.visibleAt(2.0 / 30));
  EXPECT_EQ(f.rejected(), 1);
  EXPECT_TRUE(f.update({0.52, 0.5, 0}, 3.0 / 30));
}

TEST(PoseFilter, ReacquiresAfterConsistentOutliers) {
  // Picked up and put down elsewhere: after `reacquire_after` consistent measurements
  // the new place is accepted.
  FilterConfig c;
  c.reacquire_after = 3;
  PoseFilter f(c);
  f.update({0.1, 0.1, 0}, 0.0);
  EXPECT_FALSE(f.update({0.9, 0.9, 0}, 0.1));
  EXPECT_FALSE(f.update({0.9, 0.9, 0}, 0.2));
  EXPECT_TRUE(f.update({0.9, 0.9, 0}, 0.3));
  EXPECT_DOUBLE_EQ(f.pose().x, 0.9);
  // Inconsistent outliers (flicker between two wrong places) never are.
  PoseFilter g(c);
  g.update({0.1, 0.1, 0}, 0.0);
  for (int i = 1; i < 10; ++i) EXPECT_FALSE(g.update({i % 2 ? 0.9 : 0.5, 0.9, 0}, 0.1 * i));
  EXPECT_DOUBLE_EQ(g.pose().x, 0.1);
}

TEST(PoseFilter, HoldsThenGoesStale) {
  FilterConfig c;
  c.hold_s = 1.0;
  PoseFilter f(c);
  f.update({0.3, 0.3, 1.0}, 5.0);
  EXPECT_FALSE(f.visibleAt(5.5));
  EXPECT_FALSE(f.staleAt(5.5));
  EXPECT_FALSE(f.staleAt(6.0));
  EXPECT_TRUE(f.staleAt(6.01));
  EXPECT_DOUBLE_EQ(f.pose().x, 0.3);
  // Seen again after a long gap: the filter takes the new measurement as is.
  EXPECT_TRUE(f.update({0.6, 0.3, 1.0}, 20.0));
  EXPECT_DOUBLE_EQ(f.pose().x, 0.6);
  EXPECT_FALSE(f.staleAt(20.0));
}

TEST(PoseFilter, SmoothsYawAcrossTheWrap) {
  FilterConfig c;
  c.yaw_gain = 0.5;
  PoseFilter f(c);
  f.update({0, 0, M_PI - 0.05}, 0.0);
  f.update({0, 0, -M_PI + 0.05}, 0.033);
  // Halfway between the two across +-pi, not through 0.
  EXPECT_NEAR(std::abs(f.pose().yaw), M_PI, 1e-9);
}

TEST(PoseFilter, AHeldPoseGoesStaleOnceItsSpeedSaysItHasDriftedTooFar) {
  FilterConfig c;
  c.hold_s = 1.0;
  c.max_drift_m = 0.06;
  PoseFilter fast(c), still(c);
  for (int i = 0; i <= 10; ++i) {  // 0.6 m/s along x, and one standing still
    fast.update({0.1 + 0.02 * i, 0.5, 0}, i / 30.0);
    still.update({0.5, 0.5, 0}, i / 30.0);
  }
  EXPECT_NEAR(fast.speed(), 0.6, 1e-6);
  EXPECT_NEAR(still.speed(), 0.0, 1e-9);
  const double last = 10 / 30.0;
  EXPECT_DOUBLE_EQ(fast.driftAt(last), 0.0);
  EXPECT_FALSE(fast.staleAt(last + 0.09));  // 5.4 cm
  EXPECT_TRUE(fast.staleAt(last + 0.11));   // 6.6 cm > max_drift: not a current pose any more
  EXPECT_NEAR(fast.driftAt(last + 0.11), 0.066, 1e-6);
  EXPECT_DOUBLE_EQ(fast.pose().x, 0.3);      // held, never extrapolated
  EXPECT_FALSE(still.staleAt(last + 0.99));  // standing still: the hold decides
  EXPECT_TRUE(still.staleAt(last + 1.01));
  // Seen again: current, and the speed is re-estimated from there.
  EXPECT_TRUE(fast.update({0.36, 0.5, 0}, last + 0.1));
  EXPECT_FALSE(fast.staleAt(last + 0.1));
}
