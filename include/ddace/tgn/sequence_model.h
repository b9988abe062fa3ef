// The temporal graph network (DDACE, Sec. IV-B): *which* entities do *what* next.
//
// Owns: the networks (variants below), their trainer and predictor, the gnn baseline's
// rollout, and the model directory. Implemented with libtorch behind a pimpl: this header
// includes no torch. docs/tgn.md describes every variant and why `scene` is the default.
//
// Variants:
//   scene       (default) relative features (distance, nearness ranks) on the attention
//               edges, no absolute position, entity kinds, an identity embedding keyed by name,
//               per-entity action heads and a pointer over the candidate targets;
//               attention over E' lifted to entity kinds (see Variant).
//   paper       the paper's network: 3 x [GAT (2 heads, concatenated) -> BatchNorm ->
//               ReLU -> dropout] over E' made symmetric, mean pooling, a 2-layer GRU over
//               the keyframe snapshots, linear heads with one output slot per entity.
//               Node features: (x, y) normalised per coordinate, plus the identity
//               embedding. GAT semantics are PyTorch Geometric's GATConv.
//   full-graph  `paper` over every ordered pair (the paper's ablation).
//   gnn         the paper's end-to-end baseline: the `paper` encoder over every pair, run
//               on every frame; node features add the entity's current label; the heads
//               predict every entity's next displacement and label and the end. Loss:
//               MSE + cross-entropies. It does not predict steps: use rolloutGnn().
//
// Common to all:
//   entity order    everything runs internally in the canonical order of the entity
//                   names (sorted), and inputs and outputs are mapped from and to the
//                   task's order: the order of the entities in task.yaml changes no
//                   decision, no weight and no E'.
//   loss            sum of the mean cross-entropies of action, target (the scene variant:
//                   over the entities that act) and END; Adam with the gradient norm
//                   clipped at 1; mini-batches of whole demonstrations in a seeded order.
//   plan            what the demonstrations decide about training (fixed order, names
//                   shuffled, token by token, parked entities, step rules, attention
//                   edges, the identity embedding kept or not) is a TrainingPlan,
//                   computed once by planTraining and recorded apart from the options.
//   stopping        at `max_epochs`, or at a plateau: the best loss of the last
//                   `plateau_patience` epochs differs by less than `plateau_delta` from the
//                   best loss of the `plateau_patience` epochs before them, and the last
//                   epoch's loss is within `plateau_delta` of that best too.
//   determinism     weights initialised from the model's seed without touching torch's
//                   process-wide generator (its state is saved and restored), dropout
//                   from the network's own SplitMix64, `threads` intra-op threads only
//                   while training (restored afterwards).
#pragma once

#include <cstdint>
#include <iosfwd>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "ddace/graph/dependencies.h"
#include "ddace/graph/refinement.h"
#include "ddace/task/fingerprint.h"
#include "ddace/task/task_dir.h"

