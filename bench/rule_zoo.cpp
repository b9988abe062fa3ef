// bench_rule_zoo: how many of the rules people state the sequence model learns, and how
// they run with bodies. Trains the default model (`ddace train` defaults) on a sample of the
// rule zoo (tasks/rule_zoo.h) at 10 and 20 demonstrations and evaluates it in closed loop
// (`ddace eval` defaults, ideal execution) on fresh scenes of each rule; reports the
// distribution of OSR over the rules (median, 10th percentile, the worst rules by name, by
// template) into docs/bench/rule_zoo.md. With bodies: at the largest size, each rule on two
// motion models (rule_zoo.h, ZooMotion: the generators' and a direct one, its stop gap
// cycling through directZooMotions() over the sample), trained and evaluated ideal and with
// bodies (`ddace eval --execution diffdrive --noise 0.002`): OSR, collisions, minimum
// clearance, FD, makespan, judged against the goals below.
//
//   bench_rule_zoo [--rules N=50] [--test M=20] [--every K=1] [--sizes LIST=10,20] [--seed S=1]
//                  [--without LIST] [--quick] [--repo DIR]
//
// --seed: the training seed (the data's are fixed); --without: learning rules switched
// off as `ddace train --without` (for measuring what a rule does across the zoo); --quick: a
// smoke test of the whole benchmark in seconds (2 rules, 3 demonstrations, 3 test scenes, at
// most 40 epochs, no kinds), its results printed, not written.
//
// The sample is every K-th of the first N*K distinct rules (distinctZooRules). A full run
// (50 rules, two sizes and the direct motion) trains 150 models: over an hour on two cores.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <thread>

#include "ddace/common/error.h"
#include "ddace/common/machine.h"
#include "ddace/pipeline/evaluation.h"
#include "ddace/task/body_geometry.h"
#include "ddace/tasks/rule_zoo.h"
#include "results.h"

namespace fs = std::filesystem;
using namespace ddace;

namespace {

/// One rule on one motion model at one size, ideal and with bodies.
struct WithBodies {
  tasks::ZooMotion motion;
  eval::Summary ideal, bodies;
  int deadlocked_trials = 0;  ///< with bodies: trials a robot of which was reported deadlocked
  /// With bodies: why each trial that succeeded ideal failed ("scene 3: collision at 5.3 s: R1
  /// touched R2"), printed while the benchmark runs.
  std::vector<std::string> lost;
};

struct Result {
  tasks::ZooRule rule;
  std::map<int, double> osr;  ///< by training demonstrations
  std::map<int, double> seconds;
  std::vector<WithBodies> bodies;  ///< the generators' motion, then the direct one
  std::string undrawable;          ///< why the direct motion has no demonstrations of it ("": it has)
};

constexpr double kBodiesNoiseM = 0.002;  ///< as `ddace table`'s closed loop

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

/// The command line.
struct Options {
  long rules = 50, test_demos = 20, every = 1, seed = 1;
  std::vector<int> sizes = {10, 20};  ///< training demonstrations, ascending
  bool quick = false;
  tgn::TrainOptions train;
  /// The size at which the rules are also run with bodies: the largest.
  int bodiesSize() const { return sizes.back(); }
};

/// --sizes' list, e.g. "10,20": sorted, without repeats.
std::vector<int> parseSizes(const std::string& list) {
  std::vector<int> sizes;
  std::stringstream items(list);
  for (std::string item; std::getline(items, item, ',');) {
    char* end = nullptr;
    const long n = std::strtol(item.c_str(), &end, 10);
    if (item.empty() || *end != '\0' || n < 1 || n > 1000)
      throw Error("--sizes: '" + item + "' is not a number of demonstrations (1 to 1000)");
    sizes.push_back(static_cast<int>(n));
  }
  if (sizes.empty()) throw Error("--sizes needs at least one demonstration count");
  std::sort(sizes.begin(), sizes.end());
  sizes.erase(std::unique(sizes.begin(), sizes.end()), sizes.end());
  return sizes;
}

Options parseOptions(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--rules") {
      o.rules = intFlag(i, argc, argv);
    } else if (a == "--test") {
      o.test_demos = intFlag(i, argc, argv);
    } else if (a == "--every") {
      o.every = intFlag(i, argc, argv);
    } else if (a == "--seed") {
      o.seed = intFlag(i, argc, argv);
    } else if (a == "--quick") {
      o.quick = true;
    } else if (a == "--sizes") {
      if (i + 1 >= argc) throw Error("--sizes needs a list of demonstration counts, e.g. 10,20");
      o.sizes = parseSizes(argv[++i]);
    } else if (a == "--without") {
      if (i + 1 >= argc) throw Error("--without needs a list of rule names");
      o.train.without = tgn::rulesFromList(argv[++i]);
    } else {
      throw Error("unknown argument '" + a +
                  "' (bench_rule_zoo [--rules N] [--test M] [--every K] [--sizes LIST] [--seed S] [--without LIST] "
                  "[--quick] [--repo DIR])");
    }
  }
  o.train.seed = static_cast<uint64_t>(o.seed);
  if (o.quick) {  // a smoke test of the benchmark, not its protocol
    o.rules = std::min(o.rules, 2L), o.test_demos = std::min(o.test_demos, 3L), o.every = 1;
    o.sizes = {3};
    o.train.max_epochs = 40;
  }
  return o;
}

