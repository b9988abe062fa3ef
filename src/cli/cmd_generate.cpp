// ddace generate: the task families as task directories.
#include <filesystem>
#include <iostream>

#include "command.h"
#include "ddace/tasks/generators.h"
#include "ddace/tasks/rule_zoo.h"

namespace ddace::cli {
namespace {

/// DIR as a whole: refused when it holds anything generate did not write; its own
/// earlier output is replaced (--force) in one step, or not at all.
void writeSplit(const std::string& out, const task::TaskDir& train_dir, const task::TaskDir& test_dir, bool force) {
  std::vector<task::OwnedFile> files = task::taskDirFiles(train_dir, "train/");
  const std::vector<task::OwnedFile> test_files = task::taskDirFiles(test_dir, "test/");
  files.insert(files.end(), test_files.begin(), test_files.end());
  task::writeOwnedDirectory(out, files, "ddace generate", force);
}

int runGenerate(const std::vector<std::string>& argv) {
  Args args(argv,
            {"--out", "--train", "--test", "--seed", "--robots", "--goals", "--objects", "--actions", "--jitter",
             "--mislabel", "--onset-jitter"},
            {"--force"});
  args.expectAtMostPositional(1);
  tasks::GeneratorOptions o;
  std::string names;
  for (const auto& f : tasks::allFamilies()) names += (names.empty() ? "" : ", ") + f;
  o.family = args.positional(0, "FAMILY (" + names + ", zoo:<id>)");
  const std::string out = args.require("--out");
  const long train = args.getInt("--train", 30), test = args.getInt("--test", 15);
  if (train < 1) throw Error("--train must be at least 1");
  if (test < 0) throw Error("--test must not be negative");
  const long seed = args.getInt("--seed", 1);
  if (seed < 0) throw Error("--seed must not be negative");
  o.seed = static_cast<uint64_t>(seed);
  uint64_t zoo_rule = 0;
  tasks::ZooMotion zoo_motion;
  if (tasks::parseZooFamily(o.family, zoo_rule, &zoo_motion)) {
    // A rule of the zoo (rule_zoo.h): clean demonstrations; the family options do not apply.
    // --robots, --goals, --objects state the same rule with other counts (a model trained at
    // the rule's own counts runs on them: docs/tgn.md, "Other team sizes").
    for (const char* flag : {"--actions", "--jitter", "--mislabel", "--onset-jitter"})
      if (args.has(flag)) throw Error(std::string(flag) + " does not apply to a zoo rule (" + o.family + ")");
    tasks::ZooCounts counts;
    for (auto [flag, count] :
         {std::pair{"--robots", &counts.robots}, {"--goals", &counts.goals}, {"--objects", &counts.objects}}) {
      const long n = args.getInt(flag, 0);
      if (args.has(flag) && (n < 1 || n > 64)) throw Error(std::string(flag) + " must be between 1 and 64");
      *count = static_cast<int>(n);
    }
    const task::TaskDir train_dir = tasks::generateZoo(zoo_rule, static_cast<int>(train), o.seed, zoo_motion, counts);
    const task::TaskDir test_dir =
        tasks::generateZoo(zoo_rule, static_cast<int>(test), o.seed * 2654435761ULL + 0x7e57, zoo_motion, counts);
    writeSplit(out, train_dir, test_dir, args.has("--force"));
    std::cout << "generated " << o.family << " '" << train_dir.spec.name << "': " << train
              << " training demonstrations in " << out << "/train, " << test << " test in " << out << "/test\n";
    return 0;
  }
  // The team size and the vocabulary are task2's and task3's case-study settings: given to
  // another family they would change nothing, so they are refused rather than ignored.
  for (const char* flag : {"--goals", "--objects"})
    if (args.has(flag)) throw Error(std::string(flag) + " applies to a zoo rule only, not to " + o.family);
  if (args.has("--robots") && o.family != "task2")
    throw Error("--robots applies to task2 (the team size of the scalability study) and zoo rules only, not to " +
                o.family);
  if (args.has("--actions") && o.family != "task3")
    throw Error("--actions applies to task3 only (the vocabulary size study), not to " + o.family);
  o.robots = static_cast<int>(args.getInt("--robots", 11));
  o.actions = static_cast<int>(args.getInt("--actions", 4));
  o.jitter_m = args.getDouble("--jitter", 0.0);
  o.mislabel_fraction = args.getDouble("--mislabel", 0.0);
  o.onset_jitter_s = args.getDouble("--onset-jitter", 0.0);

  o.demos = static_cast<int>(train);
  const task::TaskDir train_dir = tasks::generate(o);
  // Test configurations come from their own stream and are clean: imperfections
  // (--jitter, --mislabel, --onset-jitter) only affect what is learned from.
  o.demos = static_cast<int>(test);
  o.seed = o.seed * 2654435761ULL + 0x7e57;
  o.jitter_m = 0;
  o.mislabel_fraction = 0;
  o.onset_jitter_s = 0;
  const task::TaskDir test_dir = tasks::generate(o);

  writeSplit(out, train_dir, test_dir, args.has("--force"));
  const std::string train_path = (std::filesystem::path(out) / "train").string();
  const std::string test_path = (std::filesystem::path(out) / "test").string();
  std::cout << "generated " << o.family << " '" << train_dir.spec.name << "': " << train
            << " training demonstrations in " << train_path << ", " << test << " test in " << test_path << "\n";
  return 0;
}

DDACE_COMMAND(
    {"generate",
     "ddace generate FAMILY|zoo:ID --out DIR [--force] [--train N] [--test M] [--seed S] [--robots K] "
     "[--goals K] [--objects K] [--actions K] [--jitter SIGMA_M] [--mislabel FRACTION] [--onset-jitter SECONDS]",
     "write DIR/train and DIR/test task directories of a task family (task1..task4, fetch, "
     "nearest_goal, queue, deliver) or of rule <id> of the rule zoo (zoo:<id>, docs/tgn.md; zoo:<id>/direct "
     "or /direct-<N>mm: paths bent around "
     "nothing, stops N mm short of contact; --robots, --goals, --objects: the rule with other counts)",
     runGenerate});

}  // namespace
}  // namespace ddace::cli
