// bench_tgn_train: training speed of the temporal graph network on Task 2 (11 robots, 30
// demonstrations), against the same network and loop in Python/PyTorch
// (bench/tgn_train_reference.py) timed in the same run. Writes docs/bench/tgn_train.md.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <thread>
#include <utility>

#include "ddace/common/error.h"
#include "ddace/common/machine.h"
#include "ddace/tasks/generators.h"
#include "ddace/tgn/detail.h"
#include "ddace/tgn/sequence_model.h"
#include "results.h"
#include "reference_runner.h"

namespace fs = std::filesystem;
using namespace ddace;

namespace {

constexpr int kEpochs = 30, kRounds = 2;

/// Task 2 with 11 robots, 30 demonstrations, generator seed 1.
task::TaskDir taskTwo() {
  tasks::GeneratorOptions g;
  g.family = "task2";
  g.robots = 11;
  g.demos = 30;
  g.seed = 1;
  return tasks::generate(g);
}

/// The default options but a fixed number of epochs.
tgn::TrainOptions fixedEpochs() {
  tgn::TrainOptions fixed;
  fixed.max_epochs = kEpochs;
  fixed.plateau_patience = kEpochs + 1;  // no early stop: a fixed number of epochs
  return fixed;
}

/// Time per epoch, C++ against the reference, each its best of kRounds alternating rounds
/// (both see the same machine load); and whether the network had relative features.
struct PerEpoch {
  double cpp_ms = 1e30, python_ms = 1e30;
  bool relative = true;
};

/// The tensors are those of the network SequenceModel::train runs on `train` with `fixed`,
/// "Fixed order" rule included (Task 2: every demonstration has the same steps, so no
/// relative features, and the heads read each entity's own input); the reference builds
/// that network from the tensors' header.
PerEpoch timePerEpoch(const fs::path& repo, const task::TaskDir& train, const tgn::TrainOptions& fixed) {
  const fs::path scratch = fs::temp_directory_path() / ("ddace_bench_tgn_" + std::to_string(getpid()));
  fs::create_directories(scratch);
  const fs::path tensors = scratch / "tensors.txt";
  tgn::writeTrainingTensors(train, fixed, tensors.string());
  const std::string reference = (repo / "bench" / "tgn_train_reference.py").string();
  const auto command = [&](const std::string& extra) {
    return bench::formatted("/usr/bin/python3 '%s' train '%s' --epochs %d --batch %d --lr %g --seed %llu%s",
                            reference.c_str(), tensors.c_str(), kEpochs, fixed.batch_demos, fixed.learning_rate,
                            static_cast<unsigned long long>(fixed.seed), extra.c_str());
  };
  PerEpoch r;
  for (int round = 0; round < kRounds; ++round) {
    const auto m = tgn::SequenceModel::train(train, fixed, nullptr);
    // After 30 epochs the network is short of its demonstrations, so "Names or the scene"
    // trains a second one without the identity embedding; the time per epoch is the kept
    // network's own, and the reference has the identity embedding: it must be that one.
    if (!m.info().plan.identity_embedding)
      throw Error("the kept network has no identity embedding, the reference's has: not the same network");
    r.relative = m.info().plan.relative_features;
    std::string extra;
    if (round == 0) {  // the reference refuses to run when its parameters' shapes are not these
      m.save((scratch / "model").string());
      extra = " --same-shapes '" + (scratch / "model" / "weights.pt").string() + "'";
    }
    r.cpp_ms = std::min(r.cpp_ms, 1000 * m.info().history.back().seconds / kEpochs);
    const std::string out = bench::capture(command(extra));
    if ((bench::jsonNumber(out, "relative_features") != 0) != r.relative)
      throw Error("the reference ran the network with other relative features than C++: " + out);
    r.python_ms = std::min(r.python_ms, bench::jsonNumber(out, "ms_per_epoch"));
    std::cout << "round " << round + 1 << ": C++ " << r.cpp_ms << " ms/epoch, Python " << r.python_ms << " ms/epoch\n";
  }
  fs::remove_all(scratch);
  return r;
}

/// A whole training and its wall time: where "Names or the scene" trains a second network, it counts.
std::pair<tgn::SequenceModel, double> timedTrain(const task::TaskDir& demos, const tgn::TrainOptions& o) {
  const auto started = std::chrono::steady_clock::now();
  auto m = tgn::SequenceModel::train(demos, o, nullptr);
  return {std::move(m), std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count()};
}

/// The report's head: what was measured, and the speed table.
std::string speedTable(const PerEpoch& epoch, const tgn::TrainOptions& fixed, const tgn::SequenceModel& model,
                       double plateau_s) {
  const auto& last = model.info().history.back();
  std::ostringstream md;
  md << "# bench: tgn_train\n\n"
     << "Written by `bench_tgn_train` (`ddace bench tgn_train`), " << utcNow() << ", "
     << std::thread::hardware_concurrency() << "-core machine (1-minute load average " << loadAverage()
     << " after the timings), one thread in both languages (`at::set_num_threads(1)`, `torch.set_num_threads(1)`).\n"
     << "Task 2 with 11 robots (12 entities), 30 demonstrations (generator seed 1), the default variant `"
     << tgn::toString(fixed.variant)
     << "` with its default hyper-parameters, as `ddace train` trains it: 3 attention layers x 2 heads x 16 "
        "channels "
     << (epoch.relative ? "with relative edge features"
                        : "without the relative edge features (every demonstration has the same steps: the \"Fixed "
                          "order\" rule of docs/tgn.md; they are all zero) and with each entity's own input beside "
                          "the last layer's output")
     << ", GRU 2 x 64, per-entity heads and the pointer with 32 hidden units, batches of 8 demonstrations, Adam "
        "lr 0.005, gradient norm clipped at 1, eval-mode step accuracy after every epoch (on the training "
        "demonstrations, collated once) in both.\n"
     << "The reference is `bench/tgn_train_reference.py`: the same network and loop in Python/PyTorch "
        "(Debian's python3-torch; it builds the network from the tensors' header and checks its parameters' "
        "shapes against the C++ network's), on the same tensors, timed in the same run; per-epoch times are the "
        "best of "
     << kRounds << " alternating rounds of " << kEpochs
     << " epochs (C++: of the network kept; the second one that \"Names or the scene\" trains after 30 epochs "
        "short of the demonstrations is not timed).\n"
     << "Training to the plateau is `SequenceModel::train` with the default options, what `ddace train` runs "
        "before it fits the motion primitives.\n\n"
     << "| measure | C++ (libtorch) | reference | ratio | goal |\n|---|---|---|---|---|\n"
     << bench::formatted("| time per epoch | %.1f ms | %.1f ms (Python) | C++ %.2fx faster | >= 2x faster |\n",
                         epoch.cpp_ms, epoch.python_ms, epoch.python_ms / epoch.cpp_ms)
     << bench::formatted(
            "| training to the plateau | %.1f s (%d epochs, %s, step accuracy %.3f) | 30 s (goal) | %.2f of the "
            "goal | < 30 s |\n",
            plateau_s, last.epoch, model.info().stop_reason.c_str(), last.step_accuracy, plateau_s / 30.0);
  return md.str();
}

/// Which default: identity embedding on/off, and E' against the full graph, on every task
/// (a row per task, demonstration count and variant, also printed as they come).
std::string variantsTable() {
  std::ostringstream md;
  md << "\n## Variants: network, identity embedding and edge set\n\n"
     << "Each task: 20 or 3 training demonstrations (generator seed 1), 10 test demonstrations with new start-goal "
        "configurations (seed 101); default hyper-parameters otherwise. Step accuracy = steps and END predicted "
        "exactly from the true snapshot history. The shipped default is the first row of each group; the "
        "closed-loop comparison on every family is in docs/results.md.\n\n"
     << "| task | demos | variant | identity embedding (kept network) | epochs (kept network) | training time (all) | "
        "train step accuracy | test step accuracy |\n|---|---|---|---|---|---|---|---|\n";
  for (const std::string family : {"task1", "task2", "task3", "task4"})
    for (const int demos : {20, 3}) {
      tasks::GeneratorOptions tg;
      tg.family = family;
      tg.demos = demos;
      tg.seed = 1;
      const task::TaskDir tr = tasks::generate(tg);
      tg.demos = 10;
      tg.seed = 101;
      const task::TaskDir te = tasks::generate(tg);
      for (const auto& [variant, identity] :
           std::vector<std::pair<tgn::Variant, bool>>{{tgn::Variant::Scene, true},
                                                      {tgn::Variant::Paper, true},
                                                      {tgn::Variant::Paper, false},
                                                      {tgn::Variant::FullGraph, true}}) {
        tgn::TrainOptions o;
        o.variant = variant;
        o.identity_embedding = identity;
        // The kept network's identity setting, which "Names or the scene" may have switched off.
        const auto [m, seconds] = timedTrain(tr, o);
        const std::string row = bench::formatted(
            "| %s | %d | %s | %s | %d | %.1f s | %.3f | %.3f |\n", family.c_str(), demos, tgn::toString(variant),
            m.info().plan.identity_embedding ? "on" : "off", m.info().history.back().epoch, seconds,
            m.stepAccuracy(tr.demos), m.stepAccuracy(te.demos));
        md << row;
        std::cout << row << std::flush;
      }
    }
  return md.str();
}

}  // namespace

int main(int argc, char** argv) try {
  // The repository, found at run time (--repo DIR, DDACE_REPO, ...): bench/results.h.
  const fs::path repo = bench::repositoryFromArgs(argc, argv, {"bench/tgn_train_reference.py"});
  bench::noOtherOptions(argc, argv, "bench_tgn_train");
  const task::TaskDir train = taskTwo();
  const tgn::TrainOptions fixed = fixedEpochs();
  const PerEpoch epoch = timePerEpoch(repo, train, fixed);
  const auto [model, plateau_s] = timedTrain(train, tgn::TrainOptions{});
  const auto& last = model.info().history.back();
  std::cout << "to the plateau: " << plateau_s << " s, " << last.epoch << " epochs (" << model.info().stop_reason
            << "), step accuracy " << last.step_accuracy << "\n";
  const std::string head = speedTable(epoch, fixed, model, plateau_s);
  bench::writeResults(repo, "tgn_train", head + variantsTable());
  return 0;
} catch (const std::exception& e) {
  std::cerr << "bench_tgn_train: " << e.what() << "\n";
  return 1;
}