/// One rule trained at every size and evaluated on its own test scenes; at the largest size
/// also with bodies, and on a direct motion (when given) ideal and with bodies.
class RuleRuns {
 public:
  RuleRuns(const Options& options, fs::path scratch) : o_(options), scratch_(std::move(scratch)) {}

  Result measure(uint64_t id, const std::optional<tasks::ZooMotion>& direct) const {
    Result r;
    r.rule = tasks::zooRule(id);
    // Test scenes from a stream of their own, as `ddace generate` draws them.
    const uint64_t test_seed = 1 * 2654435761ULL + 0x7e57;
    const task::TaskDir test = tasks::generateZoo(id, static_cast<int>(o_.test_demos), test_seed);
    for (int demos : o_.sizes) {
      const auto t0 = std::chrono::steady_clock::now();
      const pipeline::Model model = train(tasks::generateZoo(id, demos, 1), std::to_string(demos));
      r.seconds[demos] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      if (demos != o_.bodiesSize() || !direct) {
        r.osr[demos] = pipeline::evaluate(model, test, {}).summary.osr;
        continue;
      }
      r.bodies.push_back(evaluateBoth(model, test, tasks::ZooMotion{}));
      r.osr[demos] = r.bodies.back().ideal.osr;
    }
    if (direct) measureDirect(id, test_seed, *direct, r);
    return r;
  }

 private:
  pipeline::Model train(const task::TaskDir& data, const std::string& name) const {
    const pipeline::Model model = pipeline::trainModel(data, o_.train, (scratch_ / name).string(), nullptr);
    fs::remove_all(scratch_ / name);
    return model;
  }

  /// Ideal and with bodies, as `ddace table`'s section "Bodies" runs them.
  WithBodies evaluateBoth(const pipeline::Model& model, const task::TaskDir& test, const tasks::ZooMotion& m) const {
    WithBodies w;
    w.motion = m;
    pipeline::EvalOptions e;
    e.execution = "diffdrive";
    e.noise_m = kBodiesNoiseM;
    e.seed = static_cast<uint64_t>(o_.seed);
    const pipeline::Evaluation ideal = pipeline::evaluate(model, test, {});
    const pipeline::Evaluation bodies = pipeline::evaluate(model, test, e);
    w.ideal = ideal.summary;
    w.bodies = bodies.summary;
    for (size_t k = 0; k < bodies.trials.size(); ++k) {
      const std::vector<std::string> why = failureWords(bodies, k);
      if (std::any_of(why.begin(), why.end(),
                      [](const std::string& f) { return f.find("deadlock") != std::string::npos; }))
        ++w.deadlocked_trials;
      if (ideal.scores.at(k).success && !bodies.scores.at(k).success)
        for (const std::string& f : why) w.lost.push_back("scene " + std::to_string(k) + ": " + f);
    }
    return w;
  }

