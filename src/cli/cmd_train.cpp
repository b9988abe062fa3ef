// ddace train: learn a task's step sequence (temporal graph network) into a model directory.
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <optional>

#include "command.h"
#include "ddace/common/error.h"
#include "ddace/task/owned_dir.h"
#include "ddace/task/task_dir.h"
#include "ddace/tgn/sequence_model.h"
#include "ddace/pipeline/evaluation.h"

namespace ddace::cli {
using namespace ddace::pipeline;
namespace {

namespace fs = std::filesystem;

/// A `ddace generate` output directory holds train/ and test/: train on train/.
std::string trainingDir(const std::string& path) {
  if (!fs::exists(fs::path(path) / "task.yaml") && fs::exists(fs::path(path) / "train" / "task.yaml")) {
    std::cout << "training on " << (fs::path(path) / "train").string() << " (the training half)\n";
    return (fs::path(path) / "train").string();
  }
  return path;
}

/// Refuses an output directory that is, lies inside or holds the directory `input`: the
/// model is written as a directory of its own and must not replace what it learns from.
void checkApart(const std::string& out, const std::string& input) {
  std::error_code ec;
  const fs::path o = fs::weakly_canonical(fs::absolute(out), ec);
  const fs::path i = fs::weakly_canonical(fs::absolute(input), ec);
  auto within = [](const fs::path& inner, const fs::path& outer) {
    return std::mismatch(outer.begin(), outer.end(), inner.begin(), inner.end()).first == outer.end();
  };
  if (within(o, i))
    throw Error(Diagnostic{out, 0, 0,
                           (o == i ? "is the training directory " : "is inside the training directory ") + input +
                               ": train writes the model into a directory of its own (choose another --out)"});
  if (within(i, o))
    throw Error(Diagnostic{out, 0, 0,
                           "holds the training directory " + input +
                               ": train writes the model into a directory of its own (choose another --out)"});
}

int runTrain(const std::vector<std::string>& argv) {
  Args args(argv, {"--out", "--variant", "--epochs", "--seed", "--threads", "--patience", "--without"},
            {"--quiet", "--force"});
  const std::string given = args.positional(0, "TASKDIR");
  const std::string task_path = trainingDir(given);
  args.expectAtMostPositional(1);
  const std::string out = args.require("--out");
  checkApart(out, given);
  if (task_path != given) checkApart(out, task_path);

  tgn::TrainOptions options;
  try {
    options.variant = tgn::variantFromString(args.get("--variant", tgn::toString(options.variant)));
  } catch (const Error& e) {
    throw Error(std::string("option --variant: ") + e.what());
  }
  options.max_epochs = static_cast<int>(args.getInt("--epochs", options.max_epochs));
  const long seed = args.getInt("--seed", static_cast<long>(options.seed));
  if (seed < 0) throw Error("option --seed: must be non-negative");
  options.seed = static_cast<uint64_t>(seed);
  options.threads = static_cast<int>(args.getInt("--threads", options.threads));
  options.plateau_patience = static_cast<int>(args.getInt("--patience", options.plateau_patience));
  // The network's hyper-parameters are TrainOptions fields for experiments, not flags: the
  // defaults are what docs/tgn.md measured (a user sets the epochs, seed and rules).
  // The scene network's learning rules, each on by default (docs/tgn.md): --without names
  // those to switch off, comma-separated.
  try {
    options.without = tgn::rulesFromList(args.get("--without", ""));
  } catch (const Error& e) {
    throw Error(std::string("option --without: ") + e.what());
  }
  options.validate();

  const task::TaskDir train = task::loadTaskDir(task_path);
  // A demonstration without a step would teach "END at once".
  std::string unlabelled;
  size_t count = 0;
  for (const auto& d : train.demos)
    if (d.steps.empty()) unlabelled += "\n" + d.source + ": no labelled step", ++count;
  if (count > 0)
    throw Error(task_path + ": demonstrations without labels (recorded with infer_labels: false?):" + unlabelled +
                "\n" + unlabelledAdvice(task_path, count == train.demos.size()));
  // The sequence model, then (except for gnn) the GP primitive library, into one
  // directory of train's own: written whole beside MODELDIR, then swapped in, so a failed
  // or interrupted run leaves the old model as it was and no old file survives.
  std::optional<Model> result;
  task::writeOwnedDirectory(
      out,
      [&](const std::string& dir) {
        std::cout << "training variant '" << tgn::toString(options.variant) << "' on " << train.demos.size()
                  << " demonstrations of task '" << train.spec.name << "' (" << train.spec.entities.size()
                  << " entities), seed " << options.seed << "\n"
                  << std::flush;
        result.emplace(trainModel(train, options, dir, args.has("--quiet") ? nullptr : &std::cout));
      },
      "ddace train", args.has("--force"));
  const Model& trained = *result;
  const tgn::SequenceModel& model = trained.sequence;

  const tgn::ModelInfo& info = model.info();
  const tgn::EpochRecord& last = info.history.back();
  std::cout << "stopped after " << last.epoch << " epochs (" << info.stop_reason << "): loss " << last.loss << ", "
            << (options.variant == tgn::Variant::Gnn ? "frame label" : "step") << " accuracy " << last.step_accuracy
            << ", " << last.seconds << " s\n";
  std::cout << "attention edges: " << info.plan.attention_edges.size() << " (E' has " << info.refined.kept.size()
            << " of " << info.refined.edges.size() << " observed edges)\n";
  if (trained.primitives) {
    std::cout << "motion primitives: " << trained.primitives->primitives().size() << " (";
    bool first = true;
    for (const auto& [key, p] : trained.primitives->primitives()) {
      std::cout << (first ? "" : ", ") << key << " x" << p.segments;
      first = false;
    }
    std::cout << ")\n";
    // Where the demonstrations stop at another gap than the footprints: they win, said here.
    for (const task::StopGap& g : task::stopGaps(train.spec, trained.primitives->endPoints(), train.demos))
      std::cout << "end points: " << g.str() << "\n";
  }
  std::cout << "transfer: runs on " << model.transfer().text() << "\n";
  std::cout << "wrote " << out << " (ddace inspect " << out << " shows it)\n";
  return 0;
}

DDACE_COMMAND(
    {"train",
     "ddace train TASKDIR --out MODELDIR [--force] [--variant scene|paper|full-graph|gnn] [--epochs N=400] "
     "[--seed S=1] [--threads T=1] [--patience P=20] "
     "[--without relative,fixed-order,shuffled-names,token-by-token,parked,ensemble,end-scene,next-targets] [--quiet]",
     "train the temporal graph network (one progress line per epoch) and fit the GP motion primitives into MODELDIR "
     "(refused when it holds anything else; --force replaces an earlier model); prints what the model can run on "
     "besides its task's entities (other numbers of robots, goals, boxes: docs/tgn.md)",
     runTrain});

}  // namespace
}  // namespace ddace::cli
