// The task fingerprint: the same task gives the same fingerprint whatever the scene,
// the demonstrator's timing or the order of task.yaml; another task with the same entity
// names (Task 2 with 4 robots on Task 4) differs, and the message says how.
#include <gtest/gtest.h>

#include <yaml-cpp/yaml.h>

#include <algorithm>

#include "ddace/common/error.h"
#include "ddace/task/fingerprint.h"
#include "ddace/tasks/generators.h"

#include "../common/error_of.h"
#include "../common/generated_task.h"

using namespace ddace;
using ddace::test::diagnosticsOf;
using ddace::test::errorOf;
using ddace::test::generated;

namespace {

std::string joined(const std::vector<std::string>& lines) {
  std::string out;
  for (const auto& l : lines) out += l + "\n";
  return out;
}

}  // namespace

TEST(TaskFingerprint, TheSameTaskMatchesAcrossScenesSeedsAndDemoCounts) {
  for (const std::string& family : tasks::families()) {
    const task::TaskFingerprint train = task::fingerprintOf(generated(family, 20, 1));
    const task::TaskFingerprint test = task::fingerprintOf(generated(family, 5, 99));
    EXPECT_EQ(joined(task::fingerprintDifferences(train, test)), "") << family;
    // task.yaml alone (what a node may be given) matches too.
    EXPECT_EQ(joined(task::fingerprintDifferences(train, task::fingerprintOf(generated(family, 1, 5).spec))), "")
        << family;
  }
}

TEST(TaskFingerprint, RecordsTheStepStructureInKindTerms) {
  const task::TaskFingerprint f = task::fingerprintOf(generated("task4", 3, 1));
  EXPECT_EQ(f.entities, (std::vector<std::string>{"G1:goal", "R1:robot:hamster", "R2:robot:hamster", "R3:robot:hamster",
                                                  "R4:robot:hamster"}));
  EXPECT_EQ(f.vocabulary, (std::vector<std::string>{"move"}));
  EXPECT_EQ(f.goal_conditions, (std::vector<std::string>{"R3 at G1", "R4 at G1"}));
  EXPECT_EQ(f.token_types, (std::vector<std::string>{"robot:move:goal", "robot:move:robot"}));
  EXPECT_EQ(f.step_counts, (std::vector<int>{2}));
  EXPECT_EQ(f.demonstrations, 3);
  EXPECT_EQ(f.digest().size(), 64u);
}

TEST(TaskFingerprint, TheOrderOfTaskYamlChangesNothing) {
  task::TaskDir dir = generated("task3", 2, 1, 0);
  const task::TaskFingerprint before = task::fingerprintOf(dir.spec);
  std::reverse(dir.spec.entities.begin(), dir.spec.entities.end());
  std::reverse(dir.spec.goal_conditions.begin(), dir.spec.goal_conditions.end());
  EXPECT_EQ(task::fingerprintOf(dir.spec).digest(), before.digest());
}

TEST(TaskFingerprint, Task2WithFourRobotsIsNotTask4) {
  // Same entity names (R1..R4, G1), same kinds and types: only the fingerprint tells them apart.
  const task::TaskDir task2 = generated("task2", 4, 1, 4), task4 = generated("task4", 4, 1);
  ASSERT_EQ(task2.spec.entityNames(), task4.spec.entityNames());
  const std::string d = joined(task::fingerprintDifferences(task::fingerprintOf(task2), task::fingerprintOf(task4)));
  EXPECT_NE(d.find("vocabulary: model [move, stop], task [move]"), std::string::npos) << d;
  EXPECT_NE(d.find("goal conditions: model [R4 at G1], task [R3 at G1, R4 at G1]"), std::string::npos) << d;
  EXPECT_NE(d.find("step structure: steps per demonstration: model [3], task [2]"), std::string::npos) << d;
  // From task.yaml alone (a node given no demonstrations) the task.yaml fields still differ.
  EXPECT_NE(joined(task::fingerprintDifferences(task::fingerprintOf(task2), task::fingerprintOf(task4.spec))), "");
  try {
    task::requireSameTask(task::fingerprintOf(task2), "m/manifest.yaml", task::fingerprintOf(task4), "t4/test",
                          "pass --allow-other-task");
    FAIL() << "refused nothing";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("m/manifest.yaml"), std::string::npos) << what;
    EXPECT_NE(what.find("t4/test"), std::string::npos) << what;
    EXPECT_NE(what.find("--allow-other-task"), std::string::npos) << what;
    EXPECT_NE(what.find("vocabulary:"), std::string::npos) << what;
  }
}

