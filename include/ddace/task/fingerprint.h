// The fingerprint of a task: what a model learned about the task it was trained on, so a
// model of another task is refused even when the entity names agree (docs/tgn.md,
// "The model directory").
//
// Fields (each sorted, so the order of entities in task.yaml or of the demonstrations
// changes nothing):
//   entities         "NAME:KIND" or "NAME:KIND:TYPE" per entity of task.yaml
//   vocabulary       the actions (task.yaml's `actions`, else every action demonstrated);
//                    empty when unknown (a task.yaml without `actions` and no demonstrations)
//   vocabulary_declared  true when task.yaml lists `actions` (else the vocabulary is only
//                    what the demonstrations happen to show)
//   goal_conditions  "ENTITY at TARGET" per goal condition (the tolerance is an evaluation
//                    threshold, not part of what is learned)
//   token_types      the demonstrated step structure in kind terms: every distinct
//                    "ACTORKIND:ACTION:TARGETKIND" (or "ACTORKIND:ACTION" in place) of
//                    the demonstrations' tokens. Kinds, not names: which robot acts
//                    depends on the scene, so it is no part of the task's identity.
//   step_counts      the distinct numbers of steps of the demonstrations (after step
//                    grouping, so robust to human timing)
//   demonstrations   how many demonstrations it was computed from (0: task.yaml alone)
// digest: SHA-256 of canonicalText(), the same fields one per line.
#pragma once

#include <string>
#include <vector>

#include "ddace/task/task_dir.h"

namespace YAML {
class Emitter;
class Node;
}  // namespace YAML

namespace ddace {
class YamlChecker;
}  // namespace ddace

namespace ddace::task {

/// Largest number of steps or of demonstrations a stored fingerprint may claim.
inline constexpr int kMaxFingerprintCount = 1000000;

struct TaskFingerprint {
  std::vector<std::string> entities;
  std::vector<std::string> vocabulary;
  bool vocabulary_declared = false;
  std::vector<std::string> goal_conditions;
  std::vector<std::string> token_types;
  std::vector<int> step_counts;
  int demonstrations = 0;

  /// One "field: a, b, c" line per field, in the order above.
  std::string canonicalText() const;
  /// SHA-256 of canonicalText(), 64 hex digits.
  std::string digest() const;
  bool operator==(const TaskFingerprint& o) const { return canonicalText() == o.canonicalText(); }
};

/// The fingerprint of a task directory (task.yaml and its demonstrations).
TaskFingerprint fingerprintOf(const TaskDir& dir);
/// The fingerprint of task.yaml alone (no step structure; vocabulary only when declared).
TaskFingerprint fingerprintOf(const TaskSpec& spec);

/// The fingerprint of `task_path` as the nodes take it: a task directory (with its
/// demonstrations when it has a demos/ folder) or a task.yaml.
TaskFingerprint fingerprintOfPath(const std::string& task_path);

/// What keeps a model trained on `model` from being used on `task`, one line per field,
/// as "vocabulary: model [move, stop], task [move]"; empty when nothing does. Entities
/// and goal conditions must be equal, the vocabulary too when both task.yaml files declare
/// it (else the task's actions must be among the model's); the step
/// structure is compared only when both sides have demonstrations: the task's token types
/// must all have been demonstrated to the model, and its step counts must lie within the
/// model's range (a test set may show fewer scene variants than the training set).
std::vector<std::string> fingerprintDifferences(const TaskFingerprint& model, const TaskFingerprint& task);

/// The refusal for another task's model (ddace::Error), naming both files and every
/// difference; `override_hint` says how to allow a deliberate transfer (e.g. "pass
/// --allow-other-task"). Returns normally when there is no difference.
void requireSameTask(const TaskFingerprint& model, const std::string& model_file, const TaskFingerprint& task,
                     const std::string& task_file, const std::string& override_hint);

/// Writes the fields and `digest` as a YAML map value (after a key).
void emitFingerprint(YAML::Emitter& out, const TaskFingerprint& fingerprint);
/// Reads a map written by emitFingerprint through `checker` (the reader of the file that
/// holds it), recording every problem at its line and column: a missing, unknown or
/// invalid field, a count out of 0..kMaxFingerprintCount, a list that is not sorted and
/// distinct, or a digest that does not match the fields (an edited fingerprint; compared
/// only when every field is valid). True, and `out` set, when there is none.
bool parseFingerprint(YamlChecker& checker, const YAML::Node& node, TaskFingerprint& out);
/// The same with a checker of its own for `file`: throws ddace::Error with every problem.
TaskFingerprint parseFingerprint(const YAML::Node& node, const std::string& file);

}  // namespace ddace::task
