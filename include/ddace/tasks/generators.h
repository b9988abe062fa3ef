// Generators of task families, so every part of ddace has demonstrations to learn from
// without a camera: the paper's four (DDACE, Sec. V) and four where the start
// configuration decides who acts (and where).
//
// Everything happens on a 1 m x 1 m table (table frame, metres, origin at a corner);
// trajectories are smooth and near noise-free, sampled at kGeneratorRateHz; the tokens of
// a step start and end together, with idle rows between steps. Entities have the task's
// bodies (docs/task-format.md, "Bodies", "Generated demonstrations"): a motion toward a
// robot or an object ends at contact with it, onto a goal on it, a carried load rides in
// front of its carrier and ends on the target, and paths are shaped so that bodies do not
// pass through each other (simulateSteps() below). The same options give byte-identical
// output (own RNG arithmetic, no implementation-defined distributions).
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

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ddace/task/demonstration.h"
#include "ddace/task/end_point.h"
#include "ddace/task/task_dir.h"

namespace ddace::tasks {

inline constexpr double kGeneratorRateHz = 20.0;
inline constexpr double kTableSize = 1.0;  // metres
/// The generators' table: its corners (metres).
inline const Eigen::AlignedBox2d kTable{Eigen::Vector2d(0, 0), Eigen::Vector2d(kTableSize, kTableSize)};
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
  /// kMinStepDurationS, so every label begins before its step ends and step grouping
  /// restores the steps exactly.
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

// ---- the motion of a generated demonstration (the generators' and the rule zoo's)

/// The shape of a motion's path in its own frame: x from the start toward the end, y to
/// the left, both in units of the start-to-end distance.
struct PathShape {
  enum Kind { Straight, Arc, SCurve, Spiral } kind = Straight;
  double amplitude = 0;  ///< lateral size, a fraction of the start-to-end distance (+ left)
};

/// One token of a planned step: entity indices of the task.
struct PlannedToken {
  task::Token token;
  PathShape shape;           ///< a motion's path shape (ignored in place)
  int label_delay_rows = 0;  ///< its label begins this many rows after the step's motion (>= 0)
};
using PlannedStep = std::vector<PlannedToken>;

/// The demonstration of `steps` from the start configuration `start` (one position per
/// entity of `spec`, table frame, metres): kIdleRowsBefore idle rows, then per step its
/// rows and kIdleRowsBetween (kIdleRowsAfter after the last) idle rows, at
/// kGeneratorRateHz. The tokens of a step start and end together (their labels begin
/// label_delay_rows late), at kGeneratorSpeed along the longest path of the step and no
/// shorter than kMinStepDurationS, eased in and out (smoothstep). Motions end at
/// task::stepEndPositions() with nothing learned (the footprints' end points) on kTable. A carried load
/// (task::ridingLoad: starting within task::togetherDistance of its carrier) rides in front of its carrier at their
/// contact distance along the carrier's heading (it swings there over the first kLoadSwingFraction of the carry), and
/// the carrier's path ends heading at the load's end; with DemoMotion::push_loads it moves only as it is pushed
/// instead: it stands while its carrier goes round it, about its centre, to the side it is pushed from (where the
/// carrier is, relative to the load, at the end), then moves with the carrier at that offset, never further than its
/// pusher in any row. Each mover of a step, in token order, takes the least changed candidate path (its shape plus an
/// extra arc kAvoidBends, a turned start kAvoidHooks, a lag kAvoidLags, its load swung (gone round) the other way
/// round; ordered by how far the path moves from its shape, then by lag) that keeps its body, and its load's, on
/// the table and no closer than contact to a standing body or to a mover placed before it (no closer
/// than the pair starts or ends, when that is already below contact); of a mirror pair the one with more clearance;
/// with none free, the one with the most clearance. Positions are rounded to whole micrometres (what a CSV holds); the
/// demonstration is analyzed (step grouping). Throws ddace::Error for a token naming an entity outside
/// the task or a start configuration of the wrong size.
///
/// `motion` changes how the person moves: other end points (where motions toward a body
/// stop: touching, a few millimetres short), and with `avoid` false every path keeps its
/// planned shape, bent around nothing; `bodies_clear` (when given) then says whether every
/// body kept clear of the others as the candidates above must (false: one passed through
/// another, and the caller draws the scene again).
struct DemoMotion {
  bool avoid = true;               ///< shape each path around the bodies (above); false: keep the planned shape
  bool push_loads = false;         ///< a carried load moves only as pushed (above); false: it swings to the front
  task::EndPointModel end_points;  ///< where motions end (nothing learned: the footprints' contact)
};
task::Demonstration simulateSteps(const task::TaskSpec& spec, const std::vector<Eigen::Vector2d>& start,
                                  const std::vector<PlannedStep>& steps, const DemoMotion& motion = {},
                                  bool* bodies_clear = nullptr);

inline constexpr double kGeneratorSpeed = 0.15;   ///< m/s, the nominal robot speed
inline constexpr double kMinStepDurationS = 1.0;  ///< s
inline constexpr int kIdleRowsBefore = 4, kIdleRowsBetween = 3, kIdleRowsAfter = 4;
inline constexpr double kLoadSwingFraction = 0.3;
/// Extra arcs tried to keep a path clear, fractions of the start-to-end distance.
inline constexpr double kAvoidBends[] = {0, 0.05, -0.05, 0.1, -0.1, 0.15, -0.15, 0.3, -0.3, 0.45, -0.45, 0.6, -0.6};
/// Lags tried (progress along the path is (time progress)^lag: the mover falls behind and
/// arrives after those placed before it; the path itself is unchanged).
inline constexpr double kAvoidLags[] = {1, 2, 3, 5};
/// Turns of a path's start tried to leave the bodies a mover touches, radians.
inline constexpr double kAvoidHooks[] = {0,        M_PI / 8,  -M_PI / 8,    M_PI / 4,      -M_PI / 4,
                                         M_PI / 2, -M_PI / 2, 3 * M_PI / 4, -3 * M_PI / 4, M_PI};

}  // namespace ddace::tasks
