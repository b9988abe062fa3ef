// `ddace train --out` end to end (the real tool): a model directory holding anything train
// did not write is refused, naming what is there; --force replaces only train's own earlier
// model, whole (no stale file survives) and atomically (a killed run leaves the old model);
// train never writes into the directory it learns from.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <thread>

#include "../common/file_tree.h"
#include "../common/run_tool.h"
#include "ddace/task/task_dir.h"
#include "ddace/tgn/sequence_model.h"

namespace fs = std::filesystem;
using ddace::test::fileBytes;
using ddace::test::fileTree;
using ddace::test::runTool;
using ddace::test::toolPath;
using ddace::test::ToolRun;

namespace {

std::string root() {
  static const std::string r = [] {
    const std::string dir = ::testing::TempDir() + "/ddace_cli_train_out_" + std::to_string(::getpid());
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
  }();
  return r;
}

/// A small generated task (generate's output: DIR/train, DIR/test), made once per family.
std::string data(const std::string& family) {
  const std::string dir = root() + "/data_" + family;
  if (!fs::exists(dir)) {
    const ToolRun r = runTool("generate " + family + " --out '" + dir + "' --train 3 --test 1 --seed 2");
    EXPECT_EQ(r.status, 0) << r.out;
  }
  return dir;
}

/// A short training run (a few epochs: these tests are about the directory, not the model).
ToolRun train(const std::string& task_dir, const std::string& out, const std::string& extra = "") {
  return runTool("train '" + task_dir + "' --out '" + out + "' --epochs 2 --quiet " + extra);
}

}  // namespace

