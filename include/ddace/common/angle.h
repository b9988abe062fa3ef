// Planar angles (radians).
#pragma once

#include <cmath>

namespace ddace {

/// `a` (radians, any finite value) wrapped into (-pi, pi]: the same heading, the
/// representation every pose in ddace uses (pi, not -pi, for the half turn).
inline double wrapAngle(double a) {
  a = std::fmod(a + M_PI, 2 * M_PI);
  if (a <= 0) a += 2 * M_PI;
  return a - M_PI;
}

}  // namespace ddace