namespace ddace::tgn {

/// Format tag of manifest.yaml in a model directory. /3: SHA-256 digests of every file
/// and of the manifest itself, and the task fingerprint; /4: the step decoding rules
/// (StepRules); /5: whether the scene network saw the relative features
/// (`relative_features`, the "Fixed order" rule); /6: whether its training shuffled the
/// names (`shuffle_names`); /7: whether it decides a step token by token
/// (`token_by_token`) and keeps parked entities out of the nearness ranks
/// (`parked_out_of_ranks`); /8: the scene network's relational basis (farness ranks, axis
/// orders, the last step) and the carried loads among the step rules; /9: what training
/// decided (TrainingPlan, `plan`) apart from the requested `hyper_parameters` (the rules
/// switched off: `without`); /10: a carried load and its carrier one decision in the step
/// rules (`load_actions`), each one's last move in the relational basis; /11: the ensemble
/// (`plan.ensemble`; weights.pt holds its other members' weights as `member1`, `member2`,
/// ...); /12: the relational basis orders along the axes strictly (tied only at one
/// place); /13: entities at one place seen from one place in the relational basis; /14:
/// token by token chooses who acts too, a carrier's pairs are its load's, and a parked
/// entity is ranked among every one of its kind; /15: motion primitives by role
/// (primitives.yaml /4), the hyper-parameters without `attention`, `node_positions` and
/// `edge_displacement` (switches nothing set); /16: the end scene (`plan.end_scene`). Older
/// ones are refused (retrain).
inline constexpr const char* kModelFormat = "ddace-model/17";

/// The network of a model (docs/tgn.md). Names: "scene", "paper", "full-graph", "gnn".
enum class Variant {
  Scene,      ///< sees the scene: relative edge features, per-entity heads, pointer targets
  Paper,      ///< the paper's network over E'
  FullGraph,  ///< the paper's network over every pair (the paper's ablation)
  Gnn,        ///< the paper's end-to-end GNN baseline (frames, not steps)
};
const char* toString(Variant v);
/// Throws ddace::Error listing the names for an unknown one.
Variant variantFromString(const std::string& name);
/// Every variant, default first.
std::vector<Variant> allVariants();

/// Most training threads a model may ask for (manifest.yaml is outside input; more threads
/// than this machine has cores only slow tiny tensors down).
inline constexpr int kMaxThreads = 64;

/// The scene network's learning rules (docs/tgn.md: what each does, why, its test), each
/// on unless switched off by name with `ddace train --without LIST`.
enum class Rule {
  Relative,       ///< "relative": the relative edge features at all
  FixedOrder,     ///< "fixed-order": drop them when every demonstration has the same steps
  ShuffledNames,  ///< "shuffled-names": permute interchangeable names' embeddings in training
  TokenByToken,   ///< "token-by-token": decide a step's targets one token at a time
  Parked,         ///< "parked": parked entities are no rivals in the nearness ranks
  Ensemble,       ///< "ensemble": networks trained from several seeds vote on each decoded step
  EndScene,       ///< "end-scene": END waits for what every demonstration's last scene had
  NextTargets,    ///< "next-targets": an entity points next only at kinds its kind pointed at after such a move
};
const char* toString(Rule r);
/// Throws ddace::Error listing the names for an unknown one.
Rule ruleFromString(const std::string& name);
std::vector<Rule> allRules();
/// A comma-separated list of rule names ("" is none); throws ddace::Error naming a bad one.
std::set<Rule> rulesFromList(const std::string& list);

/// What the user asked of training (hyper-parameters, seed, rules switched off); what the
/// demonstrations decide is the TrainingPlan.
struct TrainOptions {
  Variant variant = Variant::Scene;
  int max_epochs = 400;
  uint64_t seed = 1;
  int heads = 2;           ///< GAT heads (concatenated)
  int head_channels = 16;  ///< channels per head: node embedding = heads * head_channels
  int gat_layers = 3;
  int gru_layers = 2;
  int gru_hidden = 64;
  bool identity_embedding = true;  ///< learned per-entity embedding (training may still drop it: TrainingPlan)
  int identity_dim = 8;
  int head_hidden = 32;  ///< scene variant: hidden units of the action and pointer heads
  /// The learning rules the user switched off (`ddace train --without LIST`); each is on
  /// by default. What each decides is computed from the demonstrations by planTraining.
  std::set<Rule> without;
  bool uses(Rule r) const { return without.count(r) == 0; }
  double weight_decay = 0;  ///< Adam's L2 penalty (as torch.optim.Adam's weight_decay)
  double dropout = 0.1;
  double learning_rate = 5e-3;
  int batch_demos = 8;                  ///< at most this many demonstrations per mini-batch, and at
                                        ///< most a quarter of them (at least 4 steps per epoch)
  int plateau_patience = 20;            ///< epochs
  double plateau_delta = 1e-3;          ///< loss
  int threads = 1;                      ///< at::set_num_threads during training (1..kMaxThreads)
  graph::RefinementOptions refinement;  ///< E' (variant ddace)

