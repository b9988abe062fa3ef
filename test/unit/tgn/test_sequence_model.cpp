// Training, prediction, the model directory and the gnn baseline.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "ddace/common/error.h"
#include "ddace/tasks/generators.h"
#include "ddace/tgn/detail.h"
#include "ddace/tgn/sequence_model.h"

using namespace ddace;
namespace fs = std::filesystem;

namespace {

task::TaskDir generate(const std::string& family, int demos, uint64_t seed = 1) {
  tasks::GeneratorOptions o;
  o.family = family;
  o.demos = demos;
  o.seed = seed;
  return tasks::generate(o);
}

std::string tempDir(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("ddace_test_tgn_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(p);
  return p.string();
}

/// The message of the ddace::Error thrown by loading `dir`, or "" when none is thrown.
std::string loadError(const std::string& dir) {
  try {
    tgn::SequenceModel::load(dir);
  } catch (const Error& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("NOT A ddace::Error: ") + e.what();
  }
  return "";
}

const tgn::SequenceModel& task4Model() {
  static const tgn::SequenceModel model = [] {
    tgn::TrainOptions o;
    o.seed = 3;
    return tgn::SequenceModel::train(generate("task4", 10), o, nullptr);
  }();
  return model;
}

}  // namespace

class ReachesFullStepAccuracy : public ::testing::TestWithParam<std::string> {};

TEST_P(ReachesFullStepAccuracy, OnTheTrainingDemonstrations) {
  const task::TaskDir train = generate(GetParam(), 10);
  tgn::TrainOptions o;
  std::ostringstream progress;
  const tgn::SequenceModel m = tgn::SequenceModel::train(train, o, &progress);
  EXPECT_DOUBLE_EQ(m.stepAccuracy(train.demos), 1.0) << progress.str();
  EXPECT_EQ(m.info().history.back().step_accuracy, 1.0);
  EXPECT_LT(static_cast<int>(m.info().history.size()), o.max_epochs) << "no plateau reached";
  // One progress line per epoch.
  const std::string text = progress.str();
  EXPECT_EQ(static_cast<size_t>(std::count(text.begin(), text.end(), '\n')), m.info().history.size());
  EXPECT_NE(text.find("epoch 1/"), std::string::npos);
  EXPECT_NE(text.find("step accuracy"), std::string::npos);
}

INSTANTIATE_TEST_SUITE_P(Tasks, ReachesFullStepAccuracy, ::testing::Values("task1", "task2", "task3", "task4"));

TEST(SequenceModel, PredictsTheStepsOfNewStartGoalConfigurations) {
  const tgn::SequenceModel& m = task4Model();
  const task::TaskDir test = generate("task4", 5, 99);  // other seed: other start positions
  EXPECT_DOUBLE_EQ(m.stepAccuracy(test.demos), 1.0);
  // predictNext on a history reproduces the demonstrated steps, then END.
  const task::Demonstration& d = test.demos.front();
  for (size_t k = 0; k < d.snapshots.size(); ++k) {
    const std::vector<task::Snapshot> history(d.snapshots.begin(), d.snapshots.begin() + static_cast<long>(k) + 1);
    const tgn::Prediction p = m.predictNext(history);
    if (k + 1 == d.snapshots.size()) {
      EXPECT_TRUE(p.end);
      EXPECT_GT(p.end_probability, 0.5);
      EXPECT_TRUE(p.tokens.empty());
    } else {
      EXPECT_FALSE(p.end);
      EXPECT_EQ(p.tokens, d.steps[k].tokens) << "step " << k;
      ASSERT_EQ(p.token_probabilities.size(), p.tokens.size());
      for (double q : p.token_probabilities) EXPECT_TRUE(q > 0.25 && q <= 1.0) << q;
    }
  }
}

TEST(SequenceModel, IsDeterministicBySeed) {
  const task::TaskDir train = generate("task1", 6);
  tgn::TrainOptions o;
  o.max_epochs = 5;
  o.seed = 11;
  const auto a = tgn::SequenceModel::train(train, o, nullptr);
  const auto b = tgn::SequenceModel::train(train, o, nullptr);
  o.seed = 12;
  const auto c = tgn::SequenceModel::train(train, o, nullptr);
  ASSERT_EQ(a.info().history.size(), 5u);
  for (size_t i = 0; i < 5; ++i) EXPECT_EQ(a.info().history[i].loss, b.info().history[i].loss);
  EXPECT_NE(a.info().history.back().loss, c.info().history.back().loss);
}

TEST(SequenceModel, StopsAtAPlateauButNeverOnASpike) {
  auto history = [](std::vector<double> losses) {
    std::vector<tgn::EpochRecord> h;
    for (size_t i = 0; i < losses.size(); ++i) h.push_back({static_cast<int>(i) + 1, losses[i], 1.0, 0.0});
    return h;
  };
  std::vector<double> flat(40, 0.0035), falling, spike(40, 0.0035);
  for (int i = 0; i < 40; ++i) falling.push_back(1.0 / (i + 1));
  spike.back() = 0.43;  // the last epoch took a bad step: its weights must not be the model
  EXPECT_TRUE(tgn::detail::atPlateau(history(flat), 20, 1e-3));
  EXPECT_FALSE(tgn::detail::atPlateau(history(falling), 20, 1e-3));
  EXPECT_FALSE(tgn::detail::atPlateau(history(spike), 20, 1e-3));
  EXPECT_FALSE(tgn::detail::atPlateau(history(std::vector<double>(39, 0.0035)), 20, 1e-3)) << "too few epochs";
  spike.push_back(0.0036);  // recovered
  EXPECT_TRUE(tgn::detail::atPlateau(history(spike), 20, 1e-3));
}

TEST(SequenceModel, SaveThenLoadGivesIdenticalPredictions) {
  const tgn::SequenceModel& m = task4Model();
  const std::string dir = tempDir("roundtrip");
  m.save(dir);
  for (const char* f : {"manifest.yaml", "task.yaml", "weights.pt", "loss.csv"}) EXPECT_TRUE(fs::exists(fs::path(dir) / f)) << f;
  const tgn::SequenceModel l = tgn::SequenceModel::load(dir);
  EXPECT_EQ(l.variant(), "ddace");
  EXPECT_EQ(l.spec().entityNames(), m.spec().entityNames());
  EXPECT_EQ(l.info().vocabulary, m.info().vocabulary);
  EXPECT_EQ(l.info().refined.kept, m.info().refined.kept);
  EXPECT_EQ(l.info().attention_edges, m.info().attention_edges);
  ASSERT_EQ(l.info().history.size(), m.info().history.size());
  EXPECT_DOUBLE_EQ(l.info().history.back().loss, m.info().history.back().loss);
  const task::TaskDir test = generate("task4", 3, 7);
  for (const auto& d : test.demos)
    for (size_t k = 1; k <= d.snapshots.size(); ++k) {
      const std::vector<task::Snapshot> h(d.snapshots.begin(), d.snapshots.begin() + static_cast<long>(k));
      const auto p = m.predictNext(h), q = l.predictNext(h);
      EXPECT_EQ(p.end, q.end);
      EXPECT_EQ(p.end_probability, q.end_probability);
      EXPECT_EQ(p.tokens, q.tokens);
      EXPECT_EQ(p.token_probabilities, q.token_probabilities);
    }
  fs::remove_all(dir);
}

TEST(SequenceModel, RejectsMissingTruncatedCorruptedAndMismatchedFiles) {
  const std::string good = tempDir("good");
  task4Model().save(good);
  ASSERT_EQ(loadError(good), "");
  auto variant = [&](const std::string& name, auto mutate) {
    const std::string dir = tempDir(name);
    fs::copy(good, dir);
    mutate(fs::path(dir));
    return loadError(dir);
  };
  auto rewrite = [](const fs::path& p, auto edit) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    in.close();
    std::string s = ss.str();
    edit(s);
    std::ofstream(p, std::ios::binary) << s;
  };
  EXPECT_NE(loadError(tempDir("nothing")).find("does not exist"), std::string::npos);
  for (const char* f : {"manifest.yaml", "task.yaml", "weights.pt", "loss.csv"}) {
    const std::string e = variant(std::string("missing_") + f, [&](const fs::path& d) { fs::remove(d / f); });
    EXPECT_NE(e.find(f), std::string::npos) << f << ": " << e;
  }
  std::string e = variant("truncated", [&](const fs::path& d) {
    rewrite(d / "weights.pt", [](std::string& s) { s.resize(s.size() / 2); });
  });
  EXPECT_NE(e.find("weights.pt"), std::string::npos) << e;
  EXPECT_NE(e.find("truncated"), std::string::npos) << e;
  e = variant("flipped", [&](const fs::path& d) {
    rewrite(d / "weights.pt", [](std::string& s) { s[s.size() / 2] ^= 0x5a; });
  });
  EXPECT_NE(e.find("weights.pt"), std::string::npos) << e;
  EXPECT_NE(e.find("corrupted"), std::string::npos) << e;
  e = variant("bad_yaml", [&](const fs::path& d) {
    rewrite(d / "manifest.yaml", [](std::string& s) { s = s.substr(0, s.size() / 3) + "\n  : [\n"; });
  });
  EXPECT_NE(e.find("manifest.yaml"), std::string::npos) << e;
  e = variant("other_task", [&](const fs::path& d) {
    rewrite(d / "task.yaml", [](std::string& s) {
      for (size_t at = s.find("R4"); at != std::string::npos; at = s.find("R4")) s.replace(at, 2, "R9");
    });
  });
  EXPECT_NE(e.find("manifest.yaml"), std::string::npos) << e;
  EXPECT_NE(e.find("do not match"), std::string::npos) << e;
  e = variant("other_format", [&](const fs::path& d) {
    rewrite(d / "manifest.yaml", [](std::string& s) { s.replace(s.find("format: ddace-model/1"), 21, "format: ddace-model/9"); });
  });
  EXPECT_NE(e.find("manifest.yaml:"), std::string::npos) << e;
  e = variant("loss_row", [&](const fs::path& d) {
    rewrite(d / "loss.csv", [](std::string& s) { s += "x,y\n"; });
  });
  EXPECT_NE(e.find("loss.csv:"), std::string::npos) << e;
  // A network of another shape: the manifest's hyper-parameters no longer fit the weights
  // (the checksum still matches, so the archive itself is checked).
  e = variant("other_shape", [&](const fs::path& d) {
    rewrite(d / "manifest.yaml", [](std::string& s) { s.replace(s.find("gru_hidden: 64"), 14, "gru_hidden: 32"); });
  });
  EXPECT_NE(e.find("weights.pt"), std::string::npos) << e;
  fs::remove_all(good);
}

