// bench_tgn_decision: latency of one decision (predict the next step) for 11 entities,
// against the same forward pass in Python/PyTorch (bench/tgn_train_reference.py decision)
// timed in the same run. Writes docs/bench/tgn_decision.md.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <thread>

#include "ddace/common/error.h"
#include "ddace/common/machine.h"
#include "ddace/tasks/generators.h"
#include "ddace/tgn/detail.h"
#include "ddace/tgn/sequence_model.h"
#include "reference_runner.h"

namespace fs = std::filesystem;
using namespace ddace;

namespace {

const fs::path kRepo = fs::path(__FILE__).parent_path().parent_path();

}  // namespace

int main() try {
  const int kRepeats = 300, kHistory = 6;
  tasks::GeneratorOptions g;
  g.family = "task2";
  g.robots = 10;  // + G1: 11 entities
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

  double cpp_ms = 1e30, py_ms = 1e30;
  size_t tokens = 0;
  for (int round = 0; round < 2; ++round) {
    std::vector<double> times;
    for (int i = 0; i < kRepeats; ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      const tgn::Prediction p = model.predictNext(history);
      times.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      tokens = p.tokens.size();
    }
    std::sort(times.begin(), times.end());
    cpp_ms = std::min(cpp_ms, times[times.size() / 2]);
    py_ms = std::min(py_ms, bench::jsonNumber(bench::capture(cmd), "median_ms"));
  }
  fs::remove(tensors);
  std::cout << "one decision, 11 entities, history of " << kHistory << ": C++ " << cpp_ms << " ms (" << tokens
            << " tokens), Python " << py_ms << " ms\n";

  fs::create_directories(kRepo / "docs" / "bench");
  std::ofstream md(kRepo / "docs" / "bench" / "tgn_decision.md");
  char line[512];
  md << "# bench: tgn_decision\n\n"
     << "Written by `bench_tgn_decision` (`ddace bench tgn_decision`), " << utcNow() << ", "
     << std::thread::hardware_concurrency() << "-core machine (1-minute load average " << loadAverage()
     << " after the timings), one thread.\n"
     << "One decision = `SequenceModel::predictNext` on a history of " << kHistory
     << " keyframe snapshots of Task 2 with 10 robots + G1 (11 entities): GAT encoder over every snapshot, GRU, heads, "
        "tokens and probabilities. Median of "
     << kRepeats
     << " calls, best of 2 rounds. Reference: the same forward pass in Python/PyTorch "
        "(`bench/tgn_train_reference.py decision`), timed in the same run.\n\n"
     << "| measure | C++ (libtorch) | reference | ratio | goal |\n|---|---|---|---|---|\n";
  std::snprintf(line, sizeof line, "| one decision | %.3f ms | %.3f ms (Python) | C++ %.2fx faster | < 2 ms |\n",
                cpp_ms, py_ms, py_ms / cpp_ms);
  md << line;
  std::snprintf(line, sizeof line, "| one decision vs the goal | %.3f ms | 2 ms (goal) | %.2f of the goal | < 2 ms |\n",
                cpp_ms, cpp_ms / 2.0);
  md << line;
  std::cout << "wrote " << (kRepo / "docs" / "bench" / "tgn_decision.md").string() << "\n";
  return 0;
} catch (const std::exception& e) {
  std::cerr << "bench_tgn_decision: " << e.what() << "\n";
  return 1;
}
