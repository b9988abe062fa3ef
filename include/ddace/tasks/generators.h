// Generators of task families, so every part of ddace has demonstrations to learn from
// without a camera: the paper's four (DDACE, Sec. V) and four where the start
// configuration decides who acts (and where).
//
// Everything happens on a 1 m x 1 m table (table frame, metres, origin at a corner);
// trajectories are smooth and near noise-free, sampled at kGeneratorRateHz; the tokens of
// a step start and end together, with idle rows between steps. The same options give
// byte-identical output (own RNG arithmetic, no implementation-defined distributions).
//
// The paper's families (task1..task4) jitter a fixed template layout and always have the
// same steps. The scene-dependent families draw every start configuration uniformly over
// the table (kSceneBorder kept free along the edges, any two entities at least
// kSceneMinSeparation apart) and decide the steps from it; a configuration in which a
// decision is a near tie (nearest and runner-up closer than kSceneDecisionMargin) is drawn
// again, so the rule's answer is never ambiguous:
//
//   fetch         R1, R2, box B1, goal G1. The robot nearest B1 (F) fetches it:
//                 [F:move:B1], then [F:carry:G1 B1:carry:G1], then the other robot
//                 follows the fetcher: [O:move:F].
//   nearest_goal  R1..R3, goals G1..G4. One step: every robot drives to its own nearest
//                 free goal, matched greedily by increasing distance (the closest
//                 robot-goal pair first, then the closest pair of the unmatched robots and
//                 goals, ...; one goal stays free). Every match beats each competing pair
//                 (same robot or same goal) by the margin.
//   queue         R1..R3, slot goals Q1 (head), Q2, Q3 on a straight line,
//                 kQueueSlotSpacing apart. One robot per step in the order of the
//                 distance to Q1: the nearest to Q1, the next to Q2, the farthest to Q3.
//   deliver       R1, R2, box B1, goals G1, G2. The robot nearest B1 fetches it and
//                 carries it to the goal nearest B1: [F:move:B1], then
//                 [F:carry:G B1:carry:G]; the other robot stays.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "ddace/task/task_dir.h"

namespace ddace::tasks {

inline constexpr double kGeneratorRateHz = 20.0;
inline constexpr double kTableSize = 1.0;             // metres
inline constexpr double kSceneBorder = 0.08;          // metres
inline constexpr double kSceneMinSeparation = 0.15;   // metres
inline constexpr double kSceneDecisionMargin = 0.05;  // metres
inline constexpr double kQueueSlotSpacing = 0.16;     // metres

struct GeneratorOptions {
  std::string family = "task4";  ///< one of allFamilies()
  int demos = 30;                ///< number of demonstrations
  uint64_t seed = 1;
  int robots = 11;               ///< task2 only: team size 4..11
  int actions = 4;               ///< task3 only: vocabulary size 2..4
  double jitter_m = 0.0;         ///< std-dev of Gaussian position noise added to every row
  double mislabel_fraction = 0;  ///< fraction of demos with one motion token's target wrong
  /// Human-timed labels: each token's label begins late by a delay drawn uniformly in
  /// [0, onset_jitter_s) seconds (whole rows, rounded down), while its motion starts with
  /// the step (the person labels the robots of a step one after the other; the label
  /// lags, the robots do not wait for it). Labels still end with the step. Must be below
  /// the task's step_window_s, so step grouping restores the steps exactly.
  double onset_jitter_s = 0.0;
};

/// {"task1", "task2", "task3", "task4"}: the paper's Table 2 families.
std::vector<std::string> paperFamilies();
/// {"fetch", "nearest_goal", "queue", "deliver"}: the start configuration decides.
std::vector<std::string> sceneFamilies();
/// Every family generate() takes: paperFamilies() then sceneFamilies().
std::vector<std::string> allFamilies();
/// The families `ddace table` runs as the paper's Table 2: paperFamilies() (its rows
/// and overlays are the paper's; the table lists the others once it has rows for them).
std::vector<std::string> families();

/// Generates one task directory (spec + demos, analyzed). Throws ddace::Error
/// for an unknown family or an option out of range, naming the option.
task::TaskDir generate(const GeneratorOptions& options);

}  // namespace ddace::tasks
