// Training, prediction, the model directory and the gnn baseline.
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <set>
#include <sstream>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/random.h"
#include "ddace/common/sha256.h"
#include "ddace/tasks/generators.h"
#include "ddace/tasks/rule_zoo.h"
#include "ddace/tgn/detail.h"
#include "ddace/tgn/sequence_model.h"

#include "../common/file_tree.h"

using namespace ddace;
namespace fs = std::filesystem;

namespace {

/// A family of `ddace generate`, or a rule of the zoo ("zoo:ID").
task::TaskDir generate(const std::string& family, int demos, uint64_t seed = 1) {
  uint64_t rule = 0;
  if (tasks::parseZooFamily(family, rule)) return tasks::generateZoo(rule, demos, seed);
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

/// Recomputes the manifest's own digest after an edit (what a careful forger would do).
void reseal(std::string& manifest) {
  const size_t at = manifest.rfind("\nmanifest_sha256: ");
  manifest = manifest.substr(0, at + 1);
  manifest += "manifest_sha256: " + sha256Hex(manifest) + "\n";
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
  // One progress line per epoch (and one saying the fixed order was seen: these tasks have one).
  const std::string text = progress.str();
  size_t epoch_lines = 0;
  for (size_t at = 0; (at = text.find("epoch ", at)) != std::string::npos; ++at)
    if (at == 0 || text[at - 1] == '\n') ++epoch_lines;
  EXPECT_EQ(epoch_lines, m.info().history.size());
  EXPECT_NE(text.find("every demonstration has the same"), std::string::npos) << text;
  EXPECT_FALSE(m.info().plan.relative_features);
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
  for (const char* f : {"manifest.yaml", "task.yaml", "weights.pt", "loss.csv"})
    EXPECT_TRUE(fs::exists(fs::path(dir) / f)) << f;
  const tgn::SequenceModel l = tgn::SequenceModel::load(dir);
  EXPECT_EQ(l.variant(), "scene");
  EXPECT_EQ(l.spec().entityNames(), m.spec().entityNames());
  EXPECT_EQ(l.info().vocabulary, m.info().vocabulary);
  EXPECT_EQ(l.info().refined.kept, m.info().refined.kept);
  EXPECT_EQ(l.info().plan, m.info().plan);
  EXPECT_EQ(l.info().options.without, m.info().options.without);
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
    std::string s = test::fileBytes(p);
    edit(s);
    test::writeBytes(p, s);
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
  e = variant("flipped",
              [&](const fs::path& d) { rewrite(d / "weights.pt", [](std::string& s) { s[s.size() / 2] ^= 0x5a; }); });
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
  EXPECT_NE(e.find("task.yaml"), std::string::npos) << e;
  EXPECT_NE(e.find("manifest.yaml records"), std::string::npos) << e;
  e = variant("other_format", [&](const fs::path& d) {
    rewrite(d / "manifest.yaml",
            [](std::string& s) { s.replace(s.find("format: ddace-model/17"), 22, "format: ddace-model/18"); });
  });
  EXPECT_NE(e.find("manifest.yaml:"), std::string::npos) << e;
  e = variant("loss_row", [&](const fs::path& d) { rewrite(d / "loss.csv", [](std::string& s) { s += "x,y\n"; }); });
  EXPECT_NE(e.find("loss.csv:"), std::string::npos) << e;
  // A network of another shape: the manifest's hyper-parameters no longer fit the weights
  // (the manifest re-sealed with its digest recomputed, so the archive itself is checked).
  e = variant("other_shape", [&](const fs::path& d) {
    rewrite(d / "manifest.yaml", [](std::string& s) {
      s.replace(s.find("gru_hidden: 64"), 14, "gru_hidden: 32");
      reseal(s);
    });
  });
  EXPECT_NE(e.find("weights.pt"), std::string::npos) << e;
  fs::remove_all(good);
}

// Edits of the manifest that used to load silently. Each is a small, plausible
// hand edit; the manifest's own digest refuses every one, naming the file.
TEST(SequenceModel, RefusesEveryManifestEdit) {
  tgn::TrainOptions o;
  o.max_epochs = 2;
  tasks::GeneratorOptions g;
  g.family = "task2";
  g.robots = 4;
  g.demos = 4;
  const std::string good = tempDir("edits");
  tgn::SequenceModel::train(tasks::generate(g), o, nullptr).save(good);
  ASSERT_EQ(loadError(good), "");
  const std::string manifest = test::fileBytes(fs::path(good) / "manifest.yaml");
  ASSERT_NE(manifest.find("vocabulary: [move, stop]"), std::string::npos) << manifest;
  const auto edited = [&](const std::string& from, const std::string& to, bool seal) {
    std::string s = manifest;
    const size_t at = s.find(from);
    if (at == std::string::npos) return "'" + from + "' is not in the manifest";
    s.replace(at, from.size(), to);
    if (seal) reseal(s);
    const std::string dir = tempDir("edited");
    fs::copy(good, dir);
    test::writeBytes(fs::path(dir) / "manifest.yaml", s);
    const std::string e = loadError(dir);
    fs::remove_all(dir);
    return e;
  };
  const std::vector<std::pair<std::string, std::string>> edits = {
      {"vocabulary: [move, stop]", "vocabulary: [stop, move]"},
      {"vocabulary: [move, stop]", "vocabulary: [move, halt]"},
      {"mean_m: [0.", "mean_m: [1."},
      {"variant: scene", "variant: paper"},
      {"threads: 1", "threads: 100000"},
  };
  for (const auto& [from, to] : edits) {
    const std::string e = edited(from, to, false);
    EXPECT_NE(e.find("manifest.yaml"), std::string::npos) << from << " -> " << to << ": " << e;
    EXPECT_NE(e.find("its own digest"), std::string::npos) << from << " -> " << to << ": " << e;
  }
  // attention_edges cut to one: everything after the first edge dropped.
  {
    const size_t first = manifest.find("attention_edges:\n    - ");
    ASSERT_NE(first, std::string::npos);
    const size_t second = manifest.find("\n    - ", first + 20);
    const size_t end = manifest.rfind("\nmanifest_sha256: ");
    const std::string e = edited(manifest.substr(second, end - second), "", false);
    EXPECT_NE(e.find("its own digest"), std::string::npos) << e;
  }
  // Re-sealed edits are still caught by what the fields must agree with.
  EXPECT_NE(edited("vocabulary: [move, stop]", "vocabulary: [stop, move]", true).find("task_fingerprint"),
            std::string::npos);
  EXPECT_NE(edited("threads: 1", "threads: 100000", true).find("threads: must be in 1..64"), std::string::npos);
  {
    const std::string e = edited("clusters: ", "clusters: 99", true);
    EXPECT_NE(e.find("refinement: clusters (at most the entities) must be an integer in 1.."), std::string::npos) << e;
  }
  // A rule switched off that does not exist; a name group naming no entity.
  EXPECT_NE(edited("without: []", "without: [nearest]", true).find("'nearest' is not a learning rule"),
            std::string::npos);
  EXPECT_NE(edited("name_groups: []", "name_groups: [[R1, R9]]", true).find("unknown entity 'R9'"), std::string::npos);
  // What the model can transfer follows from the plan (Task 2: a fixed order): a manifest
  // claiming more is refused, naming what the plan says.
  const std::string transfer =
      edited("transfer: \"its own task's entities only", "transfer: \"any number of robot", true);
  EXPECT_NE(transfer.find("transfer does not follow from the variant and the plan"), std::string::npos) << transfer;
  EXPECT_NE(transfer.find("fixed order"), std::string::npos) << transfer;
  // The digest line itself cut or changed.
  EXPECT_NE(edited("manifest_sha256: ", "manifest_sha256: 0", false).find("last line"), std::string::npos);
  {
    const std::string e = edited("step_size: ", "step_size: 9", true);
    EXPECT_NE(e.find("step_rules: step_size (at most the entities) must be an integer in 0.."), std::string::npos) << e;
    EXPECT_NE(edited("step_size: ", "step_size:", true).find("missing key 'step_size'"), std::string::npos);
  }
  // An older format: retrain, saying what it lacks; a newer one: said so.
  for (const char* version :
       {"ddace-model/9", "ddace-model/8", "ddace-model/7", "ddace-model/5", "ddace-model/4", "ddace-model/2"}) {
    const std::string old = edited("format: ddace-model/17", std::string("format: ") + version, false);
    EXPECT_NE(old.find("retrain"), std::string::npos) << old;
    EXPECT_NE(old.find("relational basis"), std::string::npos) << old;
    EXPECT_EQ(old.find("no training plan") != std::string::npos, std::string(version) != "ddace-model/9") << old;
    EXPECT_NE(old.find("manifest.yaml:"), std::string::npos) << old;
  }
  {
    const std::string old = edited("format: ddace-model/17", "format: ddace-model/10", false);
    EXPECT_NE(old.find("retrain"), std::string::npos) << old;
    EXPECT_NE(old.find("no ensemble"), std::string::npos) << old;
    const std::string twelve = edited("format: ddace-model/17", "format: ddace-model/12", false);
    EXPECT_NE(twelve.find("relational basis"), std::string::npos) << twelve;
    EXPECT_EQ(twelve.find("no ensemble"), std::string::npos) << twelve;
    const std::string thirteen = edited("format: ddace-model/17", "format: ddace-model/13", false);
    EXPECT_NE(thirteen.find("who acts"), std::string::npos) << thirteen;
    EXPECT_EQ(thirteen.find("relational basis"), std::string::npos) << thirteen;
    const std::string fourteen = edited("format: ddace-model/17", "format: ddace-model/14", false);
    EXPECT_NE(fourteen.find("keyed by name only"), std::string::npos) << fourteen;
    EXPECT_EQ(fourteen.find("who acts"), std::string::npos) << fourteen;
    const std::string fifteen = edited("format: ddace-model/17", "format: ddace-model/15", false);
    EXPECT_NE(fifteen.find("no end scene"), std::string::npos) << fifteen;
    EXPECT_EQ(fifteen.find("keyed by name only"), std::string::npos) << fifteen;
    const std::string last = edited("format: ddace-model/17", "format: ddace-model/16", false);
    EXPECT_NE(last.find("retrain"), std::string::npos) << last;
    EXPECT_NE(last.find("the one it stopped at"), std::string::npos) << last;
    EXPECT_EQ(last.find("no end scene"), std::string::npos) << last;
  }
  EXPECT_NE(edited("format: ddace-model/17", "format: ddace-model/2", false).find("digests"), std::string::npos);
  EXPECT_NE(edited("format: ddace-model/17", "format: ddace-model/19", false).find("newer"), std::string::npos);
  {
    // The record is what training did: fetch's robots were shuffled (or, after 2 epochs, the
    // network without names kept: then none), Task 2's names not.
    tasks::GeneratorOptions f;
    f.family = "fetch";
    f.demos = 4;
    const std::string fetch = tempDir("fetch_names");
    const tgn::SequenceModel trained = tgn::SequenceModel::train(tasks::generate(f), o, nullptr);
    trained.save(fetch);
    const tgn::TrainingPlan& done = trained.info().plan;
    EXPECT_EQ(done.name_groups.empty(), !done.identity_embedding);
    EXPECT_EQ(tgn::SequenceModel::load(fetch).info().plan.name_groups, done.name_groups);
    EXPECT_EQ(tgn::SequenceModel::load(fetch).info().plan.identity_embedding, done.identity_embedding);
    EXPECT_TRUE(tgn::SequenceModel::load(good).info().plan.name_groups.empty());
    fs::remove_all(fetch);
  }
  fs::remove_all(good);
}

// A person mislabels a token now and then: a fixed order with one slip in ten demonstrations
// is still a fixed order (no relative features, no names shuffled), where it was trained as
// a scene-dependent task and Tasks 2-4 fell to OSR 0 (docs/results.md, "Imperfect
// demonstrations"); a family where the scene decides keeps its relative features.
TEST(SequenceModel, LabellingSlipsKeepAFixedOrderFixed) {
  tgn::TrainOptions o;
  o.max_epochs = 2;
  for (const char* family : {"task4", "fetch"}) {
    tasks::GeneratorOptions g;
    g.family = family;
    g.demos = 10;
    g.mislabel_fraction = 0.1;
    const task::TaskDir train = tasks::generate(g);
    const bool fixed = std::string(family) == "task4";
    if (fixed) {
      ASSERT_FALSE(std::all_of(train.demos.begin(), train.demos.end(), [&](const auto& d) {
        return task::sameSteps(d.steps, train.demos.front().steps);
      })) << "no slip was generated";
    }
    const tgn::TrainingPlan plan = tgn::SequenceModel::train(train, o, nullptr).info().plan;
    EXPECT_EQ(plan.fixed_order, fixed) << family;
    EXPECT_EQ(plan.slips > 0, fixed) << family;
    EXPECT_EQ(plan.relative_features, !fixed) << family;
    EXPECT_FALSE(fixed && !plan.name_groups.empty()) << family;
  }
  // The names the scene decides are read past a slip too: queue's slots keep theirs.
  tasks::GeneratorOptions q;
  q.family = "queue";
  q.demos = 10;
  q.mislabel_fraction = 0.1;
  const task::TaskDir queue = tasks::generate(q);
  const auto groups = tgn::detail::interchangeableNames(queue);
  ASSERT_EQ(groups.size(), 1u);
  std::vector<std::string> names;
  for (int e : groups[0]) names.push_back(queue.spec.entities[static_cast<size_t>(e)].name);
  EXPECT_EQ(names, (std::vector<std::string>{"R1", "R2", "R3"}));
}

// Token by token (docs/tgn.md): trained, and so decoded, where every step's targets were
// exclusive and some step had several tokens (nearest_goal); nowhere else, and not when
// switched off. The manifest keeps the record.
TEST(TokenByToken, IsTrainedWhereAStepHasSeveralExclusiveTargets) {
  tgn::TrainOptions o;
  o.max_epochs = 2;
  const auto goals = tgn::SequenceModel::train(generate("nearest_goal", 4), o, nullptr);
  EXPECT_TRUE(goals.info().plan.token_by_token);
  EXPECT_FALSE(tgn::SequenceModel::train(generate("fetch", 4), o, nullptr).info().plan.token_by_token)
      << "the fetcher and the box share a target";
  EXPECT_FALSE(tgn::SequenceModel::train(generate("queue", 4), o, nullptr).info().plan.token_by_token)
      << "one token per step";
  EXPECT_FALSE(tgn::SequenceModel::train(generate("task4", 4), o, nullptr).info().plan.token_by_token);
  const std::string dir = tempDir("token_by_token");
  goals.save(dir);
  EXPECT_TRUE(tgn::SequenceModel::load(dir).info().plan.token_by_token);
  fs::remove_all(dir);
  o.without = {tgn::Rule::TokenByToken};
  EXPECT_FALSE(tgn::SequenceModel::train(generate("nearest_goal", 4), o, nullptr).info().plan.token_by_token);
}

// Token by token, who acts is chosen one token at a time too, not only at what. In "each
// box fetched by its nearest free robot" (zoo:two-boxes: 3 robots, 2 boxes), where one
// robot is the nearest to both boxes, it takes the box nearer to it, and the other box is
// fetched by its nearest robot of the two left: a relation to a token already chosen.
// The action heads alone, deciding who acts before any token, were wrong in 8 of the 24
// such fresh scenes below (the third robot acted instead of the other box's nearest free
// one; training data seed 2, 2 of 24 at seeds 1 and 3); the decoder now misses 1.
TEST(TokenByToken, ChoosesWhoActsOneTokenAtATime) {
  const tgn::SequenceModel m =
      tgn::SequenceModel::train(generate("zoo:two-boxes", 20, 2), tgn::TrainOptions{}, nullptr);
  ASSERT_TRUE(m.info().plan.token_by_token);
  const task::TaskDir fresh = generate("zoo:two-boxes", 80, 77);
  const auto nearestRobot = [&](const std::vector<Eigen::Vector2d>& pos, const std::string& box) {
    const int b = fresh.spec.entityIndex(box);
    int best = -1;
    for (int r = 0; r < static_cast<int>(pos.size()); ++r)
      if (fresh.spec.entities[static_cast<size_t>(r)].kind == task::EntityKind::Robot &&
          (best < 0 || (pos[static_cast<size_t>(r)] - pos[static_cast<size_t>(b)]).norm() <
                           (pos[static_cast<size_t>(best)] - pos[static_cast<size_t>(b)]).norm()))
        best = r;
    return best;
  };
  int scenes = 0, right = 0;
  for (const auto& d : fresh.demos) {
    const std::vector<Eigen::Vector2d>& start = d.snapshots[0].positions;
    if (nearestRobot(start, "B1") != nearestRobot(start, "B2")) continue;
    ++scenes;
    right += m.predictNext({d.snapshots[0]}).tokens == d.steps[0].tokens;
  }
  ASSERT_GE(scenes, 15) << "fresh scenes in which one robot is the nearest to both boxes";
  EXPECT_GE(right, scenes - 2) << "the second box fetched by its nearest free robot";
}

// Parked entities (docs/tgn.md): where the scene network sees the relative features, an
// entity at one place with another is no rival in the nearness ranks; not on a fixed order
// (no relative features), nor for the paper's network, nor when switched off. The manifest
// keeps the record, and a claim that does not fit the model is refused.
TEST(ParkedEntities, AreOutOfTheRanksWhereTheSceneDecides) {
  tgn::TrainOptions o;
  o.max_epochs = 2;
  const auto queue = tgn::SequenceModel::train(generate("queue", 4), o, nullptr);
  EXPECT_TRUE(queue.info().plan.parked_out_of_ranks);
  EXPECT_FALSE(tgn::SequenceModel::train(generate("task4", 4), o, nullptr).info().plan.parked_out_of_ranks);
  o.without = {tgn::Rule::Parked};
  EXPECT_FALSE(tgn::SequenceModel::train(generate("queue", 4), o, nullptr).info().plan.parked_out_of_ranks);
  o.without.clear();
  o.variant = tgn::Variant::Paper;
  EXPECT_FALSE(tgn::SequenceModel::train(generate("queue", 4), o, nullptr).info().plan.parked_out_of_ranks);
  const std::string dir = tempDir("parked");
  queue.save(dir);
  EXPECT_TRUE(tgn::SequenceModel::load(dir).info().plan.parked_out_of_ranks);
  fs::remove_all(dir);
}

// The step rules come from the training steps, for the scene variant only, and survive
// save -> load.
TEST(SequenceModel, LearnsTheStepRulesItsTrainingDemonstrationsKeep) {
  tgn::TrainOptions o;
  o.max_epochs = 2;
  // nearest_goal: every robot to its own goal, in one step.
  const auto goals = tgn::SequenceModel::train(generate("nearest_goal", 4), o, nullptr);
  EXPECT_TRUE(goals.info().plan.step_rules.exclusive_targets);
  EXPECT_EQ(goals.info().plan.step_rules.step_size, 3);
  // fetch: the fetcher and the box carry to the same goal in one step, one decision (a
  // carried load): one decision a step, each target once.
  const auto fetch = tgn::SequenceModel::train(generate("fetch", 4), o, nullptr);
  EXPECT_EQ(fetch.info().plan.step_rules.step_size, 1);
  EXPECT_TRUE(fetch.info().plan.step_rules.exclusive_targets);
  // The paper's network decodes each entity on its own.
  o.variant = tgn::Variant::Paper;
  EXPECT_FALSE(tgn::SequenceModel::train(generate("nearest_goal", 4), o, nullptr).info().plan.step_rules.any());
  const std::string dir = tempDir("step_rules");
  goals.save(dir);
  EXPECT_EQ(tgn::SequenceModel::load(dir).info().plan.step_rules, goals.info().plan.step_rules);
  fs::remove_all(dir);
}

TEST(SequenceModel, RecordsTheTaskFingerprintOfItsTrainingDirectory) {
  const tgn::SequenceModel& m = task4Model();
  EXPECT_EQ(m.info().fingerprint, task::fingerprintOf(generate("task4", 10)));
  const std::string dir = tempDir("fingerprint");
  m.save(dir);
  const tgn::SequenceModel l = tgn::SequenceModel::load(dir);
  EXPECT_EQ(l.info().fingerprint.digest(), m.info().fingerprint.digest());
  for (const char* f : {"task.yaml", "weights.pt", "loss.csv"}) {
    ASSERT_TRUE(l.info().files.count(f)) << f;
    EXPECT_EQ(l.info().files.at(f).sha256, sha256Hex(test::fileBytes(fs::path(dir) / f))) << f;
  }
  fs::remove_all(dir);
}

TEST(SequenceModel, RejectsBadOptionsAndHistories) {
  const task::TaskDir train = generate("task4", 2);
  tgn::TrainOptions o;
  EXPECT_THROW(tgn::variantFromString("transformer"), Error);
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
  o.variant = tgn::Variant::FullGraph;
  o.max_epochs = 3;
  const auto m = tgn::SequenceModel::train(train, o, nullptr);
  const size_t n = train.spec.entities.size();
  EXPECT_EQ(m.info().plan.attention_edges.size(), n * (n - 1));
  o.variant = tgn::Variant::Paper;
  const auto paper = tgn::SequenceModel::train(train, o, nullptr);
  EXPECT_LT(paper.info().plan.attention_edges.size(), n * (n - 1));
  EXPECT_EQ(paper.info().plan.attention_edges, paper.info().refined.kept);
  // The scene variant: E' lifted to entity kinds (every pair whose kinds a kept edge has).
  const tgn::ModelInfo& scene = task4Model().info();
  EXPECT_LT(scene.plan.attention_edges.size(), n * (n - 1));
  for (const auto& e : scene.refined.kept)
    EXPECT_NE(std::find(scene.plan.attention_edges.begin(), scene.plan.attention_edges.end(), e),
              scene.plan.attention_edges.end());
  const auto& ents = task4Model().spec().entities;
  for (const auto& a : scene.plan.attention_edges) {
    bool kinds_kept = false;
    for (const auto& e : scene.refined.kept)
      kinds_kept =
          kinds_kept || (ents[a.source].kind == ents[e.source].kind && ents[a.target].kind == ents[e.target].kind);
    EXPECT_TRUE(kinds_kept) << ents[a.source].name << "->" << ents[a.target].name;
  }
}

namespace {

/// `dir` written to disk twice, the second time with task.yaml's entities in reverse order
/// (the CSV columns are named, so the demonstrations read the same); both loaded again.
std::pair<task::TaskDir, task::TaskDir> withReversedEntities(const task::TaskDir& dir, const std::string& name) {
  const std::string a = tempDir(name + "_a"), b = tempDir(name + "_b");
  task::writeTaskDir(dir, a);
  task::TaskDir reversed = dir;
  std::reverse(reversed.spec.entities.begin(), reversed.spec.entities.end());
  task::writeTaskYaml(reversed.spec, a + "/reversed.yaml");
  fs::copy(a, b, fs::copy_options::recursive);
  fs::rename(fs::path(b) / "reversed.yaml", fs::path(b) / "task.yaml");
  fs::remove(fs::path(a) / "reversed.yaml");
  auto out = std::make_pair(task::loadTaskDir(a), task::loadTaskDir(b));
  fs::remove_all(a);
  fs::remove_all(b);
  return out;
}

/// A prediction's tokens by entity name ("R1:move:G1"), so that two task orders compare.
std::vector<std::string> named(const tgn::Prediction& p, const task::TaskSpec& spec) {
  std::vector<std::string> out;
  for (const auto& t : p.tokens) out.push_back(task::tokenKey(t, spec));
  std::sort(out.begin(), out.end());
  return out;
}

/// A snapshot history in the order of `to`, from one in the order of `from`.
std::vector<task::Snapshot> reordered(const std::vector<task::Snapshot>& h, const task::TaskSpec& from,
                                      const task::TaskSpec& to) {
  std::vector<task::Snapshot> out = h;
  for (size_t k = 0; k < h.size(); ++k)
    for (size_t i = 0; i < from.entities.size(); ++i)
      out[k].positions[static_cast<size_t>(to.entityIndex(from.entities[i].name))] = h[k].positions[i];
  return out;
}

}  // namespace

// (variant, family): Task 1 has three kinds of entity, a fixed order; nearest_goal and
// queue are where the scene decides (shuffled names, parked entities; nearest_goal token by
// token, whose ties go in name order); zoo:33 a relay (farness ranks, the last step, a
// carried load).
class EntityOrder : public ::testing::TestWithParam<std::pair<tgn::Variant, std::string>> {};

TEST_P(EntityOrder, InTaskYamlChangesNoDecision) {
  const std::string family = GetParam().second;
  // The reversed order puts the goals first.
  const auto [train, train_reversed] = withReversedEntities(generate(family, 6), "order_train");
  const auto [test, test_reversed] = withReversedEntities(generate(family, 3, 21), "order_test");
  ASSERT_NE(train.spec.entityNames(), train_reversed.spec.entityNames());
  tgn::TrainOptions o;
  o.variant = GetParam().first;
  o.max_epochs = 25;
  const auto a = tgn::SequenceModel::train(train, o, nullptr);
  const auto b = tgn::SequenceModel::train(train_reversed, o, nullptr);
  // The same training, bit for bit: the loss of every epoch.
  ASSERT_EQ(a.info().history.size(), b.info().history.size());
  for (size_t e = 0; e < a.info().history.size(); ++e)
    EXPECT_EQ(a.info().history[e].loss, b.info().history[e].loss) << e;
  // The same E' (by name).
  auto names = [](const tgn::SequenceModel& m, const std::vector<graph::Edge>& edges) {
    std::set<std::string> out;
    for (const auto& e : edges) out.insert(m.spec().entities[e.source].name + "->" + m.spec().entities[e.target].name);
    return out;
  };
  EXPECT_EQ(names(a, a.info().refined.kept), names(b, b.info().refined.kept));
  EXPECT_EQ(names(a, a.info().plan.attention_edges), names(b, b.info().plan.attention_edges));
  // The same decisions on the same scenes.
  for (const auto& d : test.demos)
    for (size_t k = 1; k <= d.snapshots.size(); ++k) {
      const std::vector<task::Snapshot> h(d.snapshots.begin(), d.snapshots.begin() + static_cast<long>(k));
      const auto p = a.predictNext(h), q = b.predictNext(reordered(h, test.spec, test_reversed.spec));
      EXPECT_EQ(p.end, q.end);
      EXPECT_EQ(p.end_probability, q.end_probability);
      EXPECT_EQ(named(p, a.spec()), named(q, b.spec())) << d.source << " step " << k;
    }
  EXPECT_EQ(a.stepAccuracy(test.demos), b.stepAccuracy(test_reversed.demos));
}

INSTANTIATE_TEST_SUITE_P(Variants, EntityOrder,
                         ::testing::Values(std::pair{tgn::Variant::Scene, std::string("task1")},
                                           std::pair{tgn::Variant::Paper, std::string("task1")},
                                           std::pair{tgn::Variant::Scene, std::string("nearest_goal")},
                                           std::pair{tgn::Variant::Scene, std::string("queue")},
                                           std::pair{tgn::Variant::Scene, std::string("zoo:33")}),
                         [](const auto& info) {
                           std::string family = info.param.second;
                           std::replace(family.begin(), family.end(), ':', '_');
                           return std::string(tgn::toString(info.param.first)) + "_" + family;
                         });

// The default network sees distances, ranks and orders along the table's axes, no absolute
// position: a scene moved on the table gets the same decisions. (Rotated or mirrored it may
// not: "the leftmost" is a relation to the table's own axes.)
TEST(SequenceModel, SceneDecisionsDoNotDependOnWhereTheSceneIsOnTheTable) {
  tgn::TrainOptions o;
  o.max_epochs = 25;
  const auto m = tgn::SequenceModel::train(generate("deliver", 8), o, nullptr);
  const task::TaskDir test = generate("deliver", 4, 33);
  const auto moved = [&](std::vector<task::Snapshot> h, const Eigen::Vector2d& by) {
    for (auto& s : h)
      for (auto& p : s.positions) p += by;
    return h;
  };
  for (const auto& d : test.demos)
    for (size_t k = 1; k <= d.snapshots.size(); ++k) {
      const std::vector<task::Snapshot> h(d.snapshots.begin(), d.snapshots.begin() + static_cast<long>(k));
      const auto p = m.predictNext(h);
      for (const Eigen::Vector2d& by : {Eigen::Vector2d(0.31, -0.12), Eigen::Vector2d(-0.2, 0.45)}) {
        const auto q = m.predictNext(moved(h, by));
        EXPECT_EQ(p.end, q.end) << d.source << " step " << k;
        EXPECT_NEAR(p.end_probability, q.end_probability, 1e-4) << d.source << " step " << k;
        EXPECT_EQ(named(p, m.spec()), named(q, m.spec())) << d.source << " step " << k;
      }
    }
}

// Fixed order: every training demonstration has the same steps, so the network learns
// without the relative features, and no configuration (here: every entity anywhere on the
// table, at every snapshot) changes a decision; saved and loaded, it stays so. Where the
// steps vary (fetch: the robot nearest the box fetches it), the features stay.
TEST(SequenceModel, FixedOrderTasksDecideFromTheStepsSoFarNotTheConfiguration) {
  const tgn::SequenceModel& m = task4Model();
  EXPECT_FALSE(m.info().plan.relative_features);
  const task::TaskDir test = generate("task4", 3, 41);
  SplitMix64 rng(7);
  const std::string dir = tempDir("fixed_order");
  m.save(dir);
  const tgn::SequenceModel loaded = tgn::SequenceModel::load(dir);
  EXPECT_FALSE(loaded.info().plan.relative_features);
  for (const auto& d : test.demos)
    for (size_t k = 1; k <= d.snapshots.size(); ++k) {
      std::vector<task::Snapshot> h(d.snapshots.begin(), d.snapshots.begin() + static_cast<long>(k));
      const auto p = m.predictNext(h);
      EXPECT_EQ(p.end, k == d.snapshots.size()) << d.source << " step " << k;
      if (!p.end) {
        EXPECT_EQ(p.tokens, d.steps[k - 1].tokens) << d.source << " step " << k;
      }
      for (auto& snap : h)
        for (auto& pos : snap.positions) pos = {rng.uniform(0.03, 1.17), rng.uniform(0.03, 0.77)};
      const auto q = m.predictNext(h), r = loaded.predictNext(h);
      EXPECT_EQ(named(p, m.spec()), named(q, m.spec())) << d.source << " step " << k;
      EXPECT_EQ(named(p, m.spec()), named(r, m.spec())) << d.source << " step " << k;
    }
  fs::remove_all(dir);

  const task::TaskDir fetch = generate("fetch", 8);
  ASSERT_FALSE(std::all_of(fetch.demos.begin(), fetch.demos.end(), [&](const task::Demonstration& d) {
    return task::sameSteps(d.steps, fetch.demos.front().steps);
  })) << "the fetch demonstrations all have the same steps: the test tests nothing";
  tgn::TrainOptions o;
  o.max_epochs = 2;
  EXPECT_TRUE(tgn::SequenceModel::train(fetch, o, nullptr).info().plan.relative_features);
  // --without fixed-order: kept on a fixed order too; --without relative: off on any task.
  o.without = {tgn::Rule::FixedOrder};
  EXPECT_TRUE(tgn::SequenceModel::train(generate("task4", 3), o, nullptr).info().plan.relative_features);
  o.without = {tgn::Rule::Relative};
  EXPECT_FALSE(tgn::SequenceModel::train(fetch, o, nullptr).info().plan.relative_features);
}

// The benchmarks' Python reference trains the network the tensors are written for: they
// follow the "Fixed order" rule as training does (no relative features, all zero), and
// with the rule off they carry the features.
TEST(SequenceModel, TrainingTensorsAreThoseOfTheNetworkTrainRuns) {
  const task::TaskDir fixed = generate("task4", 3);
  const auto written = [&](const tgn::TrainOptions& o) {
    const std::string path = tempDir("tensors") + ".txt";
    tgn::writeTrainingTensors(fixed, o, path);
    std::istringstream in(readTextFile(path));
    fs::remove(path);
    std::string line, relative;
    bool nonzero = false;
    int rel_lines = 0;
    while (std::getline(in, line)) {
      std::istringstream words(line);
      std::string key, value;
      words >> key;
      if (key == "relative_features") words >> relative;
      if (key != "rel") continue;
      ++rel_lines;
      while (words >> value) nonzero = nonzero || std::stod(value) != 0;
    }
    EXPECT_EQ(rel_lines, static_cast<int>(fixed.demos.size()));
    return std::make_pair(relative, nonzero);
  };
  tgn::TrainOptions o;
  o.max_epochs = 1;
  ASSERT_FALSE(tgn::SequenceModel::train(fixed, o, nullptr).info().plan.relative_features);
  EXPECT_EQ(written(o), std::make_pair(std::string("0"), false));
  o.without = {tgn::Rule::FixedOrder};
  EXPECT_EQ(written(o), std::make_pair(std::string("1"), true));
}

// A demonstrated motion ends on its target; on robots it ends within the arrival radius of
// it, short of it on the way there. The same scenes with every entity that arrived on
// another stopping 0.8 radii short (the path follower stops within the radius less its
// tracking tolerance) get the same decisions.
TEST(SequenceModel, StoppingWithinTheArrivalRadiusOfATargetChangesNoDecision) {
  // Task 2: R1 and R2 join R3, ..., R7 and R8 join R9, before R9 and R10 move on. With the
  // relative features kept (a fixed order would switch them off, and then nothing about
  // where an entity stopped could change a decision: "Fixed order").
  tgn::TrainOptions o;
  o.without = {tgn::Rule::FixedOrder};
  const tgn::SequenceModel m = tgn::SequenceModel::train(generate("task2", 10), o, nullptr);
  ASSERT_TRUE(m.info().plan.relative_features);
  const task::TaskDir test = generate("task2", 3, 5);
  const double radius = test.spec.arrival_radius;
  int stopped_short = 0;
  for (const auto& d : test.demos) {
    std::vector<task::Snapshot> stopped = d.snapshots;
    std::vector<Eigen::Vector2d> offset(d.entities(), Eigen::Vector2d::Zero());
    for (size_t k = 1; k < d.snapshots.size(); ++k) {
      const std::vector<Eigen::Vector2d>& now = d.snapshots[k].positions;
      for (size_t i = 0; i < now.size(); ++i) {
        if ((now[i] - d.snapshots[k - 1].positions[i]).norm() < 1e-9) continue;  // did not move
        offset[i].setZero();
        for (size_t j = 0; j < now.size(); ++j)
          if (j != i && (now[j] - now[i]).norm() < 1e-9) {
            // Short of it along its way there, as the path follower stops.
            offset[i] = -0.8 * radius * (now[i] - d.snapshots[k - 1].positions[i]).normalized();
            ++stopped_short;
            break;
          }
      }
      for (size_t i = 0; i < now.size(); ++i) stopped[k].positions[i] = now[i] + offset[i];
    }
    for (size_t k = 1; k <= d.snapshots.size(); ++k) {
      const auto p = m.predictNext({d.snapshots.begin(), d.snapshots.begin() + static_cast<long>(k)});
      const auto q = m.predictNext({stopped.begin(), stopped.begin() + static_cast<long>(k)});
      EXPECT_EQ(p.end, q.end) << d.source << " step " << k;
      EXPECT_EQ(named(p, m.spec()), named(q, m.spec())) << d.source << " step " << k;
    }
  }
  EXPECT_GT(stopped_short, 0) << "no entity arrived on another: the test tests nothing";
}

TEST(SequenceModel, RefusesANonFinitePositionNamingTheEntityAndSnapshot) {
  const tgn::SequenceModel& m = task4Model();
  const task::Demonstration d = generate("task4", 1, 5).demos.front();
  std::vector<task::Snapshot> h(d.snapshots.begin(), d.snapshots.begin() + 2);
  h[1].positions[2].y() = std::numeric_limits<double>::quiet_NaN();
  try {
    m.predictNext(h);
    FAIL() << "a NaN position was accepted";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("snapshot 1"), std::string::npos) << msg;
    EXPECT_NE(msg.find("'" + m.spec().entities[2].name + "'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("not finite"), std::string::npos) << msg;
  }
  h[1].positions[2].y() = std::numeric_limits<double>::infinity();
  EXPECT_THROW(m.predictNext(h), Error);
  // Training refuses one too, naming the demonstration.
  task::TaskDir train = generate("task4", 2);
  train.demos[1].positions[7][1].x() = std::numeric_limits<double>::quiet_NaN();
  tgn::TrainOptions o;
  o.max_epochs = 1;
  try {
    tgn::SequenceModel::train(train, o, nullptr);
    FAIL() << "a NaN position was accepted for training";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("row 7"), std::string::npos) << e.what();
  }
}

TEST(SequenceModel, GnnBaselineRollsOutItsOwnTrajectories) {
  const task::TaskDir train = generate("task4", 3);
  tgn::TrainOptions o;
  o.variant = tgn::Variant::Gnn;
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

namespace {

/// interchangeableNames as entity names.
std::vector<std::vector<std::string>> nameGroups(const task::TaskDir& train) {
  std::vector<std::vector<std::string>> out;
  for (const auto& g : tgn::detail::interchangeableNames(train)) {
    out.emplace_back();
    for (int e : g) out.back().push_back(train.spec.entities[static_cast<size_t>(e)].name);
  }
  return out;
}

using Groups = std::vector<std::vector<std::string>>;

}  // namespace

// "Shuffled names": which robot or goal does what is the scene's in every scene family but
// queue's slots, whose names say which step fills them.
TEST(ShuffledNames, AreTheEntitiesWhoseRolesTheSceneDecides) {
  EXPECT_EQ(nameGroups(generate("nearest_goal", 10)), (Groups{{"R1", "R2", "R3"}, {"G1", "G2", "G3", "G4"}}));
  EXPECT_EQ(nameGroups(generate("queue", 10)), (Groups{{"R1", "R2", "R3"}}));
  EXPECT_EQ(nameGroups(generate("fetch", 10)), (Groups{{"R1", "R2"}}));
  EXPECT_EQ(nameGroups(generate("deliver", 10)), (Groups{{"R1", "R2"}, {"G1", "G2"}}));
  // One demonstration shows no role varying: only entities that share a role are grouped.
  EXPECT_EQ(nameGroups(generate("queue", 1)), Groups{});
}

// A rule may refer to an entity that no token tells from its mates: G1 in "the others meet
// at the robot nearest to G1" (zoo:43) and in two-boxes' "the goals in turn, G1 first, each
// taking the free box nearest to it". Its relation to the tokens (the robot met at is G1's
// nearest; the box carried to G1 is G1's nearest) holds in every demonstration, G2's only
// now and then: G1 keeps its name, and G2, left alone, too.
TEST(ShuffledNames, KeepTheNameOfAnEntityTheRuleRefersTo) {
  EXPECT_EQ(nameGroups(generate("zoo:43", 10)), (Groups{{"R1", "R2", "R3", "R4"}}));
  EXPECT_EQ(nameGroups(generate("zoo:two-boxes", 20)), (Groups{{"R1", "R2", "R3"}, {"B1", "B2"}}));
}

// ... and so the decision follows G1 wherever it stands. In fresh zoo:43 scenes in which G1
// and G2 have different nearest robots, the others meet at G1's nearest, and with G1 and G2
// exchanged, at the nearest of G1's new place. Shuffled with G2 (before), G1 looked like G2
// to the network, which was then wrong in one of the two scenes.
TEST(ShuffledNames, LetTheDecisionFollowAnEntityTheRuleRefersTo) {
  const tgn::SequenceModel m = tgn::SequenceModel::train(generate("zoo:43", 10), tgn::TrainOptions{}, nullptr);
  const task::TaskDir fresh = generate("zoo:43", 12, 77);
  const int g1 = fresh.spec.entityIndex("G1"), g2 = fresh.spec.entityIndex("G2");
  const auto meetAtNearest = [&](const std::vector<Eigen::Vector2d>& pos, int goal, double* margin) {
    std::vector<std::pair<double, int>> robots;
    for (int r = 0; r < static_cast<int>(pos.size()); ++r)
      if (fresh.spec.entities[static_cast<size_t>(r)].kind == task::EntityKind::Robot)
        robots.push_back({(pos[static_cast<size_t>(r)] - pos[static_cast<size_t>(goal)]).norm(), r});
    std::sort(robots.begin(), robots.end());
    *margin = robots[1].first - robots[0].first;
    std::vector<task::Token> step;
    for (size_t k = 1; k < robots.size(); ++k) step.push_back({robots[k].second, "move", robots[0].second});
    std::sort(step.begin(), step.end(), [](const auto& a, const auto& b) { return a.entity < b.entity; });
    return step;
  };
  int scenes = 0, right = 0;
  for (const auto& d : fresh.demos) {
    task::Snapshot exchanged = d.snapshots[0];
    std::swap(exchanged.positions[static_cast<size_t>(g1)], exchanged.positions[static_cast<size_t>(g2)]);
    double margin1 = 0, margin2 = 0;
    const auto at_g1 = meetAtNearest(d.snapshots[0].positions, g1, &margin1);
    const auto at_exchanged_g1 = meetAtNearest(exchanged.positions, g1, &margin2);
    // The exchange changes the rule's decision, by the zoo's decision margin.
    if (at_g1 == at_exchanged_g1 || margin2 < 0.05) continue;
    ASSERT_EQ(at_g1, d.steps[0].tokens) << "the rule as the test reads it";
    ++scenes;
    right += m.predictNext({d.snapshots[0]}).tokens == at_g1 && m.predictNext({exchanged}).tokens == at_exchanged_g1;
  }
  ASSERT_GE(scenes, 4) << "fresh scenes in which G1 and G2 have different nearest robots";
  EXPECT_GE(right, scenes - 1) << "both scenes of a pair decided by G1's place, wherever it stands";
}

// What shuffled names are for: in a scene family the decision follows the scene, not the
// names. Fresh fetch scenes with the two robots' places exchanged get the same decision with
// the robots exchanged (whoever stands where the fetcher stood fetches), and the decisions
// are the demonstrated ones.
TEST(ShuffledNames, MakeTheDecisionFollowTheSceneNotTheNames) {
  const task::TaskDir fetch = generate("fetch", 10), fresh = generate("fetch", 6, 77);
  const tgn::SequenceModel m = tgn::SequenceModel::train(fetch, tgn::TrainOptions{}, nullptr);
  ASSERT_EQ(m.info().plan.name_groups.size(), 1u);
  const int r1 = fresh.spec.entityIndex("R1"), r2 = fresh.spec.entityIndex("R2");
  const auto exchanged = [&](int e) { return e == r1 ? r2 : e == r2 ? r1 : e; };
  int right = 0;
  for (const auto& d : fresh.demos) {
    task::Snapshot swapped = d.snapshots[0];
    std::swap(swapped.positions[static_cast<size_t>(r1)], swapped.positions[static_cast<size_t>(r2)]);
    const tgn::Prediction p = m.predictNext({d.snapshots[0]}), q = m.predictNext({swapped});
    std::vector<task::Token> expected;
    for (task::Token t : p.tokens) {
      t.entity = exchanged(t.entity);
      t.target = t.target < 0 ? t.target : exchanged(t.target);
      expected.push_back(t);
    }
    std::sort(expected.begin(), expected.end(), [](const auto& a, const auto& b) { return a.entity < b.entity; });
    EXPECT_EQ(q.tokens, expected) << "the robots' places exchanged, not their roles";
    right += p.tokens == d.steps[0].tokens;
  }
  EXPECT_GE(right, 5) << "the first step decided as demonstrated in 5 of 6 fresh scenes";
}

// Shuffling changes the training of a scene family, and nothing on a fixed order, even
// with the relative features kept (--relative): there the names are what the steps follow.
TEST(ShuffledNames, ChangeTheSceneFamiliesTrainingOnly) {
  tgn::TrainOptions on, off;
  on.max_epochs = off.max_epochs = 6;
  off.without = {tgn::Rule::ShuffledNames};
  const auto losses = [](const tgn::SequenceModel& m) {
    std::vector<double> l;
    for (const auto& r : m.info().history) l.push_back(r.loss);
    return l;
  };
  // queue's data seed 1: at seed 2 the network with the names shuffled fits short after 6
  // epochs and the one with them kept ("unless they cost the fit") replaces it.
  const task::TaskDir queue = generate("queue", 6, 1), task2 = generate("task2", 6);
  EXPECT_NE(losses(tgn::SequenceModel::train(queue, on, nullptr)),
            losses(tgn::SequenceModel::train(queue, off, nullptr)));
  ASSERT_FALSE(tgn::detail::interchangeableNames(task2).empty()) << "Task 2 has no robots sharing a role";
  EXPECT_EQ(losses(tgn::SequenceModel::train(task2, on, nullptr)),
            losses(tgn::SequenceModel::train(task2, off, nullptr)));
  on.without = {tgn::Rule::FixedOrder};
  off.without = {tgn::Rule::FixedOrder, tgn::Rule::ShuffledNames};
  const tgn::SequenceModel with = tgn::SequenceModel::train(task2, on, nullptr),
                           without = tgn::SequenceModel::train(task2, off, nullptr);
  EXPECT_EQ(losses(with), losses(without));
  // And so no decision: every step of fresh Task 2 scenes.
  for (const auto& d : generate("task2", 3, 77).demos)
    for (size_t k = 1; k <= d.snapshots.size(); ++k) {
      const std::vector<task::Snapshot> history(d.snapshots.begin(), d.snapshots.begin() + static_cast<long>(k));
      const tgn::Prediction a = with.predictNext(history), b = without.predictNext(history);
      EXPECT_EQ(a.end, b.end);
      EXPECT_EQ(a.tokens, b.tokens);
    }
}

// Rules beyond "the nearest" (the rule zoo, docs/tgn.md: left-to-right order, the farthest,
// a relay to the receiver, a relay whose giver then follows the receiver (each one's last
// move), two boxes fetched and carried at once (carried loads as one decision each)), each
// learned from 10 demonstrations with a generous margin: every step of a fresh scene
// decided as the rule says (from the true history, predictNext) in at least 8 of 10 scenes.
TEST(RuleZoo, LearnsRulesBeyondTheNearestFromTenDemonstrations) {
  for (const char* rule : {"zoo:59", "zoo:62", "zoo:41", "zoo:30", "zoo:32"}) {
    const auto m = tgn::SequenceModel::train(generate(rule, 10), tgn::TrainOptions{}, nullptr);
    const task::TaskDir test = generate(rule, 10, 77);
    int right = 0;
    for (const auto& d : test.demos) {
      bool all = true;
      for (size_t k = 1; k <= d.snapshots.size() && all; ++k) {
        const auto p = m.predictNext({d.snapshots.begin(), d.snapshots.begin() + static_cast<long>(k)});
        all = p.end == (k == d.snapshots.size()) && (p.end || p.tokens == d.steps[k - 1].tokens);
      }
      right += all;
    }
    EXPECT_GE(right, 8) << test.spec.name;
  }
}