  /// One trial's failures with bodies, in words: collisions, stops, loads left short, the
  /// first step that differs from the demonstration.
  static std::vector<std::string> failureWords(const pipeline::Evaluation& e, size_t k) {
    std::vector<std::string> why;
    const exec::Trial& t = e.trials.at(k);
    for (const auto& c : t.body_report.collisions)
      why.push_back("collision at " + fmt(c.time_s) + " s: " + e.entity_names.at(c.a) + " touched " +
                    e.entity_names.at(c.b));
    why.insert(why.end(), t.failures.begin(), t.failures.end());
    for (const eval::ObjectLeftShort& o : e.scores.at(k).objects_left_short) why.push_back(o.describe());
    for (const auto& ex : t.executed)  // robots that stopped outside the arrival radius
      if (ex.token.isMotion() && e.robot_entities.count(ex.token.entity) &&
          !task::arrived(ex.executed.back(), ex.goal, e.arrival_radius_m))
        why.push_back("step " + std::to_string(ex.step + 1) + ": " + e.entity_names.at(ex.token.entity) + ":" +
                      ex.token.action + " stopped " + fmt((ex.executed.back() - ex.goal).norm() * 100, 1) +
                      " cm from its end point");
    if (k < e.first_difference.size() && !e.first_difference[k].empty()) why.push_back(e.first_difference[k]);
    if (!e.scores.at(k).goal_conditions_hold) why.push_back("goal conditions not met");
    return why;
  }

  /// The rule demonstrated and tested on the direct motion, into r.bodies (or r.undrawable).
  void measureDirect(uint64_t id, uint64_t test_seed, const tasks::ZooMotion& direct, Result& r) const {
    std::optional<task::TaskDir> direct_test, direct_train;
    try {
      direct_test = tasks::generateZoo(id, static_cast<int>(o_.test_demos), test_seed, direct);
      direct_train = tasks::generateZoo(id, o_.bodiesSize(), 1, direct);
    } catch (const Error& e) {  // no scene its bodies keep clear on straight paths and arcs
      r.undrawable = e.what();
    }
    if (direct_train) r.bodies.push_back(evaluateBoth(train(*direct_train, "direct"), *direct_test, direct));
  }

  const Options& o_;
  fs::path scratch_;
};

/// A rule's results in words, as printed while the benchmark runs.
std::string osrWords(const Result& r, const std::vector<int>& sizes) {
  std::string w = "OSR";
  for (int demos : sizes) w += " " + fmt(r.osr.at(demos)) + " (" + std::to_string(demos) + ")";
  for (const WithBodies& b : r.bodies)
    w += "; " + b.motion.words() + ": " + fmt(b.ideal.osr) + " ideal, " + fmt(b.bodies.osr) + " with bodies, " +
         std::to_string(b.bodies.collisions) + " collisions, " + std::to_string(b.deadlocked_trials) +
         " deadlocked trials";
  for (const WithBodies& b : r.bodies)
    for (const std::string& l : b.lost) w += "\n    " + b.motion.words() + ", " + l;
  return w;
}

std::string at(int n) {
  return " at " + std::to_string(n);
}

/// "10, 20 and 40".
std::string sizesWords(const std::vector<int>& sizes) {
  std::string w;
  for (size_t k = 0; k < sizes.size(); ++k)
    w += (k == 0 ? "" : k + 1 == sizes.size() ? " and " : ", ") + std::to_string(sizes[k]);
  return w;
}

