// ddace eval: closed-loop evaluation of a trained model on a test set (OSR, SSR, GCR, FD).
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>

#include "command.h"
#include "ddace/common/file.h"
#include "ddace/pipeline/evaluation.h"
#include "ddace/pipeline/perturbation.h"

namespace ddace::cli {
using namespace ddace::pipeline;
namespace {

int runEval(const std::vector<std::string>& argv) {
  Args args(argv,
            {"--json", "--execution", "--noise", "--seed", "--config", "--dispatch", "--perturb", "--speed-spread"},
            {"--allow-other-task", "--no-bodies", "--no-filter"});
  args.expectAtMostPositional(2);
  const std::string model_dir = args.positional(0, "MODELDIR");
  std::string test_dir = args.positional(1, "TESTDIR");
  // The output of `ddace generate` (train/ and test/): its test set, as validate and execute_sim take it.
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(fs::path(test_dir) / "task.yaml", ec) && fs::exists(fs::path(test_dir) / "test" / "task.yaml", ec))
    test_dir = (fs::path(test_dir) / "test").string();
  EvalOptions o;
  o.execution = args.get("--execution", "ideal");
  if (o.execution != "ideal" && o.execution != "diffdrive")
    throw Error("--execution '" + o.execution + "' is not one of ideal, diffdrive");
  o.noise_m = args.getDouble("--noise", 0.0);
  if (o.noise_m < 0) throw Error("--noise must not be negative (metres)");
  if (o.noise_m > 0 && o.execution != "diffdrive") throw Error("--noise needs --execution diffdrive");
  o.seed = static_cast<uint64_t>(args.getInt("--seed", 1));
  o.bodies = !args.has("--no-bodies");
  o.safety_filter = !args.has("--no-filter");
  if ((args.has("--no-bodies") || args.has("--no-filter")) && o.execution != "diffdrive")
    throw Error("--no-bodies and --no-filter need --execution diffdrive");
  if (args.has("--no-bodies") && args.has("--no-filter"))
    throw Error("--no-filter needs bodies: without --no-bodies (points have no filter)");
  if (args.has("--config")) {
    if (o.execution != "diffdrive") throw Error("--config needs --execution diffdrive");
    if (args.has("--no-bodies"))
      throw Error("--config runs the table with bodies; --no-bodies (points) runs the built-in control law");
    o.config = exec::readExecutionConfig(args.get("--config", ""));
  }

  std::optional<Perturbation> perturb;
  if (args.has("--dispatch")) o.dispatch = exec::parseDispatchMode(args.get("--dispatch", ""), "--dispatch");
  if (args.has("--perturb")) {
    perturb = parsePerturbation(args.get("--perturb", ""), "--perturb");
    if (o.execution == "diffdrive" && !o.bodies)
      throw Error(
          "--perturb runs the coordinator on entities that follow their paths ideally (--execution ideal) or "
          "on the table with bodies (--execution diffdrive); not on points (--no-bodies)");
  } else if (args.has("--dispatch") && o.execution != "diffdrive") {
    throw Error(
        "--dispatch needs --execution diffdrive (points: the tokens' schedule; bodies: runs through the "
        "coordinator)");
  }
  // With bodies, a dispatch runs through the coordinator: segments start when it sends them.
  o.coordinated = args.has("--dispatch") && o.execution == "diffdrive" && o.bodies;
  if (args.has("--speed-spread")) {
    o.speed_spread = args.getDouble("--speed-spread", 0.0);
    if (!(o.speed_spread >= 0 && o.speed_spread < 1))
      throw Error("--speed-spread must be in [0, 1): each robot moves at a factor drawn from [1 - spread, 1]");
    if (!o.coordinated || perturb)
      throw Error("--speed-spread needs --execution diffdrive with bodies and --dispatch, without --perturb");
  }
  const task::TaskDir test = task::loadTaskDir(test_dir);
  const ModelForTask bound =
      modelForTask(loadModel(model_dir), model_dir, test, test_dir, args.has("--allow-other-task"));
  if (!bound.note.empty()) std::cout << bound.note << "\n";
  if (perturb) {
    const exec::BodiesExecutionParams table = bodiesParams(o, test.spec);
    const PerturbationReport r = evaluatePerturbed(bound.model, test, *perturb, o.dispatch, o.seed,
                                                   o.execution == "diffdrive" ? &table : nullptr);
    printPerturbation(r, std::cout);
    if (args.has("--json")) {
      const std::string path = args.get("--json", "");
      writeTextFile(path, perturbationJson(r));
      std::cout << "wrote " << path << "\n";
    }
    return 0;
  }
  const Evaluation e = evaluate(bound.model, test, o);
  printEvaluation(e, std::cout);
  if (args.has("--json")) {
    const std::string path = args.get("--json", "");
    writeTextFile(path, evaluationJson(e));  // checked: a failed write is an error naming the file
    std::cout << "wrote " << path << "\n";
  }
  return 0;
}

DDACE_COMMAND(
    {"eval",
     "ddace eval MODELDIR TESTDIR|GENERATED_DIR [--json FILE] [--execution ideal|diffdrive] [--noise SIGMA_M] "
     "[--seed S] [--no-bodies] [--no-filter] [--config EXECUTION_YAML] [--dispatch steps|async] "
     "[--speed-spread F] [--perturb box_moved[:CM]|robot_pushed[:CM]|robot_stalled[:S]|robot_lost] "
     "[--allow-other-task]",
     "run the learned task in closed loop on every test demonstration's start configuration and "
     "report OSR, SSR, GCR and FD (a model of another task is refused unless --allow-other-task; a test set "
     "of the same task with other numbers of robots, goals or boxes runs the model bound by kind, with a "
     "note, where the rule it learned is stated by the scene). "
     "ideal: every entity traverses its path exactly (the paper). diffdrive: the robots of a step drive "
     "together on the simulated table with bodies, each through its safety filter; every trial reports "
     "its collisions, minimum clearance and makespan, and a collision fails it (--no-filter: without "
     "the filter; --no-bodies: points, each motion alone; --config: the follower gains, safety filter, "
     "simulated Hamster and table of an execution config such as config/execution.yaml, whose values "
     "are the built-in defaults; its position noise is --noise's). --dispatch: steps, every token of a "
     "step after the last step ended, or async, each token when its own predecessors under "
     "the model's learned dependencies ended; prints the makespan, the precedence violations and whom each "
     "token waited for; on points the tokens' schedule, with bodies every trial runs through the coordinator, "
     "its segments starting on the table when it sends them, recovering as the coordinator node does by default "
     "(max_replans 2). --speed-spread F (with --dispatch): robots that differ in speed, each driving at a "
     "factor drawn per trial from [1 - F, 1] of the speed it commands, the same under either dispatch. "
     "--perturb: every trial runs through the coordinator (entities following their paths ideally in time; "
     "with --execution diffdrive, on the table with bodies) "
     "three times: unperturbed, and with the table changed once at a drawn moment (--seed) without recovery "
     "and with it (max_replans 2, the default: the step re-decided from the scene, or the path re-planned); prints the "
     "trials that succeeded, the re-plans and re-decisions and the time lost (docs/execution.md, "
     "\"Perturbations\")",
     runEval});

}  // namespace
}  // namespace ddace::cli
