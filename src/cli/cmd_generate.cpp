// ddace generate: the paper's task families as task directories.
#include <filesystem>
#include <iostream>

#include "command.h"
#include "ddace/tasks/generators.h"

namespace ddace::cli {
namespace {

int runGenerate(const std::vector<std::string>& argv) {
  Args args(argv, {"--out", "--train", "--test", "--seed", "--robots", "--actions", "--jitter", "--mislabel"});
  args.expectAtMostPositional(1);
  tasks::GeneratorOptions o;
  o.family = args.positional(0, "FAMILY (task1, task2, task3 or task4)");
  const std::string out = args.require("--out");
  const long train = args.getInt("--train", 30), test = args.getInt("--test", 15);
  if (train < 1) throw Error("--train must be at least 1");
  if (test < 0) throw Error("--test must not be negative");
  const long seed = args.getInt("--seed", 1);
  if (seed < 0) throw Error("--seed must not be negative");
  o.seed = static_cast<uint64_t>(seed);
  o.robots = static_cast<int>(args.getInt("--robots", 11));
  o.actions = static_cast<int>(args.getInt("--actions", 4));
  o.jitter_m = args.getDouble("--jitter", 0.0);
  o.mislabel_fraction = args.getDouble("--mislabel", 0.0);

  o.demos = static_cast<int>(train);
  const task::TaskDir train_dir = tasks::generate(o);
  // Test configurations come from their own stream and are clean: imperfections
  // (--jitter, --mislabel) only affect what is learned from.
  o.demos = static_cast<int>(test);
  o.seed = o.seed * 2654435761ULL + 0x7e57;
  o.jitter_m = 0;
  o.mislabel_fraction = 0;
  const task::TaskDir test_dir = tasks::generate(o);

  const std::string train_path = (std::filesystem::path(out) / "train").string();
  const std::string test_path = (std::filesystem::path(out) / "test").string();
  task::writeTaskDir(train_dir, train_path);
  task::writeTaskDir(test_dir, test_path);
  std::cout << "generated " << o.family << " '" << train_dir.spec.name << "': " << train
            << " training demonstrations in " << train_path << ", " << test << " test in "
            << test_path << "\n";
  return 0;
}

DDACE_COMMAND({"generate",
               "ddace generate {task1,task2,task3,task4} --out DIR [--train N] [--test M] [--seed S] "
               "[--robots K] [--actions K] [--jitter SIGMA_M] [--mislabel FRACTION]",
               "write DIR/train and DIR/test task directories of one of the paper's task families",
               runGenerate});

}  // namespace
}  // namespace ddace::cli