TEST(SequenceModel, RejectsBadOptionsAndHistories) {
  const task::TaskDir train = generate("task4", 2);
  tgn::TrainOptions o;
  o.variant = "transformer";
  EXPECT_THROW(tgn::SequenceModel::train(train, o, nullptr), Error);
  o = {};
  o.max_epochs = 0;
  EXPECT_THROW(tgn::SequenceModel::train(train, o, nullptr), Error);
  task::TaskDir empty = train;
  empty.demos.clear();
  EXPECT_THROW(tgn::SequenceModel::train(empty, {}, nullptr), Error);
  const tgn::SequenceModel& m = task4Model();
  EXPECT_THROW(m.predictNext({}), Error);
  task::Snapshot s;
  s.positions.resize(2);
  EXPECT_THROW(m.predictNext({s}), Error);
  EXPECT_THROW(tgn::rolloutGnn(m, train.demos[0], 10), Error);
}

TEST(SequenceModel, FullGraphVariantAttendsOverEveryPair) {
  const task::TaskDir train = generate("task4", 4);
  tgn::TrainOptions o;
  o.variant = "full-graph";
  o.max_epochs = 3;
  const auto m = tgn::SequenceModel::train(train, o, nullptr);
  const size_t n = train.spec.entities.size();
  EXPECT_EQ(m.info().attention_edges.size(), n * (n - 1));
  EXPECT_LT(task4Model().info().attention_edges.size(), n * (n - 1));
  EXPECT_EQ(task4Model().info().attention_edges, task4Model().info().refined.kept);
}

