// Generators of the paper's task families: exact step structure, determinism, validity.
#include <gtest/gtest.h>

#include <filesystem>

#include "ddace/tasks/generators.h"

using namespace ddace;

namespace {

task::TaskDir gen(const std::string& family, int demos = 3, uint64_t seed = 7, int robots = 11,
                  int actions = 4) {
  tasks::GeneratorOptions o;
  o.family = family;
  o.demos = demos;
  o.seed = seed;
  o.robots = robots;
  o.actions = actions;
  return tasks::generate(o);
}

/// The steps of a demonstration as token-key lists.
std::vector<std::vector<std::string>> structure(const task::Demonstration& d, const task::TaskSpec& spec) {
  std::vector<std::vector<std::string>> out;
  for (const auto& s : d.steps) {
    out.emplace_back();
    for (const auto& t : s.tokens) out.back().push_back(task::tokenKey(t, spec));
  }
  return out;
}

using Steps = std::vector<std::vector<std::string>>;

void expectStructure(const task::TaskDir& dir, const Steps& expected) {
  for (const auto& d : dir.demos) {
    EXPECT_EQ(structure(d, dir.spec), expected);
    EXPECT_EQ(d.snapshots.size(), expected.size() + 1);
    EXPECT_TRUE(d.snapshots.back().end);
  }
}

}  // namespace

TEST(Generators, Task1HeterogeneousTransportHasFiveSteps) {
  expectStructure(gen("task1"), Steps{{"R1:drive:D1", "C1:drive:D1"},
                                      {"R1:transfer", "D1:transfer"},
                                      {"R1:stop", "D1:fly:R2", "C1:fly:R2"},
                                      {"R2:transfer", "D1:transfer"},
                                      {"R2:drive:G1", "D1:stop", "C1:drive:G1"}});
}

TEST(Generators, Task2ScalabilityHasTenSteps) {
  expectStructure(gen("task2"), Steps{{"R1:move:R3", "R2:move:R3"},
                                      {"R3:move:R5"},
                                      {"R3:move:R4"},
                                      {"R4:move:R6", "R5:move:R6"},
                                      {"R5:stop"},
                                      {"R4:move:R7"},
                                      {"R6:move:R8", "R7:move:R9"},
                                      {"R8:move:R9"},
                                      {"R9:move:R11", "R10:move:R11"},
                                      {"R11:move:G1"}});
}

TEST(Generators, Task2FewerRobotsTruncatesConsistently) {
  expectStructure(gen("task2", 2, 7, 4), Steps{{"R1:move:R3", "R2:move:R3"}, {"R3:move:R4"}, {"R4:move:G1"}});
  expectStructure(gen("task2", 2, 7, 6),
                  Steps{{"R1:move:R3", "R2:move:R3"}, {"R3:move:R5"}, {"R3:move:R4"},
                        {"R4:move:R6", "R5:move:R6"}, {"R5:stop"}, {"R6:move:G1"}});
  for (int k = 4; k <= 11; ++k) {
    const auto dir = gen("task2", 1, 3, k);
    EXPECT_EQ(dir.spec.entities.size(), static_cast<size_t>(k + 1));
    EXPECT_EQ(task::tokenKey(dir.demos[0].steps.back().tokens.back(), dir.spec), "R" + std::to_string(k) + ":move:G1");
  }
}

TEST(Generators, Task3BallScreenHasFourStepsForEveryVocabulary) {
  expectStructure(gen("task3"), Steps{{"R1:move:R3", "R2:pass", "B1:pass:R3"},
                                      {"R2:move:R1"},
                                      {"R1:stop", "R3:dribble:G1", "B1:dribble:G1"},
                                      {"R3:stop"}});
  const auto three = gen("task3", 2, 7, 11, 3);
  EXPECT_EQ(three.spec.actions, (std::vector<std::string>{"move", "stop", "dribble"}));
  expectStructure(three, Steps{{"R1:move:R3", "R2:stop", "B1:move:R3"},
                               {"R2:move:R1"},
                               {"R1:stop", "R3:dribble:G1", "B1:dribble:G1"},
                               {"R3:stop"}});
  const auto two = gen("task3", 2, 7, 11, 2);
  EXPECT_EQ(two.spec.actions, (std::vector<std::string>{"move", "stop"}));
  expectStructure(two, Steps{{"R1:move:R3", "R2:stop", "B1:move:R3"},
                             {"R2:move:R1"},
                             {"R1:stop", "R3:move:G1", "B1:move:G1"},
                             {"R3:stop"}});
}

