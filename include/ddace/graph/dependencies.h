// Which earlier tokens a token waits for, learned from the demonstrations: the
// precedence that asynchronous dispatch keeps (docs/execution.md, "Dispatch").
//
// THE RULE (one owner: this header). A token B of a later step waits for a token A of an
// earlier step when
//   1. they involve a common entity: the entities of a token are its own, its target and
//      the load it carries (task::carriedLoad: an object with the same action and target
//      in its step). B cannot start from where its entities are, nor end where its
//      target is, while A still moves one of them; or
//   2. people showed it waiting for A: in the demonstrations that show anything about the
//      pair (by token keys, "R3:move:G1" after "R2:move:R4"), B was shown waiting at
//      least as often as it started early (and at least once).
//      - B *started early* in a demonstration when its label began while A's still held
//        (B.first_row <= A.last_row): robots moved so that B starts before A has ended,
//        so B does not need A's end.
//      - B was *shown waiting* when it began after A ended, and A ended after everything
//        B waits for by rule 1 had ended (strictly later row; with no such predecessor,
//        any earlier A): B could have started, nothing it involves was moving, and still
//        it held until A had ended.
//      - Otherwise the demonstration shows nothing about the pair: A ended no later than
//        B's own predecessors (the generators' steps end together), so B's wait is
//        explained by them.
// Tokens of one step never wait for each other: they were decided together.
// A model trained before this rule (no `dependencies` in its manifest) has `learned`
// false: every token waits for every earlier one, the step-synchronous execution.
//
// Owns: the precedence between tokens and its evidence. Must not: dispatch anything
// (exec/dispatch.h does) or know about the networks.
#pragma once

#include <string>
#include <vector>

#include "ddace/task/demonstration.h"
#include "ddace/task/task_spec.h"

namespace YAML {
class Emitter;
class Node;
}  // namespace YAML

namespace ddace::graph {

/// The entities `step[i]` involves: its own, its target (a motion) and the load it
/// carries (a robot token with a carried object in `step`), without repeats.
std::vector<int> involvedEntities(const task::TaskSpec& spec, const std::vector<task::Token>& step, size_t i);

/// Whether `later[i]` and `earlier[j]` involve a common entity (rule 1).
bool shareEntities(const task::TaskSpec& spec, const std::vector<task::Token>& later, size_t i,
                   const std::vector<task::Token>& earlier, size_t j);

/// What the demonstrations show about one pair of token keys that share no entity.
struct WaitEvidence {
  std::string token;      ///< the later token's key, "R3:move:G1"
  std::string after;      ///< the earlier token's key, "R2:move:R4"
  int shown_waiting = 0;  ///< demonstrations where it was shown waiting for `after`
  int started_early = 0;  ///< demonstrations where it began before `after` ended
  /// Rule 2: shown waiting at least once and at least as often as it started early.
  bool waits() const { return shown_waiting > 0 && shown_waiting >= started_early; }
};

struct Dependencies {
  /// False for a model trained before the rule: every token waits for every earlier one.
  bool learned = false;
  int demonstrations = 0;
  /// Every pair of keys some demonstration showed something about, sorted by (token, after).
  std::vector<WaitEvidence> evidence;

  /// Whether `later[i]` (a token of a later step) waits for `earlier[j]` (rules 1, 2).
  bool waitsFor(const task::TaskSpec& spec, const std::vector<task::Token>& later, size_t i,
                const std::vector<task::Token>& earlier, size_t j) const;
  /// The evidence about the keys (`token` after `after`), or nullptr.
  const WaitEvidence* find(const std::string& token, const std::string& after) const;
};

/// Learns the rule's evidence from analyzed demonstrations of `spec`.
Dependencies learnDependencies(const task::TaskSpec& spec, const std::vector<task::Demonstration>& demos);

/// The manifest's `dependencies` mapping: demonstrations, then one entry per pair
/// {token, after, shown_waiting, started_early, waits}.
void emitDependencies(YAML::Emitter& out, const Dependencies& deps);
/// Reads what emitDependencies wrote (`learned` true). Throws ddace::Error naming `path`,
/// line and column: an unknown token key, counts out of range, or a `waits` that the counts
/// contradict (an edited manifest).
Dependencies parseDependencies(const YAML::Node& node, const std::string& path, const task::TaskSpec& spec);

}  // namespace ddace::graph
