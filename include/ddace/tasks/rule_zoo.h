// The rule zoo: tasks drawn from a grammar of the rules people state about a table, the
// benchmark of what the sequence model can learn (bench/rule_zoo.cpp, docs/tgn.md).
//
// A rule is a template with referring expressions in its slots. A referring expression
// picks one entity of a kind:
//   - by distance to a reference entity: the nearest, the farthest, the 2nd nearest, the
//     2nd farthest (the reference is an entity of the task or an entity an earlier step
//     chose: "its nearest teammate", "the goal nearest to the one who received the box");
//   - by order along the table's axes: leftmost / rightmost (x, table frame), frontmost /
//     backmost (y; the front is the edge y = 0), and the 2nd of each;
// and a matching assigns several at once ("each robot to its nearest free goal", matched
// greedily by increasing distance; "robots take goals in left-to-right order"). Entities
// already chosen are no longer free. The templates (ZooRule::kind):
//   assign     one step: every robot to a goal of its own (greedy nearest / farthest
//              free goal, or in order along an axis)
//   sequence   one robot per step in order along an axis, each to its nearest / farthest
//              free goal
//   queue      slot goals Q1..Qn: one robot per step takes the next slot, the robots in
//              order of distance to Q1 or along an axis
//   fetch      a robot chosen relative to the box B1 fetches it and carries it to a goal
//              chosen relative to B1 (optionally: then the others go to the carrier)
//   relay      the fetcher hands B1 to a teammate chosen relative to itself, who
//              carries it to a goal chosen relative to it (optionally: the giver follows)
//   boxes      two or three boxes, each fetched by a free robot (matching), then each
//              carried to a goal of its own (matching)
//   gather     the others meet at a robot chosen relative to G1, which then goes to a
//              goal chosen relative to itself
// 2-6 robots, 0-3 boxes, 1-6 goals (at most 10 entities), 1-4 steps. Motions come in two
// models (ZooMotion), so that a rule of execution is measured on more than one way of
// moving: the generators' (tasks::simulateSteps, generators.h): straight unless bodies are
// in the way, the path then bent around them, ending at contact with a robot or a box and
// on a goal; and direct: each path straight or an arc drawn per motion, bent around
// nothing, stopping a set gap short of contact with a robot or a box (touching, 4 mm, 1 cm:
// people stop where they like), a scene in which a body would pass through another drawn
// again. In the generators' a carried box swings to the front of its carrier (same target,
// same step) and rides there; in direct it moves only as pushed: its carrier goes round it
// to the side it pushes from, and the box never moves further than its pusher; later steps are decided where the
// earlier ones ended (task::stepEndPositions). Start configurations are uniform over the table with the generators'
// border and separation; one in which any decision is a near tie (the chosen and a competing entity's distance, or
// coordinate, closer than kSceneDecisionMargin) is drawn again. The same rule id, seed and count give byte-identical
// output.
#pragma once

#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "ddace/eval/metrics.h"
#include "ddace/task/task_dir.h"