  /// Throws ddace::Error naming the first option out of range.
  void validate() const;
};

/// One training epoch, as printed and stored in loss.csv.
struct EpochRecord {
  int epoch = 0;             ///< 1-based
  double loss = 0;           ///< mean training loss over the epoch's mini-batches
  double step_accuracy = 0;  ///< ddace/full-graph: steps (incl. END) predicted exactly on the
                             ///< training demos (eval mode, true history); gnn: frames whose
                             ///< next labels are all right
  double seconds = 0;        ///< wall time since training started
};

/// What every step of the training demonstrations had in common, learned from them by
/// train() (scene variant only: the paper's networks decode each entity on its own, as
/// the paper) and applied by predictNext() when the entities' own most probable tokens
/// break it. The step is then decoded jointly: the tokens maximising the sum over the
/// entities of log p(action) + log p(target), an idle entity's target being free, under
/// the rules below (an exact assignment, deterministic and in the canonical entity order).
/// With no rule set, or when the independent tokens keep the rules, the decision is each
/// entity's own argmax. Every variant: a step in which no entity would act is never handed
/// on; it becomes the most probable step in which one does, or END when END is the more
/// probable of the two (docs/tgn.md, "No empty step").
struct StepRules {
  /// No two decisions of one step had the same target entity: a step's targets are
  /// used at most once ("no target" is not a target). With carried loads (load_actions) a
  /// load and its carrier are one decision: the load's token is not counted.
  bool exclusive_targets = false;
  /// Every step had exactly this many decisions (acting entities, carried loads not
  /// counted; 0: the number varied).
  int step_size = 0;
  /// Carried loads: the actions objects took (sorted), when in every training step an
  /// object took one only together with an entity at its place (not an object) taking the
  /// same action and target, and an entity at an object's place took one only together
  /// with the object: a carrier and its load are one decision (detail::coupleLoads).
  /// Empty: no such rule (no object acted, or a step broke it).
  std::vector<std::string> load_actions;
  /// The rules of the joint decoder (decodeStep); the carried loads apply after it.
  bool any() const { return exclusive_targets || step_size > 0; }
  bool operator==(const StepRules& o) const {
    return exclusive_targets == o.exclusive_targets && step_size == o.step_size && load_actions == o.load_actions;
  }
};

/// One relation of the entities at the end: at least `count` entities of `kind` (kindKey) were
/// at one place (task::togetherDistance, transitively) with an entity of kind `with` (another
/// one, where the kinds are the same).
struct EndCount {
  std::string kind, with;
  int count = 0;
  bool operator==(const EndCount& o) const { return kind == o.kind && with == o.with && count == o.count; }
};

/// "End scene" (docs/tgn.md): what the last scene of every training demonstration had in
/// common, counted by kind. Where it held in no earlier scene (`telling`), END is decided
/// once it holds; bound to a larger team, not before a count that grew with the team holds
/// (the bound model's Impl::end_waits). Empty: no such rule.
struct EndScene {
  std::vector<EndCount> counts;  ///< by kind, then with
  bool telling = false;
  bool operator==(const EndScene& o) const { return counts == o.counts && telling == o.telling; }
};

/// One transition of "Next targets" (docs/tgn.md): an entity of `kind` (kindKey) whose last
/// move went to an entity of kind `after` ("none": it never moved, or to nothing) took a
/// token at an entity of kind `target` ("none": in place).
struct NextTarget {
  std::string kind, after, target;
  bool operator==(const NextTarget& o) const { return kind == o.kind && after == o.after && target == o.target; }
  bool operator<(const NextTarget& o) const {
    return std::tie(kind, after, target) < std::tie(o.kind, o.after, o.target);
  }
};

/// "Ensemble" (docs/tgn.md): where the scene decides the steps, this many networks from
/// different seeds decide together (each decodes the step, the majority's is kept); a
/// manifest holds at most kMaxEnsemble and exactly what training makes (1 or this).
inline constexpr int kEnsembleMembers = 3;
inline constexpr int kMaxEnsemble = 8;

/// What the training demonstrations decide about training, computed once from them and the
/// request (planTraining) and recorded in the manifest apart from the TrainOptions. Every
/// enabling condition of a rule is stated there and nowhere else: the trainer, the network
/// and the decoder read the plan. Entity indices in the task's order.
struct TrainingPlan {
  /// Every demonstration has the same steps but for `slips` labelling slips (task::commonSteps).
  bool fixed_order = false;
  int slips = 0;
  /// Scene: the network sees the relative edge features (off on a fixed order: "Fixed order").
  bool relative_features = false;
  /// Scene: the network has the identity embedding (dropped when the network without it fit
  /// the training demonstrations better: "Names or the scene").
  bool identity_embedding = false;
  /// Scene: "Names or the scene" may try the network without the identity embedding: only
  /// where no name alone tells an entity from another of its kind (every entity of a kind
  /// with several is in a name group); else the names say what no scene can (queue's slots).
  bool names_or_scene = false;
  /// Scene: the groups whose identity embeddings training permutes ("Shuffled names";
  /// detail::interchangeableNames), each ascending; none when training kept the names
  /// (shuffled, the network fit its demonstrations worse: withNamesKept).
  std::vector<std::vector<int>> name_groups;
  /// Scene: a step's targets are decided one token at a time and trained so ("Token by token").
  bool token_by_token = false;
  /// Scene: an entity at one place with another is no rival in the ranks ("Parked entities").
  bool parked_out_of_ranks = false;
  /// Scene: the number of networks voting on each decoded step ("Ensemble"): trained alike
  /// from seeds derived from the model's (the first from the model's own); 1: one network.
  int ensemble = 1;
  StepRules step_rules;  ///< scene: learned from the training steps; else none
  /// Scene, where the scene decides (relative features): when a run is over ("End scene").
  EndScene end_scene;
  /// Scene, where the scene decides: every transition the training tokens took ("Next
  /// targets"; detail::nextTargetsOf), sorted. Empty: no such rule (a manifest without it).
  std::vector<NextTarget> next_targets;
  std::vector<graph::Edge> attention_edges;  ///< directed edges the network attends over (no self-loops)
  /// The same plan for the network without the identity embedding (no names to shuffle).
  TrainingPlan withoutIdentity() const;
  /// The same plan without shuffled names (training fell short with them: the trainer's
  /// "Shuffled names, unless they cost the fit").
  TrainingPlan withNamesKept() const;
  /// Empty when planTraining() could have made this plan for `options` (of its variant);
  /// else what could not be, for a reader of a manifest to report (a plan it cannot decode
  /// with must be refused, not run).
  std::string inconsistency(const TrainOptions& options) const;
  bool operator==(const TrainingPlan& o) const {
    return fixed_order == o.fixed_order && slips == o.slips && relative_features == o.relative_features &&
           identity_embedding == o.identity_embedding && names_or_scene == o.names_or_scene &&
           name_groups == o.name_groups && token_by_token == o.token_by_token &&
           parked_out_of_ranks == o.parked_out_of_ranks && ensemble == o.ensemble && step_rules == o.step_rules &&
           end_scene == o.end_scene && next_targets == o.next_targets && attention_edges == o.attention_edges;
  }
};

/// The plan of training `options.variant` on `train` whose E' is `refined` (the one place
/// where the demonstrations decide which rules apply). Throws ddace::Error for bad options.
TrainingPlan planTraining(const task::TaskDir& train, const TrainOptions& options, const graph::RefinedGraph& refined);

struct Prediction {
  bool end = false;
  double end_probability = 0;
  std::vector<task::Token> tokens;          ///< the next step, sorted by entity: at least one token, none when end
  std::vector<double> token_probabilities;  ///< one per token: p(action) * p(target)
  /// When end: what the scene lacks of the end scene every demonstration had (EndScene;
  /// detail::endSceneShort), "" when it holds or the model has none. With robots lost, such
  /// an END does not finish the task (pipeline::unfinishedEnd): the run aborts naming them.
  std::string end_short;
};

/// Size and SHA-256 of one file of a model directory, as the manifest records it.
struct FileDigest {
  uint64_t bytes = 0;
  std::string sha256;  ///< 64 hex digits
};

/// Everything a model directory records besides the weights (manifest.yaml, loss.csv).
struct ModelInfo {
  std::string format = kModelFormat;  ///< of the manifest it was read from (an older one is read too)
  Variant variant = Variant::Scene;
  TrainOptions options;                      ///< what the user asked (hyper-parameters, seed, rules off)
  TrainingPlan plan;                         ///< what the demonstrations decided
  std::vector<std::string> vocabulary;       ///< actions; class 0 of the action head is idle
  graph::RefinedGraph refined;               ///< the spectral refinement (ddace; computed for all variants)
  graph::Dependencies dependencies;          ///< which earlier tokens each token waits for (graph/dependencies.h)
  double mean[2] = {0, 0}, std[2] = {1, 1};  ///< position normalisation, metres
  double delta_std[2] = {1, 1};              ///< gnn: displacement normalisation, metres per frame
  double frame_dt_s = 0.05;                  ///< gnn: time between rolled-out frames
  std::vector<EpochRecord> history;          ///< loss per epoch
  std::string stop_reason;                   ///< "plateau" or "max_epochs"
  task::TaskFingerprint fingerprint;         ///< of the training directory (task.yaml and demos)
  /// The files the manifest binds by digest, by name in the model directory (task.yaml,
  /// weights.pt, loss.csv and, but for gnn, primitives.yaml). Filled by load().
  std::map<std::string, FileDigest> files;
};

/// What a model can run on besides its own task's entities (docs/tgn.md, "Other team
/// sizes"): the same kinds of entity in other numbers, where the rule it learned is stated by
/// the scene. An entity the network knows by name (an identity embedding whose name training
/// did not shuffle: a role of its own, or the rule refers to it) must be there by that name;
/// the others of its kind are interchangeable, any number of them.
struct Transfer {
  /// Why the model runs on its own task's entities only ("": it transfers): the paper's
  /// networks have one output slot per entity; a fixed order (Task 2's chain) or training
  /// without the relative features learned the names' order, not a rule of the scene.
  std::string refusal;
  std::vector<std::string> named;  ///< the entities known by name (task order)
  /// The kinds ("robot", "object:box", ...) of any number: their entities' names were shuffled
  /// in training, or the network has no identity embedding.
  std::vector<std::string> any_number;
  /// One line, as the manifest's `transfer` and `ddace inspect` say it.
  std::string text() const;
};
/// The transfer of a model of `spec` (its own task) with `info`'s variant and plan.
Transfer transferOf(const ModelInfo& info, const task::TaskSpec& spec);
/// An entity's kind as transfer compares kinds: "robot", or "object:box" with a type.
std::string kindKey(const task::Entity& e);

class SequenceModel {
 public:
  /// Trains on the demonstrations of `train` (spec + demos). One progress line per epoch
  /// ("epoch 12/400  loss 0.4310  step accuracy 0.873  1.2 s") goes to `progress` when not
  /// null. Throws ddace::Error for bad options or unusable data (no demonstrations, no steps).
  static SequenceModel train(const task::TaskDir& train, const TrainOptions& options, std::ostream* progress);
  /// Writes task.yaml, weights.pt, loss.csv and last manifest.yaml into `model_dir`
  /// (created). The manifest records the digest of those and of each of `bound_files`
  /// (names of files already written into `model_dir`, e.g. primitives.yaml), and its own.
  void save(const std::string& model_dir, const std::vector<std::string>& bound_files = {}) const;
  /// Reads a model directory: the manifest (its own digest first), then task.yaml, the
  /// weights and loss.csv, each checked against its recorded size and digest. A missing,
  /// truncated, corrupted, edited or mismatched file throws ddace::Error naming the file
  /// and what differs. Files bound besides those (primitives.yaml) are listed in
  /// info().files for the caller to verify (pipeline::loadModel).
  static SequenceModel load(const std::string& model_dir);