TEST(CliTrainOut, RefusesADirectoryHoldingFilesTrainDidNotWriteEvenWithForce) {
  const std::string out = root() + "/user";
  fs::create_directories(out + "/notes");
  std::ofstream(out + "/README.txt") << "my notes\n";
  std::ofstream(out + "/notes/run1.csv") << "t,x\n0,1\n";
  const auto before = fileTree(out);
  for (const std::string force : {"", "--force"}) {
    const ToolRun r = train(data("task1") + "/train", out, force);
    EXPECT_NE(r.status, 0) << r.out;
    EXPECT_NE(r.out.find(out + "/README.txt (not written by ddace train)"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(out + "/notes/run1.csv (not written by ddace train)"), std::string::npos) << r.out;
    EXPECT_EQ(r.out.find("training variant"), std::string::npos) << "refused before training: " << r.out;
    EXPECT_EQ(fileTree(out), before);
  }
}

TEST(CliTrainOut, AModelWrittenWithoutTrainsManifestIsNotTrainsToReplace) {
  // A model copied by hand (or left by a ddace that wrote no manifest): nothing says it is
  // train's own, so it is refused, even with --force.
  const std::string first = root() + "/copied_src", out = root() + "/copied";
  ASSERT_EQ(train(data("task1") + "/train", first).status, 0);
  fs::copy(first, out, fs::copy_options::recursive);
  fs::remove(out + "/ddace-output.txt");
  const auto before = fileTree(out);
  const ToolRun r = train(data("task1") + "/train", out, "--force");
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_NE(r.out.find(out + "/manifest.yaml (not written by ddace train)"), std::string::npos) << r.out;
  EXPECT_EQ(fileTree(out), before);
}

TEST(CliTrainOut, AnEarlierModelOfAnotherTaskIsReplacedOnlyWithForce) {
  const std::string out = root() + "/other_task";
  ToolRun r = train(data("task1") + "/train", out);
  ASSERT_EQ(r.status, 0) << r.out;
  const auto task1_model = fileTree(out);
  ASSERT_TRUE(task1_model.count("manifest.yaml") && task1_model.count("primitives.yaml"));

  r = train(data("task4") + "/train", out);
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_NE(r.out.find(out + ": holds the output of an earlier ddace train; --force replaces it"), std::string::npos)
      << r.out;
  EXPECT_EQ(fileTree(out), task1_model);

  r = train(data("task4") + "/train", out, "--force");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(fileBytes(out + "/task.yaml"), task1_model.at("task.yaml"));
  EXPECT_EQ(fileBytes(out + "/task.yaml"), fileBytes(data("task4") + "/train/task.yaml"));
  // The model that was replaced is gone whole: no temporary sibling is left.
  for (const auto& e : fs::directory_iterator(root()))
    EXPECT_EQ(e.path().filename().string().find(".other_task.tmp"), std::string::npos) << e.path();
}

TEST(CliTrainOut, ForceLeavesNoStaleFileOfTheOldModel) {
  // gnn writes no primitives.yaml: the old model's must not stay behind (ddace path would
  // serve the old primitives under the new model).
  const std::string out = root() + "/stale";
  ToolRun r = train(data("task4") + "/train", out);
  ASSERT_EQ(r.status, 0) << r.out;
  ASSERT_TRUE(fs::exists(out + "/primitives.yaml"));
  r = train(data("task4") + "/train", out, "--force --variant gnn");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_FALSE(fs::exists(out + "/primitives.yaml"));
  EXPECT_NE(fileBytes(out + "/manifest.yaml").find("gnn"), std::string::npos);
  // A file the user added to train's model is not train's to delete.
  std::ofstream(out + "/my_eval.json") << "{}";
  r = train(data("task4") + "/train", out, "--force");
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_NE(r.out.find(out + "/my_eval.json (not written by ddace train)"), std::string::npos) << r.out;
  EXPECT_EQ(fileBytes(out + "/my_eval.json"), "{}");
  EXPECT_FALSE(fs::exists(out + "/primitives.yaml"));
}

TEST(CliTrainOut, AnEditedModelFileIsNotReplaced) {
  const std::string out = root() + "/edited";
  ASSERT_EQ(train(data("task1") + "/train", out).status, 0);
  std::ofstream(out + "/task.yaml", std::ios::app) << "# my note\n";
  const auto before = fileTree(out);
  const ToolRun r = train(data("task1") + "/train", out, "--force");
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_NE(r.out.find(out + "/task.yaml (changed since ddace train wrote it)"), std::string::npos) << r.out;
  EXPECT_EQ(fileTree(out), before);
}

TEST(CliTrainOut, GeneratesOutputIsNotTrainsToReplace) {
  const std::string out = root() + "/gen_as_model";
  ASSERT_EQ(runTool("generate task1 --out '" + out + "' --train 2 --test 1").status, 0);
  const auto before = fileTree(out);
  const ToolRun r = train(data("task1") + "/train", out, "--force");
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_NE(r.out.find(out + "/train/task.yaml (written by ddace generate, not ddace train)"), std::string::npos)
      << r.out;
  EXPECT_EQ(fileTree(out), before);
}

TEST(CliTrainOut, NeverWritesIntoTheTrainingDirectory) {
  // A hand-written task directory with a comment: `train own --out own` used to rewrite
  // own/task.yaml, dropping the comment.
  const std::string own = root() + "/own";
  fs::copy(data("task1") + "/train", own, fs::copy_options::recursive);
  fs::remove(own + "/ddace-output.txt");
  std::ofstream(own + "/task.yaml", std::ios::app) << "# recorded on the lab table\n";
  const auto before = fileTree(own);
  for (const std::string& out : {own, own + "/../own/", own + "/model", root()}) {
    const ToolRun r = train(own, out, "--force");
    EXPECT_NE(r.status, 0) << out << ": " << r.out;
    EXPECT_NE(r.out.find("training directory " + own + ": train writes the model into a directory of its own"),
              std::string::npos)
        << r.out;
    EXPECT_EQ(fileTree(own), before) << out;
  }
  // generate's output given as TASKDIR (train uses its train/ half): neither half is written.
  const std::string gen = data("task1");
  const auto gen_before = fileTree(gen);
  for (const std::string& out : {gen, gen + "/test"}) {
    const ToolRun r = train(gen, out, "--force");
    EXPECT_NE(r.status, 0) << out << ": " << r.out;
    EXPECT_EQ(fileTree(gen), gen_before) << out;
  }
}

TEST(CliTrainOut, AKilledRunLeavesTheOldModelAndTheNextRunClearsItsTemporary) {
  const std::string out = root() + "/killed";
  ASSERT_EQ(train(data("task1") + "/train", out).status, 0);
  const auto before = fileTree(out);
  // A long run killed while it trains (its temporary sibling exists).
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    const std::string t = toolPath().string(), task = data("task1") + "/train";
    ::execl(t.c_str(), t.c_str(), "train", task.c_str(), "--out", out.c_str(), "--epochs", "100000", "--patience",
            "100000", "--force", "--quiet", static_cast<char*>(nullptr));
    ::_exit(127);
  }
  auto temporaries = [&] {
    int n = 0;
    for (const auto& e : fs::directory_iterator(root()))
      n += e.path().filename().string().rfind(".killed.tmp-", 0) == 0;
    return n;
  };
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (temporaries() == 0 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ASSERT_EQ(temporaries(), 1) << "the run never started writing";
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // into training
  ::kill(pid, SIGKILL);
  int status = 0;
  ::waitpid(pid, &status, 0);
  EXPECT_EQ(fileTree(out), before);
  EXPECT_EQ(temporaries(), 1);  // what the killed run left
  // The next run replaces the model and removes the dead run's temporary.
  const ToolRun r = train(data("task1") + "/train", out, "--force --seed 3");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(temporaries(), 0);
  EXPECT_TRUE(fs::exists(out + "/manifest.yaml"));
}

TEST(CliTrain, HelpPrintsTheUsageWithEveryLearningRuleToSwitchOff) {
  // `ddace train --help` is the reference a user reads for --without: every rule of the
  // scene network is named there (the usage once missed 'ensemble').
  const ToolRun run = runTool("train --help");
  EXPECT_EQ(run.status, 0) << run.out;
  EXPECT_NE(run.out.find("ddace train TASKDIR --out MODELDIR"), std::string::npos) << run.out;
  const size_t without = run.out.find("--without ");
  ASSERT_NE(without, std::string::npos) << run.out;
  const std::string list = run.out.substr(without, run.out.find(']', without) - without);
  for (const ddace::tgn::Rule r : ddace::tgn::allRules())
    EXPECT_NE(list.find(ddace::tgn::toString(r)), std::string::npos) << ddace::tgn::toString(r) << " in " << list;
}

TEST(CliTrain, HelpAfterTheArgumentsPrintsTheUsageAndDoesNothing) {
  // A user appends --help to the line that failed: the usage, exit 0, and nothing trained
  // or written.
  const fs::path out = fs::temp_directory_path() / "ddace_cli_help_after_args";
  fs::remove_all(out);
  const ToolRun run = runTool("train no/such/taskdir --out " + out.string() + " --help");
  EXPECT_EQ(run.status, 0) << run.out;
  EXPECT_NE(run.out.find("usage: ddace train TASKDIR --out MODELDIR"), std::string::npos) << run.out;
  EXPECT_FALSE(fs::exists(out));
  const ToolRun short_form = runTool("generate nearest_goal -h");
  EXPECT_EQ(short_form.status, 0) << short_form.out;
  EXPECT_NE(short_form.out.find("usage: ddace generate"), std::string::npos) << short_form.out;
}

TEST(CliGenerate, RefusesASettingTheFamilyWouldIgnore) {
  // --robots is task2's team size: given to nearest_goal it once generated 3 robots
  // silently; it is refused, naming the flag, and nothing is written.
  const fs::path out = fs::temp_directory_path() / "ddace_cli_generate_ignored";
  fs::remove_all(out);
  const ToolRun robots = runTool("generate nearest_goal --robots 11 --out " + out.string());
  EXPECT_NE(robots.status, 0) << robots.out;
  EXPECT_NE(robots.out.find("--robots applies to task2 (the team size of the scalability study) and zoo rules only"),
            std::string::npos)
      << robots.out;
  const ToolRun actions = runTool("generate task1 --actions 3 --out " + out.string());
  EXPECT_NE(actions.status, 0) << actions.out;
  EXPECT_NE(actions.out.find("--actions applies to task3 only"), std::string::npos) << actions.out;
  EXPECT_FALSE(fs::exists(out));
  const ToolRun task2 = runTool("generate task2 --robots 4 --train 1 --test 0 --out " + out.string());
  EXPECT_EQ(task2.status, 0) << task2.out;
  fs::remove_all(out);
}

TEST(CliGenerate, AZooRuleWithOtherCountsIsTheSameTask) {
  // The rule a model was trained on, with other numbers of robots and goals: the same task
  // name (what `ddace eval` binds by kind), the counts asked for; a count below 1 refused.
  namespace task = ddace::task;
  const fs::path own = fs::temp_directory_path() / "ddace_cli_generate_zoo_own";
  const fs::path five = fs::temp_directory_path() / "ddace_cli_generate_zoo_five";
  const ToolRun a = runTool("generate zoo:37 --train 1 --test 0 --force --out " + own.string());
  ASSERT_EQ(a.status, 0) << a.out;
  const ToolRun b = runTool("generate zoo:37 --robots 5 --goals 6 --train 1 --test 0 --force --out " + five.string());
  ASSERT_EQ(b.status, 0) << b.out;
  const task::TaskSpec mine = task::loadTaskDir((own / "train").string()).spec;
  const task::TaskSpec other = task::loadTaskDir((five / "train").string()).spec;
  EXPECT_EQ(other.name, mine.name);
  const auto count = [&](task::EntityKind k) {
    return std::count_if(other.entities.begin(), other.entities.end(),
                         [&](const task::Entity& e) { return e.kind == k; });
  };
  EXPECT_EQ(count(task::EntityKind::Robot), 5);
  EXPECT_EQ(count(task::EntityKind::Goal), 6);
  const ToolRun zero = runTool("generate zoo:37 --robots 0 --out " + five.string() + "_0");
  EXPECT_NE(zero.status, 0) << zero.out;
  EXPECT_NE(zero.out.find("--robots must be between 1 and 64"), std::string::npos) << zero.out;
  const ToolRun goals = runTool("generate task1 --goals 3 --out " + five.string() + "_1");
  EXPECT_NE(goals.out.find("--goals applies to a zoo rule only"), std::string::npos) << goals.out;
  fs::remove_all(own);
  fs::remove_all(five);
}

TEST(CliTrain, ThreadsAreCheckedAndRecordedAndWhatTheModelTransfersIsPrinted) {
  const ToolRun none = train(data("task1") + "/train", root() + "/threads0", "--threads 0");
  EXPECT_NE(none.status, 0) << none.out;
  EXPECT_NE(none.out.find("threads"), std::string::npos) << none.out;
  EXPECT_FALSE(fs::exists(root() + "/threads0/manifest.yaml"));
  const ToolRun two = train(data("task1") + "/train", root() + "/threads2", "--threads 2");
  ASSERT_EQ(two.status, 0) << two.out;
  std::ifstream manifest(root() + "/threads2/manifest.yaml");
  const std::string text((std::istreambuf_iterator<char>(manifest)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("threads: 2"), std::string::npos);
  // Task 1 is a fixed order: the model runs on its own task's entities only, and says why.
  EXPECT_NE(two.out.find("transfer: runs on its own task's entities only"), std::string::npos) << two.out;
  EXPECT_NE(text.find("transfer: \"its own task's entities only"), std::string::npos);
  // The network's hyper-parameters are no flags.
  const ToolRun lr = train(data("task1") + "/train", root() + "/lr", "--lr 0.01");
  EXPECT_NE(lr.status, 0) << lr.out;
  EXPECT_NE(lr.out.find("--lr"), std::string::npos) << lr.out;
}

// Each of train's flags has the effect its usage names, in what it prints and the model it writes.
namespace {

/// `ddace train` of `family`'s small training set into root()/NAME with `flags` (and nothing else).
ToolRun trainWith(const std::string& family, const std::string& name, const std::string& flags) {
  return runTool("train '" + data(family) + "/train' --out '" + root() + "/" + name + "' " + flags);
}

/// What a training run printed and the model it wrote.
struct Trained {
  ToolRun run;
  ddace::tgn::ModelInfo info;
};

/// trainWith, expected to succeed: a failed run is a test failure (and an empty model).
Trained trained(const std::string& family, const std::string& name, const std::string& flags) {
  Trained t{trainWith(family, name, flags), {}};
  if (t.run.status != 0) ADD_FAILURE() << "train " << name << " " << flags << " failed:\n" << t.run.out;
  else t.info = ddace::tgn::SequenceModel::load(root() + "/" + name).info();
  return t;
}

bool says(const ToolRun& r, const std::string& text) {
  return r.out.find(text) != std::string::npos;
}

/// trainWith, expected to be refused with `message` in its output and no model written.
void expectRefused(const std::string& family, const std::string& name, const std::string& flags,
                   const std::string& message) {
  const ToolRun r = trainWith(family, name, flags);
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_TRUE(says(r, message)) << "expected '" << message << "' in:\n" << r.out;
  EXPECT_FALSE(fs::exists(root() + "/" + name + "/manifest.yaml"));
}

}  // namespace

TEST(CliTrainFlags, EpochsBoundTheRunAndQuietLeavesOutTheEpochLines) {
  const Trained loud = trained("task1", "epochs3", "--epochs 3");
  EXPECT_TRUE(says(loud.run, "epoch 1/3 ")) << loud.run.out;
  EXPECT_TRUE(says(loud.run, "epoch 3/3 ")) << loud.run.out;
  EXPECT_TRUE(says(loud.run, "stopped after 3 epochs (max_epochs)")) << loud.run.out;
  EXPECT_EQ(loud.info.history.size(), 3u);
  const Trained quiet = trained("task1", "quiet", "--epochs 3 --quiet");
  EXPECT_FALSE(says(quiet.run, "epoch 1/3")) << quiet.run.out;
  EXPECT_TRUE(says(quiet.run, "stopped after 3 epochs (max_epochs)")) << quiet.run.out;
}

TEST(CliTrainFlags, PatienceIsHowLongALossPlateauLastsBeforeTrainingStops) {
  // The same run stops at a plateau with a short patience, and runs to --epochs with one
  // longer than half of them (a plateau needs twice the patience in epochs).
  const Trained brief = trained("task1", "patience2", "--epochs 120 --patience 2 --quiet");
  EXPECT_EQ(brief.info.stop_reason, "plateau") << brief.run.out;
  EXPECT_LT(brief.info.history.size(), 120u);
  EXPECT_EQ(brief.info.options.plateau_patience, 2);
  const Trained long_one = trained("task1", "patience61", "--epochs 120 --patience 61 --quiet");
  EXPECT_EQ(long_one.info.stop_reason, "max_epochs") << long_one.run.out;
  EXPECT_EQ(long_one.info.history.size(), 120u);
}

TEST(CliTrainFlags, ASeedMakesTheSameWeightsAndAnotherSeedOthers) {
  for (const std::string name : {"seed5a", "seed5b", "seed6"})
    trained("task1", name, "--epochs 2 --quiet --seed " + name.substr(4, 1));
  EXPECT_EQ(ddace::tgn::SequenceModel::load(root() + "/seed5a").info().options.seed, 5u);
  EXPECT_EQ(fileBytes(root() + "/seed5a/weights.pt"), fileBytes(root() + "/seed5b/weights.pt"));
  EXPECT_NE(fileBytes(root() + "/seed5a/weights.pt"), fileBytes(root() + "/seed6/weights.pt"));
  expectRefused("task1", "seed_negative", "--epochs 2 --seed -1", "option --seed: must be non-negative");
}

TEST(CliTrainFlags, WithoutSwitchesOffTheRulesItNames) {
  // nearest_goal's rule is stated by the scene: by default an ensemble with the relative
  // features; --without ensemble trains one network,
  // --without relative a model of its own task's entities only.
  const Trained usual = trained("nearest_goal", "rules_all", "--epochs 2 --quiet");
  EXPECT_EQ(usual.info.plan.ensemble, ddace::tgn::kEnsembleMembers);
  EXPECT_TRUE(usual.info.plan.relative_features);
  const Trained one = trained("nearest_goal", "rules_one", "--epochs 2 --quiet --without ensemble");
  EXPECT_EQ(one.info.plan.ensemble, 1);
  EXPECT_TRUE(one.info.plan.relative_features);
  const Trained named = trained("nearest_goal", "rules_named", "--epochs 2 --quiet --without relative,ensemble");
  EXPECT_FALSE(named.info.plan.relative_features);
  EXPECT_TRUE(says(named.run, "transfer: runs on its own task's entities only: trained without the relative features"))
      << named.run.out;
  expectRefused("nearest_goal", "rules_unknown", "--epochs 2 --without ensembles", "option --without: ");
}

TEST(CliTrainFlags, VariantChoosesTheNetwork) {
  const Trained paper = trained("task4", "variant_paper", "--epochs 2 --quiet --variant paper");
  EXPECT_EQ(paper.info.variant, ddace::tgn::Variant::Paper);
  EXPECT_TRUE(says(paper.run, "training variant 'paper'")) << paper.run.out;
  EXPECT_TRUE(says(paper.run, "motion primitives: ")) << paper.run.out;
  // gnn rolls out motions itself: no GP primitives are fitted.
  const Trained gnn = trained("task4", "variant_gnn", "--epochs 2 --quiet --variant gnn");
  EXPECT_EQ(gnn.info.variant, ddace::tgn::Variant::Gnn);
  EXPECT_FALSE(says(gnn.run, "motion primitives: ")) << gnn.run.out;
  EXPECT_FALSE(fs::exists(root() + "/variant_gnn/primitives.yaml"));
  expectRefused("task4", "variant_unknown", "--epochs 2 --variant big", "option --variant: ");
}