namespace ddace::tasks {

struct ZooRule {
  uint64_t id = 0;
  std::string kind;    ///< the template: assign, sequence, queue, fetch, relay, boxes, gather
  std::string name;    ///< the rule in words, with its entity counts (also the task's name)
  std::string family;  ///< as `ddace generate` takes it: "zoo:<id>", or "zoo:<key>" for a named rule
  int robots = 0, objects = 0, goals = 0;
};

/// How the demonstrations of a rule move (see the header comment).
struct ZooMotion {
  /// false: the generators' motion; true: paths straight or arcs, bent around nothing.
  bool direct = false;
  /// direct only: where a motion toward a robot or a box stops, metres short of contact
  /// (whole millimetres, at most kMaxZooStopGapM).
  double stop_gap_m = 0;
  /// The family suffix: "" (the generators'), "/direct", "/direct-4mm".
  std::string suffix() const;
  /// In words, for a task's name and the benchmark's tables.
  std::string words() const;
};
inline constexpr double kMaxZooStopGapM = 0.02;
/// The direct motions the benchmarks cycle through over a sample of rules: touching, 4 mm
/// and 1 cm short.
std::vector<ZooMotion> directZooMotions();

/// Ids from here on are the named rules' (namedZooRules), in their order; the drawn rules
/// are the ids below (`zoo:<id>` takes at most 18 digits).
inline constexpr uint64_t kNamedZooRuleIds = uint64_t{1} << 62;

/// The rule with this id (any id below kNamedZooRuleIds is a drawn rule; different ids may
/// state the same rule). Throws ddace::Error for an id past the named rules.
ZooRule zooRule(uint64_t id);
/// Named rules: fixed rules of the grammar that the drawn ones do not state, for the kinds
/// of task users name (docs/tgn.md, "Kinds of task"): zoo:nearest-goals (each of 6 robots
/// to its nearest free goal of 7, all at once: more entities than a drawn rule has),
/// zoo:left-to-right (3 robots take 3 goals in left-to-right order), zoo:two-boxes (2
/// boxes, each fetched by its nearest free robot of 3; then the goals in turn, G1 first,
/// each take the free box nearest to them), zoo:two-pairs (the same with 2 robots: two
/// carrier-load pairs carry at once).
std::vector<ZooRule> namedZooRules();

/// The kinds of task users name (docs/tgn.md, "Kinds of task"), each with the zoo rule
/// that states it: the named rules above, and drawn rules (the first id stating the kind
/// with at least 3 robots).
struct ZooKind {
  std::string kind;    ///< in words
  std::string family;  ///< "zoo:<id>" or "zoo:<key>"
};
std::vector<ZooKind> userKinds();

/// The distribution of OSR over a sample of rules, as `ddace bench rule_zoo` and `ddace
/// table` report it.
struct OsrDistribution {
  size_t rules = 0;
  double median = 0, p10 = 0, mean = 0;  ///< quantiles linear between order statistics
  size_t at_least_0_9 = 0;               ///< rules with OSR >= 0.9
};
/// Throws ddace::Error when `osr` is empty.
OsrDistribution osrDistribution(const std::vector<double>& osr);
/// Execution with bodies beside ideal over a sample of rules (one motion model), as `ddace
/// bench rule_zoo` and `ddace table` report it. Ratios are per rule, bodies over ideal: OSR
/// over the rules with an ideal OSR above 0, FD over those with both FDs finite and the
/// ideal above 0 (NaN when none).
struct BodiesComparison {
  size_t rules = 0;
  double ideal_osr_median = NAN, bodies_osr_median = NAN;
  double osr_ratio_median = NAN, osr_ratio_p10 = NAN, fd_ratio_median = NAN;
  int collisions = 0, trials_with_collision = 0, trials = 0;
  double min_clearance_m = NAN;  ///< the smallest over the rules (NaN: none measured)
  double makespan_s = NAN;       ///< mean over the rules
  /// The goals: OSR ratio >= 0.95 at the median and >= 0.9 at the 10th percentile, zero
  /// collisions, FD ratio <= 2 at the median.
  bool goalsMet() const;
};
inline constexpr double kBodiesOsrRatioMedian = 0.95, kBodiesOsrRatioP10 = 0.9, kBodiesFdRatioMedian = 2.0;
/// `runs`: per rule, its ideal and its bodies summary. Throws ddace::Error when empty.
BodiesComparison compareBodies(const std::vector<std::pair<eval::Summary, eval::Summary>>& runs);

/// The ids of the first `count` rules with distinct names, in increasing id order.
std::vector<uint64_t> distinctZooRules(int count);
/// `demos` demonstrations of rule `rule_id` over start configurations drawn from `seed`,
/// moving as `motion` says. Throws ddace::Error when no unambiguous configuration is found
/// (direct: none whose bodies keep clear, as for a robot boxed in by those that met at it
/// and then leaving: such a rule cannot be demonstrated without bending around bodies).
/// `counts`: the same rule with other numbers of entities (docs/tgn.md, "Other team
/// sizes"), the rule's own where 0. The task's name is the rule in words, not its counts,
/// so a model of the rule meets it as the same task.
struct ZooCounts {
  int robots = 0, objects = 0, goals = 0;
};
task::TaskDir generateZoo(uint64_t rule_id, int demos, uint64_t seed, const ZooMotion& motion = {},
                          const ZooCounts& counts = {});
/// Why zooSteps states no steps.
enum class ZooNoAnswer : uint8_t {
  NearTie,         ///< a decision there is a near tie (kSceneDecisionMargin): no one answer
  TooFewEntities,  ///< a choice needs more robots than the team left (a relay's receiver, a box's fetcher)
};
/// The steps rule `rule_id` decides on `scene` (index = `spec`'s entities, a zoo task's
/// in any counts) taken as its start, later steps decided where the earlier ones end as
/// `motion` ends them, for the team without the robots `without` (lost for good: the rule
/// chooses among the others; their bodies stay in `scene`); nothing when the rule states
/// no one answer there (`why`, when given, says why). What a run is judged by where a hand
/// changed the scene under its first step, or a robot was lost. Throws ddace::Error when
/// `scene` does not fit `spec` or `without` names an entity that is not a robot.
std::optional<std::vector<task::Step>> zooSteps(uint64_t rule_id, const task::TaskSpec& spec,
                                                const std::vector<Eigen::Vector2d>& scene, const ZooMotion& motion = {},
                                                const std::vector<int>& without = {}, ZooNoAnswer* why = nullptr);
/// The zoo rule and motion a task states when generateZoo made it (its name says which),
/// or false.
bool zooRuleOfTask(const task::TaskSpec& spec, uint64_t& id, ZooMotion& motion);
/// Parses "zoo:<id>" or "zoo:<key>" of a named rule (as `ddace generate` takes it), with an
/// optional motion suffix "/direct" or "/direct-<N>mm" (N whole millimetres, 0..20), into
/// the rule's id and `motion`; false for any other family name. Throws ddace::Error naming
/// the text when it is neither, or when it has a suffix and `motion` is null (the caller
/// takes the generators' motion only).
bool parseZooFamily(const std::string& family, uint64_t& id, ZooMotion* motion = nullptr);

}  // namespace ddace::tasks
