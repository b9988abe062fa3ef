#include "ddace/task/fingerprint.h"

#include <algorithm>
#include <filesystem>
#include <set>

#include <yaml-cpp/yaml.h>

#include "ddace/common/error.h"
#include "ddace/common/sha256.h"
#include "ddace/common/yaml_checker.h"

namespace ddace::task {

namespace {

template <typename T>
std::vector<T> sortedUnique(std::vector<T> v) {
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}

std::string list(const std::vector<std::string>& v) {
  std::string out = "[";
  for (size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + v[i];
  return out + "]";
}

std::string list(const std::vector<int>& v) {
  std::vector<std::string> s;
  for (int n : v) s.push_back(std::to_string(n));
  return list(s);
}

std::vector<std::string> specEntities(const TaskSpec& spec) {
  std::vector<std::string> out;
  for (const auto& e : spec.entities)
    out.push_back(e.name + ":" + toString(e.kind) + (e.type.empty() ? "" : ":" + e.type));
  return sortedUnique(out);
}

std::vector<std::string> specGoals(const TaskSpec& spec) {
  std::vector<std::string> out;
  for (const auto& g : spec.goal_conditions) out.push_back(g.entity + " at " + g.at);
  return sortedUnique(out);
}

/// The fields of a stored fingerprint through the caller's YamlChecker: each records
/// its diagnostic at its node and says whether the value is usable.
YAML::Node field(YamlChecker& c, const YAML::Node& map, const std::string& key) {
  return c.required(map, key, "task_fingerprint: ");
}

/// A list of non-empty texts, sorted and distinct (as emitFingerprint writes it).
bool texts(YamlChecker& c, const YAML::Node& map, const std::string& key, std::vector<std::string>& out) {
  const YAML::Node n = field(c, map, key);
  if (!n) return false;
  if (!n.IsSequence()) {
    c.error(n, "task_fingerprint: '" + key + "' must be a list");
    return false;
  }
  bool ok = true;
  std::vector<std::string> v;
  for (const auto& e : n) {
    if (!e.IsScalar() || e.Scalar().empty()) {
      c.error(e, "task_fingerprint: '" + key + "' holds a non-text item");
      ok = false;
    } else {
      v.push_back(e.Scalar());
    }
  }
  if (ok && v != sortedUnique(v)) {
    c.error(n, "task_fingerprint: '" + key + "' is not sorted and distinct");
    ok = false;
  }
  if (ok) out = std::move(v);
  return ok;
}

/// A count in 0..kMaxFingerprintCount.
bool count(YamlChecker& c, const YAML::Node& n, const std::string& what, int& out) {
  return n && c.integer(n, "task_fingerprint: " + what, 0, kMaxFingerprintCount, out);
}

}  // namespace

std::string TaskFingerprint::canonicalText() const {
  return "entities: " + list(entities) + "\nvocabulary: " + list(vocabulary) +
         "\nvocabulary_declared: " + (vocabulary_declared ? "true" : "false") +
         "\ngoal_conditions: " + list(goal_conditions) + "\ntoken_types: " + list(token_types) +
         "\nstep_counts: " + list(step_counts) + "\ndemonstrations: " + std::to_string(demonstrations) + "\n";
}

std::string TaskFingerprint::digest() const {
  return sha256Hex(canonicalText());
}

TaskFingerprint fingerprintOf(const TaskSpec& spec) {
  TaskFingerprint f;
  f.entities = specEntities(spec);
  if (spec.actions_declared) f.vocabulary = sortedUnique(spec.actions);
  f.vocabulary_declared = spec.actions_declared;
  f.goal_conditions = specGoals(spec);
  return f;
}

TaskFingerprint fingerprintOf(const TaskDir& dir) {
  TaskFingerprint f = fingerprintOf(dir.spec);
  f.vocabulary = sortedUnique(dir.vocabulary());
  const auto kind = [&](int i) { return std::string(toString(dir.spec.entities.at(static_cast<size_t>(i)).kind)); };
  for (const auto& demo : dir.demos) {
    for (const auto& step : demo.steps)
      for (const auto& t : step.tokens)
        f.token_types.push_back(kind(t.entity) + ":" + t.action + (t.isMotion() ? ":" + kind(t.target) : ""));
    f.step_counts.push_back(static_cast<int>(demo.steps.size()));
  }
  f.token_types = sortedUnique(f.token_types);
  f.step_counts = sortedUnique(f.step_counts);
  f.demonstrations = static_cast<int>(dir.demos.size());
  return f;
}

TaskFingerprint fingerprintOfPath(const std::string& task_path) {
  namespace fs = std::filesystem;
  const fs::path p(task_path);
  if (fs::is_directory(p)) {
    if (fs::is_directory(p / "demos")) return fingerprintOf(loadTaskDir(task_path));
    return fingerprintOf(readTaskYaml((p / "task.yaml").string()));
  }
  return fingerprintOf(readTaskYaml(task_path));
}

std::vector<std::string> fingerprintDifferences(const TaskFingerprint& model, const TaskFingerprint& task) {
  std::vector<std::string> out;
  const auto differ = [&](const std::string& field, const auto& a, const auto& b) {
    if (a != b) out.push_back(field + ": model " + list(a) + ", task " + list(b));
  };
  differ("entities", model.entities, task.entities);
  if (model.vocabulary_declared && task.vocabulary_declared) {
    differ("vocabulary", model.vocabulary, task.vocabulary);
  } else if (!std::includes(model.vocabulary.begin(), model.vocabulary.end(), task.vocabulary.begin(),
                            task.vocabulary.end())) {
    out.push_back("vocabulary: model " + list(model.vocabulary) + ", task " + list(task.vocabulary) +
                  " (actions the model never learned)");
  }
  differ("goal conditions", model.goal_conditions, task.goal_conditions);
  if (model.demonstrations > 0 && task.demonstrations > 0) {
    std::vector<std::string> unseen;
    std::set_difference(task.token_types.begin(), task.token_types.end(), model.token_types.begin(),
                        model.token_types.end(), std::back_inserter(unseen));
    if (!unseen.empty())
      out.push_back("step structure: the task's demonstrations have token types " + list(unseen) +
                    " never demonstrated to the model (model " + list(model.token_types) + ")");
    if (!model.step_counts.empty() && !task.step_counts.empty() &&
        (task.step_counts.front() < model.step_counts.front() || task.step_counts.back() > model.step_counts.back()))
      out.push_back("step structure: steps per demonstration: model " + list(model.step_counts) + ", task " +
                    list(task.step_counts));
  }
  return out;
}

void requireSameTask(const TaskFingerprint& model, const std::string& model_file, const TaskFingerprint& task,
                     const std::string& task_file, const std::string& override_hint) {
  const std::vector<std::string> diffs = fingerprintDifferences(model, task);
  if (diffs.empty()) return;
  std::string message = "the model (" + model_file + ") was trained on another task than " + task_file + ":";
  for (const auto& d : diffs) message += "\n  " + d;
  throw Error(message + "\ntrain a model on this task (ddace train), or " + override_hint +
              " to use it on purpose for another task");
}

void emitFingerprint(YAML::Emitter& y, const TaskFingerprint& f) {
  y << YAML::BeginMap;
  y << YAML::Key << "entities" << YAML::Value << YAML::Flow << f.entities;
  y << YAML::Key << "vocabulary" << YAML::Value << YAML::Flow << f.vocabulary;
  y << YAML::Key << "vocabulary_declared" << YAML::Value << f.vocabulary_declared;
  y << YAML::Key << "goal_conditions" << YAML::Value << YAML::Flow << f.goal_conditions;
  y << YAML::Key << "token_types" << YAML::Value << YAML::Flow << f.token_types;
  y << YAML::Key << "step_counts" << YAML::Value << YAML::Flow << f.step_counts;
  y << YAML::Key << "demonstrations" << YAML::Value << f.demonstrations;
  y << YAML::Key << "digest" << YAML::Value << f.digest();
  y << YAML::EndMap;
}

bool parseFingerprint(YamlChecker& c, const YAML::Node& node, TaskFingerprint& out) {
  if (!c.expectMap(node, "task_fingerprint")) return false;
  c.onlyKeys(node,
             {"entities", "vocabulary", "vocabulary_declared", "goal_conditions", "token_types", "step_counts",
              "demonstrations", "digest"},
             "task_fingerprint");
  TaskFingerprint f;
  bool ok = YamlChecker::allOf({texts(c, node, "entities", f.entities), texts(c, node, "vocabulary", f.vocabulary)});
  if (const YAML::Node declared = field(c, node, "vocabulary_declared"))
    ok &= c.boolean(declared, "task_fingerprint: vocabulary_declared", f.vocabulary_declared);
  else ok = false;
  ok = YamlChecker::allOf(
      {texts(c, node, "goal_conditions", f.goal_conditions), texts(c, node, "token_types", f.token_types), ok});
  if (const YAML::Node steps = field(c, node, "step_counts")) {
    if (!steps.IsSequence()) {
      c.error(steps, "task_fingerprint: 'step_counts' must be a list");
      ok = false;
    } else {
      bool counts_ok = true;
      for (size_t i = 0; i < steps.size(); ++i) {
        int n = 0;
        if (count(c, steps[i], "step_counts[" + std::to_string(i) + "]", n)) f.step_counts.push_back(n);
        else counts_ok = false;
      }
      if (counts_ok && f.step_counts != sortedUnique(f.step_counts)) {
        c.error(steps, "task_fingerprint: 'step_counts' is not sorted and distinct");
        counts_ok = false;
      }
      ok &= counts_ok;
    }
  } else {
    ok = false;
  }
  ok &= count(c, field(c, node, "demonstrations"), "demonstrations", f.demonstrations);
  const YAML::Node digest = field(c, node, "digest");
  if (!digest) return false;
  // Compared only when every field was read: a digest of half the fields says nothing.
  if (!ok) return false;
  if (!digest.IsScalar() || digest.Scalar() != f.digest()) {
    c.error(digest, "task_fingerprint: the digest does not match the fields (the fingerprint was edited)");
    return false;
  }
  out = std::move(f);
  return true;
}

TaskFingerprint parseFingerprint(const YAML::Node& node, const std::string& file) {
  YamlChecker c(file);
  TaskFingerprint f;
  parseFingerprint(c, node, f);
  c.throwIfErrors();
  return f;
}

}  // namespace ddace::task
