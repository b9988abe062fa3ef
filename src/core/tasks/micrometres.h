// Positions as a demonstration file holds them, for the generators (generators.cpp,
// motion.cpp): generated rows equal what reading their CSV gives back.
#pragma once

#include <cstdio>
#include <cstdlib>

namespace ddace::tasks::detail {

/// `v` (metres) rounded to six decimals as printf rounds it (the digits a file holds), read back.
inline double micrometres(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6f", v);
  return std::strtod(buf, nullptr);
}

}  // namespace ddace::tasks::detail