/// The report's head: what ran, and the distribution of OSR over the rules at every size.
std::string head(const Options& o, size_t rules, size_t distinct, double minutes, const std::vector<Result>& results) {
  std::ostringstream md;
  md << "# Rule zoo\n\n"
     << (o.quick ? "**`--quick`: a smoke test of the benchmark (2 rules, 3 demonstrations, 3 test scenes, at most 40 "
                   "epochs); not its protocol, not its numbers.**\n\n"
                 : "")
     << "Written by `ddace bench rule_zoo" << (o.quick ? " --quick" : "")
     << "` (bench/rule_zoo.cpp). The default model (`ddace train` defaults) "
     << "trained on " << rules << " rules of the rule zoo (every " << o.every << (o.every == 1 ? "st" : "th")
     << " of the first " << distinct << " distinct rules, docs/tgn.md) at " << sizesWords(o.sizes)
     << " demonstrations, evaluated in closed loop (`ddace eval` defaults) on " << o.test_demos
     << " fresh scenes per rule. Training seed " << o.seed;
  if (!o.train.without.empty()) {
    md << ", without";
    for (tgn::Rule r : o.train.without) md << " " << tgn::toString(r);
  }
  md << ". "
     << "Run: " << utcNow() << ", " << fmt(minutes, 1) << " min, " << std::thread::hardware_concurrency()
     << "-core machine (1-minute load average " << loadAverage() << " at the end).\n\n";
  md << "| demonstrations | rules | median OSR | 10th percentile | mean | rules at OSR >= 0.9 "
        "|\n|---|---|---|---|---|---|\n";
  for (int demos : o.sizes) {
    std::vector<double> v;
    for (const auto& r : results) v.push_back(r.osr.at(demos));
    const tasks::OsrDistribution d = tasks::osrDistribution(v);
    md << "| " << demos << " | " << d.rules << " | " << fmt(d.median) << " | " << fmt(d.p10) << " | " << fmt(d.mean)
       << " | " << d.at_least_0_9 << " |\n";
  }
  return md.str();
}

/// Median OSR per template of rules, at every size.
std::string byTemplate(const std::vector<Result>& results, const std::vector<int>& sizes) {
  std::ostringstream md;
  md << "\n## By template (median OSR" << at(sizes.back()) << " demonstrations)\n\n| template | rules |";
  for (int demos : sizes) md << " median" << at(demos) << " |";
  md << "\n|---|---|";
  for (size_t k = 0; k < sizes.size(); ++k) md << "---|";
  md << "\n";
  std::map<std::string, std::vector<const Result*>> by_kind;
  for (const auto& r : results) by_kind[r.rule.kind].push_back(&r);
  for (const auto& [kind, rs] : by_kind) {
    md << "| " << kind << " | " << rs.size() << " |";
    for (int demos : sizes) {
      std::vector<double> v;
      for (const Result* r : rs) v.push_back(r->osr.at(demos));
      md << " " << fmt(tasks::osrDistribution(v).median) << " |";
    }
    md << "\n";
  }
  return md.str();
}

/// A table's header: `first` over `columns` columns, then OSR at every size and training time.
std::string osrHeader(const std::string& first, int columns, const std::vector<int>& sizes) {
  std::string h = "| " + first + " |", bars = "|";
  for (int k = 0; k < columns; ++k) bars += "---|";
  for (int demos : sizes) h += " OSR" + at(demos) + " |", bars += "---|";
  return h + " training" + at(sizes.back()) + ", s |\n" + bars + "---|\n";
}

/// A rule's cells under osrHeader.
std::string osrCells(const Result& r, const std::vector<int>& sizes) {
  std::string c;
  for (int demos : sizes) c += " " + fmt(r.osr.at(demos)) + " |";
  return c + " " + fmt(r.seconds.at(sizes.back()), 1) + " |\n";
}

