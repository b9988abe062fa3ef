// bench_tgn_decision: latency of one decision (predict the next step) with 11 robots,
// against the same forward pass in Python/PyTorch (bench/tgn_train_reference.py decision)
// timed in the same run. Writes docs/bench/tgn_decision.md.
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <thread>

#include "ddace/common/error.h"
#include "ddace/common/machine.h"
#include "ddace/tasks/generators.h"
#include "ddace/tasks/rule_zoo.h"
#include "ddace/tgn/detail.h"
#include "ddace/tgn/sequence_model.h"
#include "ddace/common/clock.h"
#include "results.h"
#include "reference_runner.h"

namespace fs = std::filesystem;
using namespace ddace;

namespace {

constexpr int kRepeats = 300, kHistory = 6, kWideTeam = 30;

/// Times of one decision: median and 99th percentile of the wall time, 99th percentile of
/// the thread's CPU time (the decision's own compute, without waiting for a core).
struct Timing {
  double median_ms = 1e30, p99_ms = 1e30, cpu_p99_ms = 1e30;
  size_t tokens = 0;  ///< tokens of the decision
  /// Keeps the better of this and `other`, measure by measure.
  void keepBest(const Timing& other) {
    median_ms = std::min(median_ms, other.median_ms);
    p99_ms = std::min(p99_ms, other.p99_ms);
    cpu_p99_ms = std::min(cpu_p99_ms, other.cpu_p99_ms);
    tokens = other.tokens;
  }
};

/// One round: `m` decides the next step after `history` kRepeats times.
Timing timeDecisions(const tgn::SequenceModel& m, const std::vector<task::Snapshot>& history) {
  std::vector<double> times, cpu;
  Timing t;
  for (int i = 0; i < kRepeats; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = 1e3 * threadCpuS();
    const tgn::Prediction p = m.predictNext(history);
    cpu.push_back(1e3 * threadCpuS() - c0);
    times.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    t.tokens = p.tokens.size();
  }
  std::sort(times.begin(), times.end());
  std::sort(cpu.begin(), cpu.end());
  t.median_ms = times[times.size() / 2];
  t.p99_ms = times[times.size() * 99 / 100];
  t.cpu_p99_ms = cpu[cpu.size() * 99 / 100];
  return t;
}

/// The better of two rounds of timeDecisions.
Timing bestOfTwo(const tgn::SequenceModel& m, const std::vector<task::Snapshot>& history) {
  Timing best;
  for (int round = 0; round < 2; ++round) best.keepBest(timeDecisions(m, history));
  return best;
}

/// The first `n` snapshots of the first demonstration of `dir`.
std::vector<task::Snapshot> firstSnapshots(const task::TaskDir& dir, int n) {
  const auto& s = dir.demos.front().snapshots;
  return {s.begin(), s.begin() + n};
}

/// Task 2 with 11 robots, a history of kHistory snapshots: C++ against the same forward
/// pass in Python (bench/tgn_train_reference.py decision), alternating, best of 2 rounds.
struct ElevenRobots {
  Timing cpp;
  double python_ms = 1e30;
};

ElevenRobots timeElevenRobots(const fs::path& repo) {
  tasks::GeneratorOptions g;
  g.family = "task2";
  g.robots = 11;  // + G1: 12 entities (the issue's goal: one decision with 11 robots)
  g.demos = 10;
  const task::TaskDir train = tasks::generate(g);
  const tgn::TrainOptions o;  // trained to the plateau, as a user would
  const auto model = tgn::SequenceModel::train(train, o, nullptr);
  const std::vector<task::Snapshot> history = firstSnapshots(train, kHistory);
  const fs::path tensors =
      fs::temp_directory_path() / ("ddace_bench_tgn_decision_" + std::to_string(getpid()) + ".txt");
  tgn::writeTrainingTensors(train, o, tensors.string());
  const std::string cmd = "/usr/bin/python3 '" + (repo / "bench" / "tgn_train_reference.py").string() + "' decision '" +
                          tensors.string() + "' --history " + std::to_string(kHistory) + " --repeats " +
                          std::to_string(kRepeats);
  ElevenRobots r;
  for (int round = 0; round < 2; ++round) {
    r.cpp.keepBest(timeDecisions(model, history));
    r.python_ms = std::min(r.python_ms, bench::jsonNumber(bench::capture(cmd), "median_ms"));
  }
  fs::remove(tensors);
  return r;
}

/// Token by token (docs/tgn.md): nearest_goal's step (3 robots, 4 goals) decided one target
/// at a time, against the same network trained and decided all at once.
struct TokenByToken {
  Timing by_token, all_at_once;
};

TokenByToken timeTokenByToken() {
  tasks::GeneratorOptions g;
  g.family = "nearest_goal";
  g.robots = 11;
  g.demos = 10;
  const task::TaskDir goals = tasks::generate(g);
  tgn::TrainOptions at_once;
  at_once.without = {tgn::Rule::TokenByToken};
  const auto by_token = tgn::SequenceModel::train(goals, tgn::TrainOptions{}, nullptr);
  const auto all_at_once = tgn::SequenceModel::train(goals, at_once, nullptr);
  if (!by_token.info().plan.token_by_token || all_at_once.info().plan.token_by_token)
    throw Error("nearest_goal did not train token by token (and all at once when told)");
  const std::vector<task::Snapshot> first = firstSnapshots(goals, 1);
  return {bestOfTwo(by_token, first), bestOfTwo(all_at_once, first)};
}

/// Ensemble (docs/tgn.md): where the scene decides, the plan's networks each decode a step.
/// The largest scene-decided task shipped, zoo:nearest-goals (6 robots, 7 goals: 13
/// entities, token by token), against one network of the same training (--without
/// ensemble); and the same ensemble bound to kWideTeam robots and goals.
struct Ensemble {
  Timing ensemble, single, wide;
};

/// zoo:nearest-goals's kinds in other numbers (docs/tgn.md, "Other team sizes"): kWideTeam
/// robots and goals, and one scene with them on a grid 8 cm apart.
std::pair<task::TaskSpec, task::Snapshot> wideTeam(const task::TaskSpec& like_spec) {
  task::TaskSpec wide = like_spec;
  wide.entities.clear();
  task::Snapshot scene;
  for (const task::EntityKind kind : {task::EntityKind::Robot, task::EntityKind::Goal}) {
    const auto like = std::find_if(like_spec.entities.begin(), like_spec.entities.end(),
                                   [&](const task::Entity& e) { return e.kind == kind; });
    for (int i = 0; i < kWideTeam; ++i) {
      wide.entities.push_back(
          {(kind == task::EntityKind::Robot ? "R" : "G") + std::to_string(i + 1), kind, like->type});
      const int cell = static_cast<int>(scene.positions.size());
      scene.positions.push_back({0.06 + 0.08 * (cell % 10), 0.06 + 0.08 * (cell / 10)});
    }
  }
  return {wide, scene};
}

Ensemble timeEnsemble() {
  uint64_t nearest_goals = 0;
  tasks::parseZooFamily("zoo:nearest-goals", nearest_goals);
  const task::TaskDir big = tasks::generateZoo(nearest_goals, 20, 1);
  tgn::TrainOptions one_network;
  one_network.without = {tgn::Rule::Ensemble};
  const auto ensemble = tgn::SequenceModel::train(big, tgn::TrainOptions{}, nullptr);
  const auto single = tgn::SequenceModel::train(big, one_network, nullptr);
  if (ensemble.info().plan.ensemble != tgn::kEnsembleMembers || single.info().plan.ensemble != 1)
    throw Error("zoo:nearest-goals did not train an ensemble (and one network when told)");
  const std::vector<task::Snapshot> first = firstSnapshots(big, 1);
  const auto [wide, wide_scene] = wideTeam(big.spec);
  return {bestOfTwo(ensemble, first), bestOfTwo(single, first), bestOfTwo(ensemble.boundTo(wide), {wide_scene})};
}

void printSummary(const ElevenRobots& eleven, const TokenByToken& tokens, const Ensemble& e) {
  std::cout << "nearest_goal, one decision: token by token " << tokens.by_token.median_ms << " ms, all at once "
            << tokens.all_at_once.median_ms << " ms\n";
  std::cout << "zoo:nearest-goals, one decision median / p99: ensemble of " << tgn::kEnsembleMembers << " "
            << e.ensemble.median_ms << " / " << e.ensemble.p99_ms << " ms, one network " << e.single.median_ms << " / "
            << e.single.p99_ms << " ms\n";
  std::cout << "zoo:nearest-goals bound to " << kWideTeam << " robots and " << kWideTeam
            << " goals, one decision median / p99: " << e.wide.median_ms << " / " << e.wide.p99_ms << " ms\n";
  std::cout << "one decision, 11 robots, history of " << kHistory << ": C++ median " << eleven.cpp.median_ms
            << " ms, p99 " << eleven.cpp.p99_ms << " ms (thread CPU time p99 " << eleven.cpp.cpu_p99_ms << " ms; "
            << eleven.cpp.tokens << " tokens), Python median " << eleven.python_ms << " ms\n";
}

/// docs/bench/tgn_decision.md.
std::string report(const ElevenRobots& eleven, const TokenByToken& tokens, const Ensemble& e) {
  using bench::formatted;
  const Timing& cpp = eleven.cpp;
  std::ostringstream md;
  md << "# bench: tgn_decision\n\n"
     << "Written by `bench_tgn_decision` (`ddace bench tgn_decision`), " << utcNow() << ", "
     << std::thread::hardware_concurrency() << "-core machine (1-minute load average " << loadAverage()
     << " after the timings), one thread.\n"
     << "One decision = `SequenceModel::predictNext` on a history of " << kHistory
     << " keyframe snapshots of Task 2 with 11 robots + G1 (12 entities): the default network's encoder over every "
        "snapshot, GRU, heads, tokens and probabilities. Median and 99th percentile of "
     << kRepeats
     << " calls, best of 2 rounds. Reference: the same forward pass in Python/PyTorch "
        "(`bench/tgn_train_reference.py decision`), timed in the same run.\n\n"
     << "| measure | C++ (libtorch) | reference | ratio | goal |\n|---|---|---|---|---|\n"
     << formatted("| one decision, median | %.3f ms | %.3f ms (Python) | C++ %.2fx faster | |\n", cpp.median_ms,
                  eleven.python_ms, eleven.python_ms / cpp.median_ms)
     << formatted("| one decision, p99 vs the goal | %.3f ms | 1 ms (goal) | %.2f of the goal | < 1 ms |\n", cpp.p99_ms,
                  cpp.p99_ms / 1.0)
     << formatted(
            "| one decision, p99 of the thread's CPU time (without waiting for a core) | %.3f ms | 1 ms (goal) | "
            "%.2f of the goal | < 1 ms |\n",
            cpp.cpu_p99_ms, cpp.cpu_p99_ms / 1.0)
     << formatted(
            "| nearest_goal's step (3 robots, 4 goals, first snapshot), median: token by token | %.3f ms | "
            "%.3f ms (the same training all at once) | %.2fx the time | |\n",
            tokens.by_token.median_ms, tokens.all_at_once.median_ms,
            tokens.by_token.median_ms / tokens.all_at_once.median_ms)
     << formatted(
            "| zoo:nearest-goals's step (6 robots, 7 goals, first snapshot), median: the ensemble of %d networks | "
            "%.3f ms | %.3f ms (one network, --without ensemble) | %.2fx the time | |\n",
            tgn::kEnsembleMembers, e.ensemble.median_ms, e.single.median_ms, e.ensemble.median_ms / e.single.median_ms)
     << formatted(
            "| zoo:nearest-goals's step, p99: the ensemble of %d networks | %.3f ms | %.3f ms (one network) | "
            "%.2f of the goal | < 1 ms |\n",
            tgn::kEnsembleMembers, e.ensemble.p99_ms, e.single.p99_ms, e.ensemble.p99_ms / 1.0)
     << formatted(
            "| zoo:nearest-goals's ensemble bound to %d robots and %d goals (docs/tgn.md, \"Other team sizes\"), "
            "one scene, median: %zu tokens decided one at a time | %.3f ms | %.3f ms (the same ensemble at its own 6 "
            "robots, 7 goals) | %.2fx the time | |\n",
            kWideTeam, kWideTeam, e.wide.tokens, e.wide.median_ms, e.ensemble.median_ms,
            e.wide.median_ms / e.ensemble.median_ms)
     << formatted("| the same, p99 | %.3f ms | 5 ms (goal) | %.2f of the goal | < 5 ms |\n", e.wide.p99_ms,
                  e.wide.p99_ms / 5.0)
     << formatted("| the same, p99 of the thread's CPU time | %.3f ms | 5 ms (goal) | %.2f of the goal | < 5 ms |\n",
                  e.wide.cpu_p99_ms, e.wide.cpu_p99_ms / 5.0);
  return md.str();
}

}  // namespace

int main(int argc, char** argv) try {
  // The repository, found at run time (--repo DIR, DDACE_REPO, ...): bench/results.h.
  const fs::path repo = bench::repositoryFromArgs(argc, argv, {"bench/tgn_train_reference.py"});
  bench::noOtherOptions(argc, argv, "bench_tgn_decision");
  const ElevenRobots eleven = timeElevenRobots(repo);
  const TokenByToken tokens = timeTokenByToken();
  const Ensemble ensemble = timeEnsemble();
  printSummary(eleven, tokens, ensemble);
  bench::writeResults(repo, "tgn_decision", report(eleven, tokens, ensemble));
  return 0;
} catch (const std::exception& e) {
  std::cerr << "bench_tgn_decision: " << e.what() << "\n";
  return 1;
}
