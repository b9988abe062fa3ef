// The run's clearance measurement: the closest approach, collisions counted once per
// contact, a load placed on its carrier not measured.
#include <gtest/gtest.h>

#include <cmath>

#include "ddace/exec/clearance.h"

using namespace ddace::exec;
using Eigen::Vector2d;

TEST(ClearanceMeter, ClosestApproachAndOneCollisionPerContact) {
  ClearanceMeter m({0.02, 0.02, 0.0});  // two bodies and a goal
  const Vector2d goal(0.05, 0.0);       // flat: never measured, even when driven over
  // R2 comes at R1 from 0.2 m, overlaps by 5 mm twice (apart in between), stops at 1 cm;
  // noise at contact (a 4 mm overlap and 1 mm apart in between) is one contact.
  const std::vector<double> xs = {0.2, 0.1, 0.035, 0.036, 0.041, 0.036, 0.05, 0.035, 0.05, 0.05};
  for (size_t k = 0; k < xs.size(); ++k) m.update(k * 0.1, {{0, 0}, {xs[k], 0}, goal});
  EXPECT_NEAR(m.closest().clearance_m, -0.005, 1e-12);
  EXPECT_EQ(m.closest().a, 0);
  EXPECT_EQ(m.closest().b, 1);
  EXPECT_NEAR(m.closest().time_s, 0.2, 1e-12);
  ASSERT_EQ(m.collisions().size(), 2u);
  EXPECT_NEAR(m.collisions()[0].time_s, 0.2, 1e-12);
  EXPECT_NEAR(m.collisions()[1].time_s, 0.7, 1e-12);
}

TEST(ClearanceMeter, TrackingNoiseAtContactIsNoCollision) {
  ClearanceMeter m({0.02, 0.02}, 0.002);
  m.update(0, {{0, 0}, {0.1, 0}});
  m.update(1, {{0, 0}, {0.039, 0}});  // 1 mm overlap: touching, within the noise
  EXPECT_TRUE(m.collisions().empty());
  EXPECT_NEAR(m.closest().clearance_m, -0.001, 1e-12);
}

TEST(ClearanceMeter, ALoadOnItsCarrierIsNotMeasured) {
  ClearanceMeter m({0.02, 0.02});
  m.update(0, {{0, 0}, {0, 0}});
  m.update(1, {{0.1, 0}, {0.1, 0.001}});
  EXPECT_TRUE(m.collisions().empty());
  EXPECT_EQ(m.loadedPairs().size(), 1u);
  EXPECT_EQ(m.closest().a, -1);
}

TEST(ClearanceMeter, UnknownPositionsWaitUntilSeen) {
  ClearanceMeter m({0.02, 0.02});
  m.update(0, {{0, 0}, Vector2d::Constant(NAN)});
  EXPECT_EQ(m.closest().a, -1);
  m.update(1, {{0, 0}, {0.1, 0}});
  EXPECT_NEAR(m.closest().clearance_m, 0.06, 1e-12);
}