/// Every rule, the worst (lowest OSR summed over the sizes) first.
std::string everyRule(const std::vector<Result>& results, const std::vector<int>& sizes) {
  const auto osrSum = [&](const Result* r) {
    double sum = 0;
    for (int demos : sizes) sum += r->osr.at(demos);
    return sum;
  };
  std::vector<const Result*> sorted;
  for (const auto& r : results) sorted.push_back(&r);
  std::stable_sort(sorted.begin(), sorted.end(),
                   [&](const Result* x, const Result* y) { return osrSum(x) < osrSum(y); });
  std::string md = "\n## Every rule, worst first\n\n" + osrHeader("rule", 1, sizes);
  for (const Result* r : sorted)
    md += "| zoo:" + std::to_string(r->rule.id) + " " + r->rule.name + " |" + osrCells(*r, sizes);
  return md;
}

std::string mm(double m) {
  return std::isfinite(m) ? fmt(m * 1000, 1) + " mm" : std::string("–");
}

/// With bodies: per motion model, bodies over ideal across the rules, against the goals.
std::string bodiesSummary(const std::vector<Result>& results, int bodies_size) {
  std::ostringstream md;
  md << "\n## With bodies\n\n"
     << "Each rule" << at(bodies_size)
     << " demonstrations on two motion models (rule_zoo.h, `ZooMotion`): the generators' (paths bent around bodies, "
        "stops touching) and a direct one (paths straight or arcs bent around nothing, a scene where a body would "
        "pass through another drawn again; stops touching, 4 mm and 1 cm short of contact in turn over the rules), "
        "trained on its own demonstrations and evaluated on its own fresh scenes, ideal and with bodies (`ddace eval "
        "--execution diffdrive --noise "
     << kBodiesNoiseM
     << "`, the filter on: docs/results.md, \"Bodies\"). Ratios per rule, bodies over ideal (OSR: rules with an "
        "ideal OSR above 0). Goals: OSR ratio >= "
     << tasks::kBodiesOsrRatioMedian << " at the median and >= " << tasks::kBodiesOsrRatioP10
     << " at the 10th percentile, zero collisions, FD ratio <= " << tasks::kBodiesFdRatioMedian << " at the median.\n\n"
     << "| motion | rules | median OSR ideal / bodies | OSR ratio median | p10 | collisions (trials) | min clearance | "
        "FD ratio median | makespan, mean | goals |\n|---|---|---|---|---|---|---|---|---|---|\n";
  for (const bool direct : {false, true}) {
    std::vector<std::pair<eval::Summary, eval::Summary>> runs;
    for (const Result& r : results)
      for (const WithBodies& b : r.bodies)
        if (b.motion.direct == direct) runs.push_back({b.ideal, b.bodies});
    if (runs.empty()) continue;
    const tasks::BodiesComparison c = tasks::compareBodies(runs);
    md << "| " << (direct ? "direct (touching, 4 mm, 1 cm)" : "the generators'") << " | " << c.rules << " | "
       << fmt(c.ideal_osr_median) << " / " << fmt(c.bodies_osr_median) << " | " << fmt(c.osr_ratio_median) << " | "
       << fmt(c.osr_ratio_p10) << " | " << c.collisions << " (" << c.trials_with_collision << "/" << c.trials << ") | "
       << mm(c.min_clearance_m) << " | " << fmt(c.fd_ratio_median) << " | " << fmt(c.makespan_s, 1) << " s | "
       << (c.goalsMet() ? "met" : "**not met**") << " |\n";
  }
  return md.str();
}

