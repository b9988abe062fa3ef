#include "ddace/common/angle.h"

#include <cmath>

#include <gtest/gtest.h>

using ddace::wrapAngle;

TEST(WrapAngle, RangeIsMinusPiExclusiveToPiInclusive) {
  EXPECT_DOUBLE_EQ(wrapAngle(M_PI), M_PI);
  EXPECT_DOUBLE_EQ(wrapAngle(-M_PI), M_PI);
  EXPECT_NEAR(wrapAngle(3 * M_PI / 2), -M_PI / 2, 1e-12);
  EXPECT_NEAR(wrapAngle(-3 * M_PI / 2), M_PI / 2, 1e-12);
  EXPECT_NEAR(wrapAngle(-7.0), -7.0 + 2 * M_PI, 1e-12);
}

TEST(WrapAngle, KeepsAnglesInsideTheRangeAndRemovesWholeTurns) {
  for (double a : {0.0, 0.5, -0.5, 3.0, -3.0}) {
    EXPECT_DOUBLE_EQ(wrapAngle(a), a);
    EXPECT_NEAR(wrapAngle(a + 6 * M_PI), a, 1e-12);
    EXPECT_NEAR(wrapAngle(a - 4 * M_PI), a, 1e-12);
  }
}
