// The pipeline shared by `ddace train/eval/table` and the ROS nodes: trains the two learned
// halves into one model directory and runs the closed-loop evaluation of a model on a
// test set. Its own library (ddace_pipeline) because it ties tgn (libtorch) to gp, exec and eval.
#pragma once

#include <iosfwd>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "ddace/eval/metrics.h"
#include "ddace/exec/bodies_execution.h"
#include "ddace/exec/coordinator.h"
#include "ddace/exec/dispatch.h"
#include "ddace/exec/execution_config.h"
#include "ddace/exec/simulator.h"
#include "ddace/gp/primitives.h"
#include "ddace/task/task_dir.h"
#include "ddace/tgn/sequence_model.h"

namespace ddace::pipeline {

/// A trained model directory: the sequence model and (except for gnn) the primitives.
struct Model {
  tgn::SequenceModel sequence;
  std::shared_ptr<gp::PrimitiveLibrary> primitives;  ///< null for the gnn variant
};

/// Trains the sequence model and fits the primitive library (not for gnn, which rolls
/// out its own trajectories), writing both into `model_dir`.
Model trainModel(const task::TaskDir& train, const tgn::TrainOptions& options, const std::string& model_dir,
                 std::ostream* progress);
/// Loads a model directory: the one loader of `ddace eval/inspect/path` and the nodes.
/// Every file is read and checked against the manifest's digests (the manifest against
/// its own), and the primitive library must name the sequence model's task fingerprint.
/// Throws ddace::Error naming the file at fault and what differs.
Model loadModel(const std::string& model_dir);

/// The model to run on a task (`spec` and `fingerprint`, read from `task_file`): `model`
/// itself on its own task's entities; on a task of the same name and kinds of entity in
/// other numbers (more or fewer robots, goals, boxes), the model bound to the task's
/// entities (tgn::SequenceModel::boundTo, gp::PrimitiveLibrary::boundTo), with `note` saying
/// so. Refuses (ddace::Error) another task, listing what differs (task::requireSameTask:
/// entities, kinds, vocabulary, goal conditions, demonstrated step structure; for other
/// numbers all but the entities, goal conditions and step counts), unless
/// `allow_other_task` (a deliberate transfer); `override_hint` says how to allow it. A model
/// that cannot run on other entities is refused naming why (tgn::Transfer), with or without.
struct ModelForTask {
  Model model;
  std::string note;  ///< "" on the model's own entities
};
ModelForTask modelForTask(const Model& model, const std::string& model_dir, const task::TaskSpec& spec,
                          const task::TaskFingerprint& fingerprint, const std::string& task_file, bool allow_other_task,
                          const std::string& override_hint);
/// The same for a test set (a task directory) as `ddace eval` takes it ("pass --allow-other-task").
ModelForTask modelForTask(const Model& model, const std::string& model_dir, const task::TaskDir& test,
                          const std::string& test_dir, bool allow_other_task);

struct EvalOptions {
  std::string execution = "ideal";  ///< ideal | diffdrive
  double noise_m = 0;               ///< diffdrive: std-dev of the measured position, metres
  uint64_t seed = 1;                ///< diffdrive noise seed
  /// diffdrive: the robots of a step move together on the table with bodies
  /// (exec/bodies_execution.h); false: points, each motion alone (exec/diff_drive_execution.h).
  bool bodies = true;
  /// diffdrive with bodies: each robot's command goes through its safety filter.
  bool safety_filter = true;
  /// diffdrive with bodies: the follower, filter, robot and table parameters (the built-in
  /// defaults, which config/execution.yaml states; `--config FILE` reads another file's).
  /// Its filter off or its table without bodies turn the above off too.
  exec::ExecutionConfig config;
  /// diffdrive: when each token starts (exec/dispatch.h): steps, or async (its own
  /// predecessors under the model's learned dependencies). On points, which do not meet, a
  /// trial's tokens take the same time either way and the makespan is their schedule; with
  /// bodies and `coordinated`, each trial runs through the coordinator (pipeline/perturbation.h).
  exec::DispatchMode dispatch = exec::CoordinatorConfig{}.dispatch;
  /// diffdrive with bodies: every trial runs through the coordinator (its dispatch, its
  /// end points, its checks of DONE) on the table, segments starting when it sends them;
  /// false: step by step through the closed-loop simulator (the paper's execution).
  bool coordinated = false;
  /// coordinated: robots that differ in speed, each at a factor of the speed it is driven
  /// at drawn per trial from [1 - speed_spread, 1] (the same under either dispatch).
  double speed_spread = 0;
  /// Every path from its names' primitive (the paper's keys) to its names' end point, not its
  /// role's where fitting keyed a motion class by role (gp/primitives.h, task/end_point.h):
  /// what the role keys give, measured.
  bool paths_by_name = false;
};

/// The parameters of the table with bodies for `options` (diffdrive) and `spec`.
exec::BodiesExecutionParams bodiesParams(const EvalOptions& options, const task::TaskSpec& spec);
/// Every token of `d`'s record that had predecessors: "step 2 R3:move:G1 at 4.10 s,
/// released by R1:move:R3 at 4.10 s".
std::vector<std::string> describeWaits(const exec::Dispatch& d, const task::TaskSpec& spec);

/// Whether the model's decisions read the scene (positions): every variant but a scene
/// network of a fixed order, whose decisions follow from the steps so far. Async dispatch
/// asks such a policy for the next step only once every entity has settled.
bool policyReadsScene(const Model& model);
/// The same from a model's manifest alone (the coordinator node, which runs no network).
bool policyReadsScene(const tgn::ModelInfo& info);

struct Evaluation {
  std::string task, variant, execution;
  std::vector<std::string> entity_names;  ///< the test task's, in its order
  std::set<int> robot_entities;           ///< indices of its robots
  double arrival_radius_m = 0;            ///< its arrival radius
  std::vector<eval::TrialScore> scores;
  std::vector<exec::Trial> trials;
  /// Per trial: "" when every step matched, else the first step that differs, as
  /// "step K: predicted {R1:move:G2} demonstrated {R2:move:G2}" (K 1-based).
  std::vector<std::string> first_difference;
  eval::Summary summary;
  /// diffdrive on points or coordinated: the dispatch the runs had ("" otherwise),
  /// and the tokens that started before a predecessor under the learned dependencies ended.
  std::string dispatch;
  int precedence_violations = 0;
  /// Per trial with a dispatch: every token that had predecessors, "step 2 R3:move:G1 at
  /// 4.10 s, released by R1:move:R3 at 4.10 s" (who it waited for, and when).
  std::vector<std::vector<std::string>> waits;
  /// Coordinated runs, per trial: the makespan async dispatch would give were every token to
  /// take the time it took in the run (CoordinatedRun::async_bound_s; 0: not finished).
  std::vector<double> async_bound_s;
};

Evaluation evaluate(const Model& model, const task::TaskDir& test, const EvalOptions& options);

/// Human-readable table: one line per trial (a failed one adds its first differing step),
/// then the summary.
void printEvaluation(const Evaluation& e, std::ostream& out);
/// {"task", "variant", "execution", "trials", "osr", "ssr", "gcr", "fd", "per_trial": [...]}, with bodies
/// also "collisions", "trials_with_collision", "min_clearance_m", "makespan_s" (and per trial,
/// with its "failures").
std::string evaluationJson(const Evaluation& e);

}  // namespace ddace::pipeline
