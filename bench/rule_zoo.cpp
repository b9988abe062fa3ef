// bench_rule_zoo: how many of the rules people state the sequence model learns. Trains the
// default model (`ddace train` defaults) on a sample of the rule zoo (tasks/rule_zoo.h) at
// 10 and 20 demonstrations and evaluates it in closed loop (`ddace eval` defaults, ideal
// execution) on fresh scenes of each rule; reports the distribution of OSR over the rules
// (median, 10th percentile, the worst rules by name, by template) into docs/bench/rule_zoo.md.
//
//   bench_rule_zoo [--rules N=50] [--test M=20] [--every K=1] [--seed S=1] [--without LIST] [--repo DIR]
//
// --seed: the training seed (the data's are fixed); --without: learning rules switched
// off as `ddace train --without` (for measuring what a rule does across the zoo).
//
// The sample is every K-th of the first N*K distinct rules (distinctZooRules). A full run
// (50 rules, two sizes) trains 100 models: on the order of an hour on two cores.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <sstream>
#include <thread>

#include "ddace/common/error.h"
#include "ddace/common/machine.h"
#include "ddace/pipeline/evaluation.h"
#include "ddace/tasks/rule_zoo.h"
#include "results.h"

namespace fs = std::filesystem;
using namespace ddace;

namespace {

struct Result {
  tasks::ZooRule rule;
  std::map<int, double> osr;  ///< by training demonstrations
  std::map<int, double> seconds;
};

std::string fmt(double v, int digits = 2) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

long intFlag(int& i, int argc, char** argv) {
  if (i + 1 >= argc) throw Error(std::string(argv[i]) + " needs a positive integer");
  char* end = nullptr;
  const long v = std::strtol(argv[++i], &end, 10);
  if (*end != '\0' || v < 1) throw Error(std::string(argv[i - 1]) + " needs a positive integer, not '" + argv[i] + "'");
  return v;
}

}  // namespace

