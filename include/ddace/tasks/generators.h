// Generators of the paper's four task families (DDACE, Sec. V), so every part
// of ddace has demonstrations to learn from without a camera.
//
// Start-goal configurations are drawn per demonstration inside a 1 m x 1 m table
// (table frame, metres, origin at a corner); trajectories are smooth and near
// noise-free, sampled at kGeneratorRateHz. The same options give byte-identical
// output (own RNG arithmetic, no implementation-defined distributions).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "ddace/task/task_dir.h"

namespace ddace::tasks {

inline constexpr double kGeneratorRateHz = 20.0;
inline constexpr double kTableSize = 1.0;  // metres

struct GeneratorOptions {
  std::string family = "task4";  ///< task1 .. task4
  int demos = 30;                ///< number of demonstrations
  uint64_t seed = 1;
  int robots = 11;               ///< task2 only: team size 4..11
  int actions = 4;               ///< task3 only: vocabulary size 2..4
  double jitter_m = 0.0;         ///< std-dev of Gaussian position noise added to every row
  double mislabel_fraction = 0;  ///< fraction of demos with one keyframe's label swapped
};

/// Names of the families: {"task1", "task2", "task3", "task4"}.
std::vector<std::string> families();

/// Generates one task directory (spec + demos, analyzed). Throws ddace::Error
/// for an unknown family or an option out of range, naming the option.
task::TaskDir generate(const GeneratorOptions& options);

}  // namespace ddace::tasks
