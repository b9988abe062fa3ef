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

int main(int argc, char** argv) try {
  // The repository, found at run time (--repo DIR, DDACE_REPO, ...): bench/results.h.
  const fs::path kRepo = bench::repositoryFromArgs(argc, argv, {"bench/tgn_train_reference.py"});
  bench::noOtherOptions(argc, argv, "bench_tgn_decision");
  const int kRepeats = 300, kHistory = 6, kWideTeam = 30;
  tasks::GeneratorOptions g;
  g.family = "task2";
  g.robots = 11;  // + G1: 12 entities (the issue's goal: one decision with 11 robots)
  g.demos = 10;
  const task::TaskDir train = tasks::generate(g);
  const tgn::TrainOptions o;  // trained to the plateau, as a user would
  const auto model = tgn::SequenceModel::train(train, o, nullptr);
  const task::Demonstration& d = train.demos.front();
  const std::vector<task::Snapshot> history(d.snapshots.begin(), d.snapshots.begin() + kHistory);

  const fs::path tensors =
      fs::temp_directory_path() / ("ddace_bench_tgn_decision_" + std::to_string(getpid()) + ".txt");
  tgn::writeTrainingTensors(train, o, tensors.string());
  const std::string cmd = "/usr/bin/python3 '" + (kRepo / "bench" / "tgn_train_reference.py").string() +
                          "' decision '" + tensors.string() + "' --history " + std::to_string(kHistory) +
                          " --repeats " + std::to_string(kRepeats);

  double cpp_ms = 1e30, cpp_p99_ms = 1e30, cpu_p99_ms = 1e30, py_ms = 1e30;
  size_t tokens = 0;
  for (int round = 0; round < 2; ++round) {
    std::vector<double> times, cpu;
    for (int i = 0; i < kRepeats; ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      const double c0 = 1e3 * threadCpuS();  // the decision's own compute, without waiting for a core
      const tgn::Prediction p = model.predictNext(history);
      cpu.push_back(1e3 * threadCpuS() - c0);
      times.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      tokens = p.tokens.size();
    }
    std::sort(times.begin(), times.end());
    std::sort(cpu.begin(), cpu.end());
    cpu_p99_ms = std::min(cpu_p99_ms, cpu[cpu.size() * 99 / 100]);
    cpp_ms = std::min(cpp_ms, times[times.size() / 2]);
    cpp_p99_ms = std::min(cpp_p99_ms, times[times.size() * 99 / 100]);
    py_ms = std::min(py_ms, bench::jsonNumber(bench::capture(cmd), "median_ms"));
  }
  fs::remove(tensors);

  // Token by token (docs/tgn.md): nearest_goal's step (3 robots, 4 goals) decided one target
  // at a time, against the same network trained and decided all at once, timed alike.
  g.family = "nearest_goal";
  const task::TaskDir goals = tasks::generate(g);
  tgn::TrainOptions at_once;
  at_once.without = {tgn::Rule::TokenByToken};
  const auto by_token = tgn::SequenceModel::train(goals, tgn::TrainOptions{}, nullptr);
  const auto all_at_once = tgn::SequenceModel::train(goals, at_once, nullptr);
  if (!by_token.info().plan.token_by_token || all_at_once.info().plan.token_by_token)
    throw Error("nearest_goal did not train token by token (and all at once when told)");
  const std::vector<task::Snapshot> first(goals.demos.front().snapshots.begin(),
                                          goals.demos.front().snapshots.begin() + 1);
  const auto medianMs = [&](const tgn::SequenceModel& m) {
    double best = 1e30;
    for (int round = 0; round < 2; ++round) {
      std::vector<double> times;
      for (int i = 0; i < kRepeats; ++i) {
        const auto t0 = std::chrono::steady_clock::now();
        (void)m.predictNext(first);
        times.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      }
      std::sort(times.begin(), times.end());
      best = std::min(best, times[times.size() / 2]);
    }
    return best;
  };
  const double token_ms = medianMs(by_token), once_ms = medianMs(all_at_once);
  // Ensemble (docs/tgn.md): where the scene decides, the plan's networks each decode a step.
  // The largest scene-decided task shipped, zoo:nearest-goals (6 robots, 7 goals: 13
  // entities, token by token), against one network of the same training (--without ensemble).
  uint64_t nearest_goals = 0;
  tasks::parseZooFamily("zoo:nearest-goals", nearest_goals);
  const task::TaskDir big = tasks::generateZoo(nearest_goals, 20, 1);
  tgn::TrainOptions one_network;
  one_network.without = {tgn::Rule::Ensemble};
  const auto ensemble = tgn::SequenceModel::train(big, tgn::TrainOptions{}, nullptr);
  const auto single = tgn::SequenceModel::train(big, one_network, nullptr);
  if (ensemble.info().plan.ensemble != tgn::kEnsembleMembers || single.info().plan.ensemble != 1)
    throw Error("zoo:nearest-goals did not train an ensemble (and one network when told)");
  const std::vector<task::Snapshot> big_first(big.demos.front().snapshots.begin(),
                                              big.demos.front().snapshots.begin() + 1);
  const auto p99On = [&](const tgn::SequenceModel& m, const std::vector<task::Snapshot>& history,
                         double* median) {  // the better of 2 rounds
    double best = 1e30;
    *median = 1e30;
    for (int round = 0; round < 2; ++round) {
      std::vector<double> times;
      for (int i = 0; i < kRepeats; ++i) {
        const auto t0 = std::chrono::steady_clock::now();
        (void)m.predictNext(history);
        times.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      }
      std::sort(times.begin(), times.end());
      best = std::min(best, times[times.size() * 99 / 100]);
      *median = std::min(*median, times[times.size() / 2]);
    }
    return best;
  };
  double ensemble_median_ms = 0, single_median_ms = 0;
  const double ensemble_p99_ms = p99On(ensemble, big_first, &ensemble_median_ms),
               single_p99_ms = p99On(single, big_first, &single_median_ms);
  // 30 robots and 30 goals: the same ensemble bound to a task of the same kinds in other
  // numbers (docs/tgn.md, "Other team sizes"), on one scene, the entities on a grid 8 cm apart.
  task::TaskSpec wide = big.spec;
  wide.entities.clear();
  task::Snapshot wide_scene;
  for (const task::EntityKind kind : {task::EntityKind::Robot, task::EntityKind::Goal}) {
    const auto like = std::find_if(big.spec.entities.begin(), big.spec.entities.end(),
                                   [&](const task::Entity& e) { return e.kind == kind; });
    for (int i = 0; i < kWideTeam; ++i) {
      wide.entities.push_back(
          {(kind == task::EntityKind::Robot ? "R" : "G") + std::to_string(i + 1), kind, like->type});
      const int cell = static_cast<int>(wide_scene.positions.size());
      wide_scene.positions.push_back({0.06 + 0.08 * (cell % 10), 0.06 + 0.08 * (cell / 10)});
    }
  }
  double wide_median_ms = 0;
  const double wide_p99_ms = p99On(ensemble.boundTo(wide), {wide_scene}, &wide_median_ms);
  std::cout << "nearest_goal, one decision: token by token " << token_ms << " ms, all at once " << once_ms << " ms\n";
  std::cout << "zoo:nearest-goals, one decision median / p99: ensemble of " << tgn::kEnsembleMembers << " "
            << ensemble_median_ms << " / " << ensemble_p99_ms << " ms, one network " << single_median_ms << " / "
            << single_p99_ms << " ms\n";
  std::cout << "zoo:nearest-goals bound to " << kWideTeam << " robots and " << kWideTeam
            << " goals, one decision median / p99: " << wide_median_ms << " / " << wide_p99_ms << " ms\n";
  std::cout << "one decision, 11 robots, history of " << kHistory << ": C++ median " << cpp_ms << " ms, p99 "
            << cpp_p99_ms << " ms (thread CPU time p99 " << cpu_p99_ms << " ms; " << tokens
            << " tokens), Python median " << py_ms << " ms\n";

  std::ostringstream md;  // written whole and checked by bench::writeResults
  char line[512];
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
     << "| measure | C++ (libtorch) | reference | ratio | goal |\n|---|---|---|---|---|\n";
  std::snprintf(line, sizeof line, "| one decision, median | %.3f ms | %.3f ms (Python) | C++ %.2fx faster | |\n",
                cpp_ms, py_ms, py_ms / cpp_ms);
  md << line;
  std::snprintf(line, sizeof line,
                "| one decision, p99 vs the goal | %.3f ms | 1 ms (goal) | %.2f of the goal | < 1 ms |\n", cpp_p99_ms,
                cpp_p99_ms / 1.0);
  md << line;
  std::snprintf(line, sizeof line,
                "| one decision, p99 of the thread's CPU time (without waiting for a core) | %.3f ms | 1 ms (goal) | "
                "%.2f of the goal | < 1 ms |\n",
                cpu_p99_ms, cpu_p99_ms / 1.0);
  md << line;
  std::snprintf(line, sizeof line,
                "| nearest_goal's step (3 robots, 4 goals, first snapshot), median: token by token | %.3f ms | "
                "%.3f ms (the same training all at once) | %.2fx the time | |\n",
                token_ms, once_ms, token_ms / once_ms);
  md << line;
  std::snprintf(line, sizeof line,
                "| zoo:nearest-goals's step (6 robots, 7 goals, first snapshot), median: the ensemble of %d networks | "
                "%.3f ms | %.3f ms (one network, --without ensemble) | %.2fx the time | |\n",
                tgn::kEnsembleMembers, ensemble_median_ms, single_median_ms, ensemble_median_ms / single_median_ms);
  md << line;
  std::snprintf(line, sizeof line,
                "| zoo:nearest-goals's step, p99: the ensemble of %d networks | %.3f ms | %.3f ms (one network) | "
                "%.2f of the goal | < 1 ms |\n",
                tgn::kEnsembleMembers, ensemble_p99_ms, single_p99_ms, ensemble_p99_ms / 1.0);
  md << line;
  std::snprintf(line, sizeof line,
                "| zoo:nearest-goals's ensemble bound to %d robots and %d goals (docs/tgn.md, \"Other team sizes\"), "
                "one scene, p99 | %.3f ms | 5 ms (goal) | %.2f of the goal | < 5 ms |\n",
                kWideTeam, kWideTeam, wide_p99_ms, wide_p99_ms / 5.0);
  md << line;
  bench::writeResults(kRepo, "tgn_decision", md.str());
  return 0;
} catch (const std::exception& e) {
  std::cerr << "bench_tgn_decision: " << e.what() << "\n";
  return 1;
}