int main(int argc, char** argv) try {
  const fs::path repo = bench::repositoryFromArgs(argc, argv);
  long rules = 50, test_demos = 20, every = 1, seed = 1;
  tgn::TrainOptions options;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--rules") {
      rules = intFlag(i, argc, argv);
    } else if (a == "--test") {
      test_demos = intFlag(i, argc, argv);
    } else if (a == "--every") {
      every = intFlag(i, argc, argv);
    } else if (a == "--seed") {
      seed = intFlag(i, argc, argv);
    } else if (a == "--without") {
      if (i + 1 >= argc) throw Error("--without needs a list of rule names");
      options.without = tgn::rulesFromList(argv[++i]);
    } else {
      throw Error("unknown argument '" + a +
                  "' (bench_rule_zoo [--rules N] [--test M] [--every K] [--seed S] [--without LIST] [--repo DIR])");
    }
  }
  options.seed = static_cast<uint64_t>(seed);
  const std::vector<int> sizes = {10, 20};
  const std::vector<uint64_t> distinct = tasks::distinctZooRules(static_cast<int>(rules * every));
  const fs::path scratch = fs::temp_directory_path() / ("ddace_bench_rule_zoo_" + std::to_string(getpid()));
  const auto start = std::chrono::steady_clock::now();
  // One rule trained at every size and evaluated on its own test scenes.
  const auto measure = [&](uint64_t id) {
    Result r;
    r.rule = tasks::zooRule(id);
    // Test scenes from a stream of their own, as `ddace generate` draws them.
    const task::TaskDir test = tasks::generateZoo(id, static_cast<int>(test_demos), 1 * 2654435761ULL + 0x7e57);
    for (int demos : sizes) {
      const task::TaskDir train = tasks::generateZoo(id, demos, 1);
      const auto t0 = std::chrono::steady_clock::now();
      const pipeline::Model model =
          pipeline::trainModel(train, options, (scratch / std::to_string(demos)).string(), nullptr);
      r.seconds[demos] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      r.osr[demos] = pipeline::evaluate(model, test, {}).summary.osr;
      fs::remove_all(scratch / std::to_string(demos));
    }
    return r;
  };
  std::vector<Result> results;
  for (size_t k = 0; k < distinct.size(); k += static_cast<size_t>(every)) {
    Result r = measure(distinct[k]);
    std::cout << "zoo " << r.rule.id << " " << r.rule.name << ": OSR " << fmt(r.osr[10]) << " (10), " << fmt(r.osr[20])
              << " (20)\n"
              << std::flush;
    results.push_back(r);
  }
  // The kinds of task users name, each its zoo rule (rule_zoo.h, userKinds), as the rules above.
  std::vector<std::pair<tasks::ZooKind, Result>> kinds;
  for (const tasks::ZooKind& kind : tasks::userKinds()) {
    uint64_t id = 0;
    tasks::parseZooFamily(kind.family, id);
    Result r = measure(id);
    std::cout << kind.family << " " << kind.kind << ": OSR " << fmt(r.osr[10]) << " (10), " << fmt(r.osr[20])
              << " (20)\n"
              << std::flush;
    kinds.push_back({kind, r});
  }
  fs::remove_all(scratch);
  const double minutes = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / 60;

  std::ostringstream md;
  md << "# Rule zoo\n\n"
     << "Written by `ddace bench rule_zoo` (bench/rule_zoo.cpp). The default model (`ddace train` defaults) "
     << "trained on " << results.size() << " rules of the rule zoo (every " << every << (every == 1 ? "st" : "th")
     << " of the first " << distinct.size() << " distinct rules, docs/tgn.md) at 10 and 20 demonstrations, "
     << "evaluated in closed loop (`ddace eval` defaults) on " << test_demos << " fresh scenes per rule. "
     << "Training seed " << seed;
  if (!options.without.empty()) {
    md << ", without";
    for (tgn::Rule r : options.without) md << " " << tgn::toString(r);
  }
  md << ". "
     << "Run: " << utcNow() << ", " << fmt(minutes, 1) << " min, " << std::thread::hardware_concurrency()
     << "-core machine (1-minute load average " << loadAverage() << " at the end).\n\n";
  md << "| demonstrations | rules | median OSR | 10th percentile | mean | rules at OSR >= 0.9 "
        "|\n|---|---|---|---|---|---|\n";
  for (int demos : sizes) {
    std::vector<double> v;
    for (const auto& r : results) v.push_back(r.osr.at(demos));
    const tasks::OsrDistribution d = tasks::osrDistribution(v);
    md << "| " << demos << " | " << d.rules << " | " << fmt(d.median) << " | " << fmt(d.p10) << " | " << fmt(d.mean)
       << " | " << d.at_least_0_9 << " |\n";
  }
  md << "\n## By template (median OSR at 20 demonstrations)\n\n| template | rules | median at 10 | median at 20 |\n"
        "|---|---|---|---|\n";
  std::map<std::string, std::vector<const Result*>> by_kind;
  for (const auto& r : results) by_kind[r.rule.kind].push_back(&r);
  for (const auto& [kind, rs] : by_kind) {
    std::vector<double> a, b;
    for (const Result* r : rs) a.push_back(r->osr.at(10)), b.push_back(r->osr.at(20));
    md << "| " << kind << " | " << rs.size() << " | " << fmt(tasks::osrDistribution(a).median) << " | "
       << fmt(tasks::osrDistribution(b).median) << " |\n";
  }
  std::vector<const Result*> sorted;
  for (const auto& r : results) sorted.push_back(&r);
  std::stable_sort(sorted.begin(), sorted.end(), [](const Result* x, const Result* y) {
    return x->osr.at(20) + x->osr.at(10) < y->osr.at(20) + y->osr.at(10);
  });
  md << "\n## Every rule, worst first\n\n| rule | OSR at 10 | OSR at 20 | training at 20, s |\n|---|---|---|---|\n";
  for (const Result* r : sorted)
    md << "| zoo:" << r->rule.id << " " << r->rule.name << " | " << fmt(r->osr.at(10)) << " | " << fmt(r->osr.at(20))
       << " | " << fmt(r->seconds.at(20), 1) << " |\n";
  md << "\n## Kinds of task users name\n\nEach kind as the zoo rule that states it (rule_zoo.h, `userKinds`; goal: "
        "OSR >= 0.9 at 20 demonstrations), trained and evaluated as the rules above.\n\n"
        "| kind | zoo rule | OSR at 10 | OSR at 20 | training at 20, s |\n|---|---|---|---|---|\n";
  for (const auto& [kind, r] : kinds)
    md << "| " << kind.kind << " | " << kind.family << " " << r.rule.name << " | " << fmt(r.osr.at(10)) << " | "
       << fmt(r.osr.at(20)) << " | " << fmt(r.seconds.at(20), 1) << " |\n";
  bench::writeResults(repo, "rule_zoo", md.str());
  return 0;
} catch (const std::exception& e) {
  std::cerr << "bench_rule_zoo: error: " << e.what() << "\n";
  return 1;
}
