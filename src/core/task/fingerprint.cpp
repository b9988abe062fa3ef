#include "ddace/task/fingerprint.h"

#include <algorithm>
#include <filesystem>
#include <set>

#include <yaml-cpp/yaml.h>

#include "ddace/common/error.h"
#include "ddace/common/sha256.h"

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

[[noreturn]] void failAt(const std::string& file, const YAML::Node& node, const std::string& message) {
  const YAML::Mark m = node.Mark();
  throw Error(Diagnostic{file, m.line >= 0 ? m.line + 1 : 0, m.column >= 0 ? m.column + 1 : 0, message});
}

YAML::Node need(const YAML::Node& parent, const std::string& key, const std::string& file) {
  if (!parent.IsMap()) failAt(file, parent, "task_fingerprint must be a map");
  const YAML::Node n = parent[key];
  if (!n) failAt(file, parent, "task_fingerprint: missing key '" + key + "'");
  return n;
}

std::vector<std::string> texts(const YAML::Node& parent, const std::string& key, const std::string& file) {
  const YAML::Node n = need(parent, key, file);
  if (!n.IsSequence()) failAt(file, n, "task_fingerprint: '" + key + "' must be a list");
  std::vector<std::string> out;
  for (const auto& e : n) {
    if (!e.IsScalar() || e.Scalar().empty()) failAt(file, e, "task_fingerprint: '" + key + "' holds a non-text item");
    out.push_back(e.Scalar());
  }
  if (out != sortedUnique(out)) failAt(file, n, "task_fingerprint: '" + key + "' is not sorted and distinct");
  return out;
}

int count(const YAML::Node& n, const std::string& what, const std::string& file) {
  long long v = -1;
  try {
    v = n.as<long long>();
  } catch (const YAML::Exception&) {
    failAt(file, n, "task_fingerprint: " + what + " must be an integer");
  }
  if (v < 0 || v > kMaxFingerprintCount)
    failAt(file, n, "task_fingerprint: " + what + " must be in 0.." + std::to_string(kMaxFingerprintCount));
  return static_cast<int>(v);
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

TaskFingerprint parseFingerprint(const YAML::Node& node, const std::string& file) {
  TaskFingerprint f;
  f.entities = texts(node, "entities", file);
  f.vocabulary = texts(node, "vocabulary", file);
  {
    const YAML::Node declared = need(node, "vocabulary_declared", file);
    try {
      f.vocabulary_declared = declared.as<bool>();
    } catch (const YAML::Exception&) {
      failAt(file, declared, "task_fingerprint: vocabulary_declared must be true or false");
    }
  }
  f.goal_conditions = texts(node, "goal_conditions", file);
  f.token_types = texts(node, "token_types", file);
  const YAML::Node steps = need(node, "step_counts", file);
  if (!steps.IsSequence()) failAt(file, steps, "task_fingerprint: 'step_counts' must be a list");
  for (const auto& s : steps) f.step_counts.push_back(count(s, "a step count", file));
  if (f.step_counts != sortedUnique(f.step_counts))
    failAt(file, steps, "task_fingerprint: 'step_counts' is not sorted and distinct");
  f.demonstrations = count(need(node, "demonstrations", file), "demonstrations", file);
  const YAML::Node digest = need(node, "digest", file);
  if (!digest.IsScalar() || digest.Scalar() != f.digest())
    failAt(file, digest, "task_fingerprint: the digest does not match the fields (the fingerprint was edited)");
  return f;
}

}  // namespace ddace::task
