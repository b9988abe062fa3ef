// SequenceModel's state and its data preparation (internal to the tgn module).
#pragma once

#include <torch/torch.h>

#include <memory>
#include <string>
#include <vector>

#include "batching.h"
#include "ddace/tgn/detail.h"
#include "ddace/tgn/sequence_model.h"
#include "network.h"
#include "scene_network.h"

namespace ddace::tgn {

/// The task's entities in canonical (name-sorted) order: every tensor of the model is in
/// this order, so that the order of task.yaml changes nothing.
struct EntityOrder {
  std::vector<int> task_of;       ///< [canonical] -> task index
  std::vector<int> canonical_of;  ///< [task index] -> canonical
  explicit EntityOrder(const task::TaskSpec& spec = {});
  int size() const { return static_cast<int>(task_of.size()); }
  /// A demonstration (raw rows and everything analyze() derived) in canonical order.
  task::Demonstration toCanonical(const task::Demonstration& d) const;
  /// Rows of a canonical demonstration back in task order (derived fields not filled).
  task::Demonstration rowsToTask(const task::Demonstration& d) const;
};

/// Demonstrated tokens (Impl::demonstratedTokens): per entity (canonical order) the action
/// classes [N][actions] and target slots [N][targets] the decoder may choose.
struct DemonstratedTokens {
  std::vector<bool> action_ok, target_ok;
  /// Token by token: [N][targets], the (entity, target) pairs an entity the action heads
  /// left idle may still be chosen for (its kind acted, it is not a carried load, and the
  /// target is a demonstrated entity, not "none").
  std::vector<bool> may_point;
};

struct SequenceModel::Impl {
  task::TaskSpec spec;  ///< in the task's order (as task.yaml)
  EntityOrder order;
  ModelInfo info;  ///< entity indices in the task's order
  NetConfig cfg;
  Network net{nullptr};         ///< paper, full-graph, gnn
  SceneNetwork scene{nullptr};  ///< scene: the network training trains (an ensemble's first member)
  /// scene, an ensemble (TrainingPlan::ensemble > 1): its other members, trained as `scene`
  /// from other seeds (memberSeed); each decodes a step, the majority decides.
  std::vector<SceneNetwork> others;
  std::vector<float> kinds;  ///< [canonical][3] one-hot entity kind
  /// Bound to another task's entities (SequenceModel::boundTo): runs, is not saved.
  bool bound = false;
  /// Bound: per count of info.plan.end_scene, whether END waits for it (it grew with the team).
  std::vector<bool> end_waits;