TEST(TaskFingerprint, AnUndemonstratedTokenTypeIsAnotherTask) {
  task::TaskFingerprint model = task::fingerprintOf(generated("task4", 2, 1)), task = model;
  task.token_types.push_back("robot:move:zz");
  const std::string d = joined(task::fingerprintDifferences(model, task));
  EXPECT_NE(d.find("step structure: the task's demonstrations have token types [robot:move:zz]"), std::string::npos)
      << d;
}

TEST(TaskFingerprint, RoundTripsThroughYamlAndRefusesEdits) {
  const task::TaskFingerprint f = task::fingerprintOf(generated("task2", 3, 1, 5));
  YAML::Emitter y;
  y << YAML::BeginMap << YAML::Key << "task_fingerprint" << YAML::Value;
  task::emitFingerprint(y, f);
  y << YAML::EndMap;
  const std::string text = y.c_str();
  EXPECT_EQ(task::parseFingerprint(YAML::Load(text)["task_fingerprint"], "f.yaml"), f);
  const auto refusal = [&](const std::string& from, const std::string& to) {
    std::string edited = text;
    const size_t at = edited.find(from);
    if (at == std::string::npos) return std::string("'" + from + "' not in the text");
    edited.replace(at, from.size(), to);
    return errorOf([&] { task::parseFingerprint(YAML::Load(edited)["task_fingerprint"], "f.yaml"); });
  };
  EXPECT_NE(refusal("[move, stop]", "[move, stops]").find("digest does not match"), std::string::npos);
  EXPECT_NE(refusal("demonstrations: 3", "demonstrations: 4").find("f.yaml:"), std::string::npos);
  EXPECT_NE(refusal("demonstrations: 3", "demonstrations: 99999999").find("0..1000000"), std::string::npos);
  EXPECT_NE(refusal("[move, stop]", "[stop, move]").find("not sorted"), std::string::npos);
  EXPECT_NE(refusal("digest:", "dig:").find("missing key 'digest'"), std::string::npos);
}

TEST(TaskFingerprint, AStoredFingerprintReportsEveryProblemAtItsLineAndColumn) {
  // As the readers of the files that hold it do: one pass, every problem, file:line:column.
  const std::string text =
      "task_fingerprint:\n"
      "  entities: [R1:robot, R2:robot]\n"
      "  vocabulary: [move]\n"
      "  vocabulary_declared: perhaps\n"
      "  goal_conditions: []\n"
      "  token_types: robot:move:robot\n"
      "  step_counts: [2, 1.5]\n"
      "  demonstrations: -1\n"
      "  colour: blue\n";
  EXPECT_EQ(diagnosticsOf([&] { task::parseFingerprint(YAML::Load(text)["task_fingerprint"], "m.yaml"); }),
            "m.yaml:9:3: unknown key 'colour' in task_fingerprint (allowed: demonstrations, digest, entities, "
            "goal_conditions, step_counts, token_types, vocabulary, vocabulary_declared)\n"
            "m.yaml:4:24: task_fingerprint: vocabulary_declared: 'perhaps' is not true or false\n"
            "m.yaml:6:16: task_fingerprint: 'token_types' must be a list\n"
            "m.yaml:7:20: task_fingerprint: step_counts[1] must be an integer in 0..1000000 (got 1.5)\n"
            "m.yaml:8:19: task_fingerprint: demonstrations must be an integer in 0..1000000 (got -1)\n"
            "m.yaml:2:3: task_fingerprint: missing key 'digest'\n");
}

TEST(TaskFingerprint, AnUndeclaredVocabularyNeedOnlyBeAmongTheModels) {
  // Without `actions` in task.yaml a test set that never shows `stop` is the same task...
  const task::TaskDir train = generated("task2", 3, 1, 4);
  task::TaskFingerprint model = task::fingerprintOf(train), shown = model;
  model.vocabulary_declared = shown.vocabulary_declared = false;
  shown.vocabulary = {"move"};
  EXPECT_EQ(joined(task::fingerprintDifferences(model, shown)), "");
  // ...but an action the model never learned is not.
  shown.vocabulary = {"dribble", "move"};
  EXPECT_NE(joined(task::fingerprintDifferences(model, shown)).find("actions the model never learned"),
            std::string::npos);
}
