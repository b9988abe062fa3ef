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
// 2-6 robots, 0-3 boxes, 1-6 goals (at most 10 entities), 1-4 steps. Motions are the
// generators' (tasks::simulateSteps, generators.h): straight unless bodies are in the way,
// ending at contact with a robot or a box and on a goal, a carried box in front of its
// carrier (same target, same step); later steps are decided where the earlier ones ended
// (task::stepEndPositions). Start configurations are uniform over the table with the
// generators' border and separation; one in which any decision is a near tie (the chosen
// and a competing entity's distance, or coordinate, closer than kSceneDecisionMargin) is
// drawn again. The same rule id, seed and count give byte-identical output.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "ddace/task/task_dir.h"

namespace ddace::tasks {

struct ZooRule {
  uint64_t id = 0;
  std::string kind;    ///< the template: assign, sequence, queue, fetch, relay, boxes, gather
  std::string name;    ///< the rule in words, with its entity counts (also the task's name)
  std::string family;  ///< as `ddace generate` takes it: "zoo:<id>", or "zoo:<key>" for a named rule
  int robots = 0, objects = 0, goals = 0;
};

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
/// The ids of the first `count` rules with distinct names, in increasing id order.
std::vector<uint64_t> distinctZooRules(int count);
/// `demos` demonstrations of rule `rule_id` over start configurations drawn from `seed`.
/// Throws ddace::Error when no unambiguous configuration is found.
task::TaskDir generateZoo(uint64_t rule_id, int demos, uint64_t seed);
/// The same rule with other numbers of entities (docs/tgn.md, "Other team sizes"): `robots`,
/// `objects` and `goals` of them (the rule's own where 0). The task's name is the rule's
/// (the rule in words; the counts are the entities'), so a model of the rule meets it as the
/// same task. Throws ddace::Error when no unambiguous configuration is found.
task::TaskDir generateZoo(uint64_t rule_id, int demos, uint64_t seed, int robots, int objects, int goals);
/// Parses "zoo:<id>" or "zoo:<key>" of a named rule (as `ddace generate` takes it) into
/// the rule's id; false for any other family name. Throws ddace::Error naming the text when
/// it is neither.
bool parseZooFamily(const std::string& family, uint64_t& id);

}  // namespace ddace::tasks