  bool isScene() const { return info.variant == Variant::Scene; }
  torch::nn::Module& module();
  /// Index of `action` in the vocabulary, or -1.
  int vocabIndex(const std::string& action) const;
  /// The network of `info` (shapes, attention edges), weights initialised from the model's
  /// seed; torch's process-wide generator is left as it was. `members`: the scene
  /// ensemble's networks to build (training builds and trains one at a time).
  void build(int members = 1);
  /// Scene: every member of the ensemble, `scene` first.
  std::vector<SceneNetwork> members() const;
  /// Normalised node features of one row / snapshot (canonical order) into out[N][features].
  void features(const std::vector<Eigen::Vector2d>& pos, const std::vector<task::Label>* labels, float* out) const;
  /// Relative features of every pair (canonical order) into out[N][N][kRelativeFeatures].
  /// `competing`, when given ([N], canonical): the ranks and axis orders count only these
  /// entities as rivals ("Token by token": those not yet given a part in the step).
  /// `history[0 .. count)`: the snapshots so far (canonical), the last the one whose
  /// features these are; the ones before it for the relations of the last step and of each
  /// entity's last move.
  void relative(const std::vector<Eigen::Vector2d>* history, size_t count, float* out,
                const std::vector<bool>* competing = nullptr) const;
  Sequence keyframeSequence(const task::Demonstration& canonical) const;
  Sequence frameSequence(const task::Demonstration& canonical) const;
  /// Every demonstration (task order) as a Sequence (keyframes, or frames for gnn); throws
  /// ddace::Error naming the demonstration when it does not fit the model.
  std::vector<Sequence> sequences(const std::vector<task::Demonstration>& demos) const;
  /// The network on a batch: outputs [B, T, ...]; scene: the node embeddings [B, T, N, W]
  /// and the GRU outputs [B, T, H] into `nodes` and `z` when given. `member`: the scene
  /// ensemble's network to run (0: `scene`).
  Heads run(const Batch& batch, torch::Tensor* nodes = nullptr, torch::Tensor* z = nullptr, int member = 0);
  /// The step decoder, the one predictNext and the accuracy check use: one step's decision
  /// (canonical order) from the heads at it. detail::decideStep under the plan's step
  /// rules; token by token, who acts and at what chosen one token at a time
  /// (chooseTokens); then the carried loads (detail::coupleLoads). `p_end` p(END); `la`
  /// [N][actions] and `lt` [N][targets] log-probabilities (token by token puts the chosen
  /// targets' log-probabilities into `lt`). Scene, token by token: `target_logits` [N,
  /// targets], `nodes` [N, W] and `z` [H] are the network's at the step (else unread).
  /// `history[0 .. count)`: the snapshots so far (canonical), the last the step's.
  /// `member`: the scene ensemble's network whose heads these are (token by token runs its
  /// heads again); an ensemble keeps its members' majority (detail::majorityDecision).
  /// First, scene only, p(END) under the end scene (endProbability); demonstrated tokens (demonstratedTokens): the
  /// actions and targets an entity's kind never took are set to -1e9 (the joint decoder's floor), in `lt` too.
  /// `demonstrated`: demonstratedTokens(), computed once by the caller (it does not change
  /// from step to step).
  detail::StepDecision decide(double p_end, const std::vector<double>& la, std::vector<double>& lt,
                              const torch::Tensor& target_logits, const torch::Tensor& nodes, const torch::Tensor& z,
                              const std::vector<Eigen::Vector2d>* history, size_t count,
                              const DemonstratedTokens& demonstrated, int member = 0) const;
  /// p(END) under the plan's end scene (detail::endProbability) at `pos` (canonical).
  double endProbability(double p_end, const std::vector<Eigen::Vector2d>& pos) const;
  /// What the scene at `pos` (canonical) lacks of the plan's end scene (detail::endSceneShort).
  std::string endSceneShort(const std::vector<Eigen::Vector2d>& pos) const;
  /// `pos` (canonical order) in the task's order.
  std::vector<Eigen::Vector2d> inTaskOrder(const std::vector<Eigen::Vector2d>& pos) const;
  /// Carried loads (StepRules::load_actions): every object of the task (canonical) with the
  /// entities, not objects, within task::togetherDistance of it in `pos` (canonical).
  std::vector<detail::Load> loadsAt(const std::vector<Eigen::Vector2d>& pos) const;
  /// `loads` (loadsAt) as a matrix [N, N] float: 1 where object j is a load at entity i's
  /// place. Token by token, i's pointer logits are then `logits + carried.mm(logits)` (one
  /// decision with its loads), in training and decoding alike.
  torch::Tensor carriedBy(const std::vector<detail::Load>& loads) const;
  /// Token by token (scene; docs/tgn.md): who acts in one step and at what, one token at a
  /// time. The step has as many tokens as the action heads chose entities (`acting`,
  /// canonical); each is the surest (entity, target) pair of the pointer's logits among the
  /// entities not yet given one (an acting entity at any demonstrated target, another at a
  /// pair of `demonstrated.may_point`), then given to the heads (its target taken, both out
  /// of the ranks and orders of the last snapshot of `history`) before the next.
  /// `target_logits` [N, targets] are the heads' with nothing given, on `nodes` [N, W] and
  /// `z` [H]. Returns per entity the target slot (0 = none; -1: given no token, idle) and
  /// its log-probability when chosen.
  std::pair<std::vector<int>, std::vector<double>> chooseTokens(const torch::Tensor& target_logits,
                                                                const torch::Tensor& nodes, const torch::Tensor& z,
                                                                const std::vector<Eigen::Vector2d>* history,
                                                                size_t count, const std::vector<bool>& acting,
                                                                const DemonstratedTokens& demonstrated,
                                                                const torch::Tensor& carried, int member = 0) const;
  /// Demonstrated tokens (scene; docs/tgn.md): per entity (canonical) the action classes
  /// [N][actions] and target slots [N][targets] its kind took in the training
  /// demonstrations (info.fingerprint.token_types); idle always. Other variants: all.
  DemonstratedTokens demonstratedTokens() const;
  /// Exact-step accuracy, eval mode: the steps (and END) decide() decodes exactly from
  /// their true history; gnn: frames whose next labels are all right.
  double accuracy(const std::vector<Sequence>& seqs);
  /// The same on a batch of every sequence (collateAll): training collates it once and
  /// reuses it after every epoch (the data do not change; the pass only reads the batch).
  double accuracy(const Batch& everything);
};

/// The relative features of one history (SequenceModel::Impl::relative) for one set of
/// competing entities after another: what does not depend on them (the pairs' distances,
/// each entity's others in order of nearness, the last moves) is computed once. Token by
/// token asks for them again after every token.
class PairRelations {
 public:
  /// `history[0 .. count)` as in SequenceModel::Impl::relative.
  PairRelations(const SequenceModel::Impl& model, const std::vector<Eigen::Vector2d>* history, size_t count);
  ~PairRelations();
  /// Into out[N][N][kRelativeFeatures]; `competing` as in SequenceModel::Impl::relative.
  /// `rows`, when given: the pairs (i, j) of these i only, into out[rows][N][kRelativeFeatures].
  void write(float* out, const std::vector<bool>* competing = nullptr,
             const std::vector<int64_t>* rows = nullptr) const;

 private:
  struct Scene;
  std::unique_ptr<Scene> scene_;
};

/// The seed of an ensemble's member k (0: the model's own).
uint64_t memberSeed(uint64_t seed, int k);

/// Spec, vocabulary, E', the TrainingPlan and normalisation: everything but the weights.
std::shared_ptr<SequenceModel::Impl> prepare(const task::TaskDir& train, const TrainOptions& options);

/// Throws ddace::Error naming the entity and the snapshot (or row) when a position is not
/// finite. `what` is "snapshot" or "row".
void requireFinite(const std::vector<Eigen::Vector2d>& pos, const task::TaskSpec& spec, const std::string& source,
                   const char* what, size_t index);

}  // namespace ddace::tgn