TEST(SequenceModel, GnnBaselineRollsOutItsOwnTrajectories) {
  const task::TaskDir train = generate("task4", 3);
  tgn::TrainOptions o;
  o.variant = "gnn";
  o.max_epochs = 20;
  std::ostringstream progress;
  const auto m = tgn::SequenceModel::train(train, o, &progress);
  EXPECT_NE(progress.str().find("frame label accuracy"), std::string::npos);
  // Labels of the next frame are mostly right after a short training.
  EXPECT_GT(m.stepAccuracy(train.demos), 0.8) << progress.str();
  EXPECT_THROW(m.predictNext(train.demos[0].snapshots), Error);
  const task::Demonstration& d = train.demos[0];
  const task::Demonstration r = tgn::rolloutGnn(m, d, 50);
  ASSERT_GE(r.rows(), 2u);
  EXPECT_LE(r.rows(), 50u);
  EXPECT_EQ(r.positions[0], d.positions[0]);
  EXPECT_EQ(r.entities(), d.entities());
  EXPECT_NEAR(r.t[1] - r.t[0], d.t[1] - d.t[0], 1e-9);
  // It moves: some entity left its start.
  double moved = 0;
  for (size_t i = 0; i < r.entities(); ++i) moved = std::max(moved, (r.positions.back()[i] - r.positions[0][i]).norm());
  EXPECT_GT(moved, 1e-3);
  // Save and load keep the rollout.
  const std::string dir = tempDir("gnn");
  m.save(dir);
  const task::Demonstration r2 = tgn::rolloutGnn(tgn::SequenceModel::load(dir), d, 50);
  ASSERT_EQ(r2.rows(), r.rows());
  for (size_t i = 0; i < r.rows(); ++i) EXPECT_EQ(r2.positions[i], r.positions[i]);
  fs::remove_all(dir);
}
