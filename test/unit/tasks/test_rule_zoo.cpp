// The rule zoo: hundreds of distinct rules, valid task directories, determinism, and the
// rules' decisions checked against the scenes (nearest, axis order, carrier with its load).
#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <set>

#include "ddace/tasks/generators.h"
#include "ddace/tasks/rule_zoo.h"

using namespace ddace;

namespace {

/// The first rule (by id) whose name contains every one of `words`.
uint64_t findRule(const std::vector<std::string>& words) {
  for (uint64_t id : tasks::distinctZooRules(400)) {
    const std::string name = tasks::zooRule(id).name;
    bool all = true;
    for (const auto& w : words) all = all && name.find(w) != std::string::npos;
    if (all) return id;
  }
  ADD_FAILURE() << "no zoo rule among the first 400 says all of the words";
  return 0;
}

}  // namespace

TEST(RuleZoo, HundredsOfDistinctRulesOfEveryKind) {
  const std::vector<uint64_t> ids = tasks::distinctZooRules(300);
  ASSERT_EQ(ids.size(), 300u);
  EXPECT_LT(ids.back(), 1500u) << "distinct rules are rare among the ids";
  std::set<std::string> kinds;
  for (uint64_t id : ids) {
    const tasks::ZooRule r = tasks::zooRule(id);
    kinds.insert(r.kind);
    EXPECT_GE(r.robots, 2);
    EXPECT_LE(r.robots, 6);
    EXPECT_LE(r.robots + r.objects + r.goals, 10) << r.name;
  }
  EXPECT_EQ(kinds, (std::set<std::string>{"assign", "sequence", "queue", "fetch", "relay", "boxes", "gather"}));
}

TEST(RuleZoo, ValidDeterministicTaskDirectories) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "ddace_test_rule_zoo";
  for (uint64_t id : tasks::distinctZooRules(20)) {
    const task::TaskDir a = tasks::generateZoo(id, 3, 5);
    const task::TaskDir b = tasks::generateZoo(id, 3, 5);
    ASSERT_EQ(a.demos.size(), 3u);
    for (size_t i = 0; i < a.demos.size(); ++i) {
      EXPECT_EQ(a.demos[i].positions, b.demos[i].positions) << a.spec.name;
      const size_t steps = a.demos[i].steps.size();
      EXPECT_GE(steps, 1u) << a.spec.name;
      EXPECT_LE(steps, 4u) << a.spec.name;
    }
    // Written and read back as ddace-task/1, with the same steps.
    std::filesystem::remove_all(dir);
    task::writeTaskDir(a, dir.string());
    const task::TaskDir back = task::loadTaskDir(dir.string());
    ASSERT_EQ(back.demos.size(), a.demos.size());
    for (size_t i = 0; i < a.demos.size(); ++i) EXPECT_TRUE(task::sameSteps(back.demos[i].steps, a.demos[i].steps));
  }
  std::filesystem::remove_all(dir);
  EXPECT_THROW(tasks::generateZoo(1, -1, 1), Error);
  uint64_t id = 0;
  EXPECT_FALSE(tasks::parseZooFamily("fetch", id));
  EXPECT_TRUE(tasks::parseZooFamily("zoo:17", id));
  EXPECT_EQ(id, 17u);
  EXPECT_THROW(tasks::parseZooFamily("zoo:x", id), Error);
  EXPECT_THROW(tasks::parseZooFamily("zoo:", id), Error);
}

TEST(RuleZoo, DecisionsFollowTheStatedRule) {
  // "the robot farthest from B1 fetches B1": the first step's robot is the farthest.
  const uint64_t fetch = findRule({"fetch: the robot farthest from B1"});
  const int robots = tasks::zooRule(fetch).robots;
  for (const auto& d : tasks::generateZoo(fetch, 5, 3).demos) {
    const auto& p = d.snapshots[0].positions;
    const task::Token first = d.steps[0].tokens[0];
    const int box = first.target;
    ASSERT_EQ(box, robots);  // B1 follows the robots
    for (int r = 0; r < robots; ++r) {
      if (r != first.entity) {
        EXPECT_GT((p[first.entity] - p[box]).norm(), (p[r] - p[box]).norm() + tasks::kSceneDecisionMargin - 1e-9);
      }
    }
    // The carrier and its load: the same target in the same step.
    const auto& carry = d.steps[1].tokens;
    ASSERT_EQ(carry.size(), 2u);
    EXPECT_EQ(carry[0].target, carry[1].target);
  }
  // "robots take goals in left-to-right order": the k-th robot from the left takes the
  // k-th goal from the left.
  const uint64_t order = findRule({"assign: robots take goals in left-to-right order"});
  const tasks::ZooRule rule = tasks::zooRule(order);
  for (const auto& d : tasks::generateZoo(order, 5, 3).demos) {
    const auto& p = d.snapshots[0].positions;
    ASSERT_EQ(d.steps.size(), 1u);
    ASSERT_EQ(d.steps[0].tokens.size(), static_cast<size_t>(rule.robots));
    for (const auto& s : d.steps[0].tokens) {
      for (const auto& t : d.steps[0].tokens) {
        if (p[s.entity].x() < p[t.entity].x()) {
          EXPECT_LT(p[s.target].x(), p[t.target].x());
        }
      }
    }
  }
}

