// Seeded pseudo-random numbers with the same sequence on every platform and standard
// library (std::*_distribution is implementation-defined): generated data, k-means
// seeding, GP restarts and the training order all reproduce bit for bit from a seed.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

namespace ddace {

/// SplitMix64 (Steele, Lea, Flood 2014).
class SplitMix64 {
 public:
  /// `state` is used as given: callers derive it from the user's seed with a constant of
  /// their own, so one seed gives unrelated streams in different places.
  explicit SplitMix64(uint64_t state) : state_(state) {}

  uint64_t next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }
  /// Uniform in [0, 1), 53 random bits.
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  /// Standard normal (Box-Muller, one of the pair).
  double normal() {
    const double u1 = 1.0 - uniform(), u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
  }
  /// Uniform in 0 .. n-1 (n > 0; the modulo bias is negligible for small n).
  size_t index(size_t n) { return static_cast<size_t>(next() % n); }

 private:
  uint64_t state_;
};

}  // namespace ddace