/// With bodies, rule by rule: the rules the direct motion cannot demonstrate, then every
/// rule on every motion model.
std::string bodiesPerRule(const std::vector<Result>& results) {
  std::ostringstream md;
  std::string undrawable;
  for (const Result& r : results)
    if (!r.undrawable.empty()) undrawable += (undrawable.empty() ? "" : "; ") + ("zoo:" + std::to_string(r.rule.id));
  md << "\nRules the direct motion cannot demonstrate (no scene whose bodies keep clear without bending around each "
        "other), not in its row: "
     << (undrawable.empty() ? std::string("none") : undrawable) << ".\n";
  md << "\n| rule | motion | OSR ideal | OSR with bodies | collisions (trials) | deadlocked trials | min clearance | "
        "FD "
        "ideal | FD with bodies | makespan |\n|---|---|---|---|---|---|---|---|---|---|\n";
  for (const Result& r : results)
    for (const WithBodies& b : r.bodies)
      md << "| zoo:" << r.rule.id << " " << r.rule.name << " | " << b.motion.words() << " | " << fmt(b.ideal.osr)
         << " | " << fmt(b.bodies.osr) << " | " << b.bodies.collisions << " (" << b.bodies.trials_with_collision << "/"
         << b.bodies.trials << ") | " << b.deadlocked_trials << " | " << mm(b.bodies.min_clearance_m) << " | "
         << fmt(b.ideal.fd, 4) << " | " << fmt(b.bodies.fd, 4) << " | " << fmt(b.bodies.makespan_s, 1) << " s |\n";
  return md.str();
}

/// The kinds of task users name, each as its zoo rule.
std::string userKinds(const std::vector<std::pair<tasks::ZooKind, Result>>& kinds, const std::vector<int>& sizes) {
  std::string md =
      "\n## Kinds of task users name\n\nEach kind as the zoo rule that states it (rule_zoo.h, `userKinds`; goal: "
      "OSR >= 0.9 at 20 demonstrations), trained and evaluated as the rules above (ideal).\n\n" +
      osrHeader("kind | zoo rule", 2, sizes);
  for (const auto& [kind, r] : kinds)
    md += "| " + kind.kind + " | " + kind.family + " " + r.rule.name + " |" + osrCells(r, sizes);
  return md;
}

}  // namespace

int main(int argc, char** argv) try {
  const fs::path repo = bench::repositoryFromArgs(argc, argv);
  const Options o = parseOptions(argc, argv);
  const std::vector<uint64_t> distinct = tasks::distinctZooRules(static_cast<int>(o.rules * o.every));
  const fs::path scratch = fs::temp_directory_path() / ("ddace_bench_rule_zoo_" + std::to_string(getpid()));
  const auto start = std::chrono::steady_clock::now();
  const RuleRuns runs(o, scratch);
  const std::vector<tasks::ZooMotion> direct_motions = tasks::directZooMotions();
  std::vector<Result> results;
  for (size_t k = 0; k < distinct.size(); k += static_cast<size_t>(o.every)) {
    Result r = runs.measure(distinct[k], direct_motions[results.size() % direct_motions.size()]);
    std::cout << "zoo " << r.rule.id << " " << r.rule.name << ": " << osrWords(r, o.sizes) << "\n" << std::flush;
    results.push_back(r);
  }
  // The kinds of task users name, each its zoo rule (rule_zoo.h, userKinds), as the rules above.
  std::vector<std::pair<tasks::ZooKind, Result>> kinds;
  for (const tasks::ZooKind& kind : o.quick ? std::vector<tasks::ZooKind>{} : tasks::userKinds()) {
    uint64_t id = 0;
    tasks::parseZooFamily(kind.family, id);
    Result r = runs.measure(id, std::nullopt);
    std::cout << kind.family << " " << kind.kind << ": " << osrWords(r, o.sizes) << "\n" << std::flush;
    kinds.push_back({kind, r});
  }
  fs::remove_all(scratch);
  const double minutes = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / 60;
  const std::string md = head(o, results.size(), distinct.size(), minutes, results) + byTemplate(results, o.sizes) +
                         everyRule(results, o.sizes) + bodiesSummary(results, o.bodiesSize()) + bodiesPerRule(results) +
                         userKinds(kinds, o.sizes);
  if (o.quick) {
    std::cout << md;
    return 0;
  }
  bench::writeResults(repo, "rule_zoo", md);
  return 0;
} catch (const std::exception& e) {
  std::cerr << "bench_rule_zoo: error: " << e.what() << "\n";
  return 1;
}