TEST(RuleZoo, NamedRulesStateTheKindsUsersName) {
  // Every kind names a rule `ddace generate` takes, and the rule generates.
  for (const tasks::ZooKind& k : tasks::userKinds()) {
    uint64_t id = 0;
    ASSERT_TRUE(tasks::parseZooFamily(k.family, id)) << k.family;
    EXPECT_EQ(tasks::zooRule(id).family, k.family);
    EXPECT_EQ(tasks::generateZoo(id, 1, 2).demos.size(), 1u) << k.family;
  }
  // The drawn rules chosen for a kind state it (an id chosen once by its words: a change of
  // the grammar's draw must not leave a kind measured on another rule).
  const std::pair<const char*, const char*> drawn[] = {
      {"zoo:140", "the robot farthest from B1 fetches B1 and carries it to"},
      {"zoo:87", "the robot nearest to B1 fetches B1 and hands it to the teammate nearest to it, who carries it to"},
      {"zoo:21", "robots take the slots Q1..Q3 one per step, the nearest to Q1 first"}};
  for (const auto& [family, words] : drawn) {
    uint64_t drawn_id = 0;
    ASSERT_TRUE(tasks::parseZooFamily(family, drawn_id));
    const tasks::ZooRule rule = tasks::zooRule(drawn_id);
    EXPECT_NE(rule.name.find(words), std::string::npos) << family << ": " << rule.name;
    EXPECT_GE(rule.robots, 3) << family;
  }
  uint64_t id = 0;
  ASSERT_TRUE(tasks::parseZooFamily("zoo:nearest-goals", id));
  const tasks::ZooRule nearest = tasks::zooRule(id);
  EXPECT_EQ(nearest.robots, 6);
  EXPECT_EQ(nearest.goals, 7);
  try {
    tasks::parseZooFamily("zoo:farthest-goals", id);
    ADD_FAILURE() << "an unknown named rule was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("zoo:two-boxes"), std::string::npos) << e.what();
  }
  // Drawn rules keep their ids and names: the zoo's sample is the same.
  EXPECT_EQ(tasks::zooRule(4).family, "zoo:4");
  EXPECT_EQ(tasks::generateZoo(4, 1, 1).spec.name.rfind("zoo 4 boxes: ", 0), 0u);
  // "then the box nearer G1 goes to it, the other to G2".
  ASSERT_TRUE(tasks::parseZooFamily("zoo:two-boxes", id));
  const tasks::ZooRule boxes = tasks::zooRule(id);
  const int b1 = boxes.robots, g1 = boxes.robots + boxes.objects;
  for (const auto& d : tasks::generateZoo(id, 5, 3).demos) {
    ASSERT_EQ(d.steps.size(), 2u);
    const auto& p = d.snapshots[1].positions;  // as the second step begins
    const int nearer = (p[b1] - p[g1]).norm() < (p[b1 + 1] - p[g1]).norm() ? b1 : b1 + 1;
    int to_g1 = -1;
    for (const auto& t : d.steps[1].tokens)
      if (t.entity == b1 || t.entity == b1 + 1) {
        if (t.target == g1) to_g1 = t.entity;
        EXPECT_TRUE(t.target == g1 || t.target == g1 + 1);
      }
    EXPECT_EQ(to_g1, nearer);
  }
}

TEST(RuleZoo, OsrDistributionIsLinearBetweenOrderStatistics) {
  const tasks::OsrDistribution d = tasks::osrDistribution({1.0, 0.0, 0.5, 1.0, 1.0, 0.9, 1.0, 1.0, 0.8, 1.0, 1.0});
  EXPECT_EQ(d.rules, 11u);
  EXPECT_DOUBLE_EQ(d.median, 1.0);
  EXPECT_DOUBLE_EQ(d.p10, 0.5);  // the 2nd of 11 sorted: 0.0, 0.5, ...
  EXPECT_NEAR(d.mean, 9.2 / 11, 1e-12);
  EXPECT_EQ(d.at_least_0_9, 8u);
  EXPECT_DOUBLE_EQ(tasks::osrDistribution({0.0, 1.0}).p10, 0.1);
  EXPECT_THROW(tasks::osrDistribution({}), Error);
}