TEST(Generators, Task4TrajectoryShapeHasTwoSteps) {
  expectStructure(gen("task4"), Steps{{"R1:move:R3", "R2:move:R4"}, {"R3:move:G1", "R4:move:G1"}});
}

TEST(Generators, SameSeedGivesByteIdenticalOutputAndOtherSeedsDiffer) {
  for (const auto& family : tasks::families()) {
    const auto a = gen(family, 2, 42), b = gen(family, 2, 42), c = gen(family, 2, 43);
    EXPECT_EQ(task::taskYamlText(a.spec), task::taskYamlText(b.spec));
    for (size_t i = 0; i < a.demos.size(); ++i) {
      EXPECT_EQ(task::demonstrationCsvText(a.demos[i], a.spec), task::demonstrationCsvText(b.demos[i], b.spec));
      EXPECT_NE(task::demonstrationCsvText(a.demos[i], a.spec), task::demonstrationCsvText(c.demos[i], c.spec));
    }
  }
}

TEST(Generators, MotionsEndAtTheirGoalInsideTheTable) {
  for (const auto& family : tasks::families()) {
    const auto dir = gen(family, 5);
    for (const auto& d : dir.demos) {
      for (const auto& row : d.positions)
        for (const auto& p : row) {
          EXPECT_GE(p.minCoeff(), 0.0);
          EXPECT_LE(p.maxCoeff(), tasks::kTableSize);
        }
      for (const auto& s : d.segments) {
        if (!s.token.isMotion()) continue;
        const auto path = d.segmentPath(s);
        const Eigen::Vector2d goal = d.segmentGoal(s);
        EXPECT_LT((path.back() - goal).norm(), dir.spec.arrival_radius) << family;
        EXPECT_GT((path.front() - goal).norm(), 0.1) << family << " " << task::tokenKey(s.token, dir.spec);
        EXPECT_GT(path.size(), 20u);
      }
    }
  }
}

TEST(Generators, WrittenDirectoriesValidateAndReadBackIdentically) {
  const std::string root = ::testing::TempDir() + "/ddace_gen_roundtrip";
  for (const auto& family : tasks::families()) {
    const auto dir = gen(family, 2);
    const std::string path = root + "/" + family;
    task::writeTaskDir(dir, path);
    const task::TaskDirReport report = task::checkTaskDir(path);
    ASSERT_TRUE(report.errors.empty()) << formatDiagnostics(report.errors);
    ASSERT_EQ(report.dir.demos.size(), dir.demos.size());
    for (size_t i = 0; i < dir.demos.size(); ++i) {
      EXPECT_EQ(task::demonstrationCsvText(report.dir.demos[i], report.dir.spec),
                task::demonstrationCsvText(dir.demos[i], dir.spec));
      EXPECT_EQ(report.dir.demos[i].keyframes, dir.demos[i].keyframes);
    }
  }
  std::filesystem::remove_all(root);
}

TEST(Generators, ImperfectDemonstrations) {
  tasks::GeneratorOptions o;
  o.family = "task4";
  o.demos = 10;
  o.jitter_m = 0.005;
  o.mislabel_fraction = 0.1;
  const auto dir = tasks::generate(o);
  const Steps clean{{"R1:move:R3", "R2:move:R4"}, {"R3:move:G1", "R4:move:G1"}};
  int differing = 0;
  for (const auto& d : dir.demos) differing += structure(d, dir.spec) != clean;
  EXPECT_EQ(differing, 1);  // one mislabelled keyframe in 10 % of 10 demonstrations
}

TEST(Generators, BadOptionsAreRefusedNamingTheOption) {
  try {
    gen("task2", 1, 1, 12);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("--robots"), std::string::npos);
  }
  EXPECT_THROW(gen("task3", 1, 1, 11, 5), Error);
  EXPECT_THROW(gen("task9"), Error);
}
