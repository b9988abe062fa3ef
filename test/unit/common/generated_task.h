// A generated task for tests (what `ddace generate` makes): the one copy for every test
// binary of test/unit/.
#pragma once

#include <cstdint>
#include <string>

#include "ddace/tasks/generators.h"

namespace ddace::test {

/// `family` with `demos` demonstrations drawn from `seed`; `robots` is task2's team size
/// (the generator's default when not given; the other families ignore it).
inline task::TaskDir generated(const std::string& family, int demos, uint64_t seed,
                               int robots = tasks::GeneratorOptions{}.robots) {
  tasks::GeneratorOptions o;
  o.family = family;
  o.demos = demos;
  o.seed = seed;
  o.robots = robots;
  return tasks::generate(o);
}

}  // namespace ddace::test