  /// The next step given the keyframe snapshots so far (positions of all entities in task
  /// order, metres, oldest first; at least one). Throws ddace::Error for the gnn variant,
  /// an empty history or a snapshot with the wrong number of entities.
  Prediction predictNext(const std::vector<task::Snapshot>& history) const;

  /// What the model can run on besides its own task's entities (transferOf).
  Transfer transfer() const;
  /// This model on the entities of `other` (docs/tgn.md, "Other team sizes"): the same
  /// kinds, other numbers or names. Each of other's entities reads the identity embedding of
  /// the model's entity of that name, or (a name the model does not know) of one of its kind's
  /// interchangeable entities; the attention edges are E' lifted to other's entities; a step
  /// size that was every actor's grows with them. Throws ddace::Error naming why not (the
  /// model's transfer refusal, a kind either lacks, an entity known by name that other lacks,
  /// or a new entity of a kind known by name only). The result predicts on other's snapshots
  /// (its spec() is other) and is not saved.
  SequenceModel boundTo(const task::TaskSpec& other) const;
  const task::TaskSpec& spec() const;
  /// The variant's name (for messages; info().variant is the enum).
  std::string variant() const;
  const ModelInfo& info() const;

  /// Fraction of the steps (and END) of `demos` predicted exactly from their true snapshot
  /// history (ddace/full-graph); for gnn the fraction of frames whose next labels are right.
  double stepAccuracy(const std::vector<task::Demonstration>& demos) const;

  SequenceModel(const SequenceModel&) = default;
  SequenceModel& operator=(const SequenceModel&) = default;
  SequenceModel(SequenceModel&&) noexcept = default;
  SequenceModel& operator=(SequenceModel&&) noexcept = default;
  ~SequenceModel();
  struct Impl;

 private:
  explicit SequenceModel(std::shared_ptr<Impl> impl);
  std::shared_ptr<Impl> impl_;
  friend task::Demonstration rolloutGnn(const SequenceModel&, const task::Demonstration&, int);
};

/// The gnn baseline's closed loop: starts every entity at `test_demo`'s first row
/// (positions and labels), then repeatedly predicts the next frame (displacements and
/// labels) from its own rolled-out history, until it predicts the end or `max_rows` rows
/// exist. Returns an analyzed Demonstration (t at the training frame rate, positions,
/// labels, has_label_columns of `test_demo`) whose steps and segments the evaluator
/// compares with the test demonstration. No GP is involved. Throws ddace::Error when the
/// model is not of variant gnn or the demonstration does not fit the model's task.
task::Demonstration rolloutGnn(const SequenceModel& model, const task::Demonstration& test_demo, int max_rows);

}  // namespace ddace::tgn
