// The temporal graph network (DDACE, Sec. IV-B): *which* entities do *what* next.
//
// Owns: the network (3 GAT layers over the refined edge set E' -> global mean
// pooling -> 2-layer GRU over the keyframe snapshots -> heads), its trainer and
// predictor, the `full-graph` and `gnn` variants, and the model directory.
// Implemented with libtorch behind a pimpl: this header includes no torch.
//
// Network (variant `ddace`; `full-graph` only swaps the edge set):
//   node features   per snapshot, per entity: (x, y) normalised by the training set's
//                   per-coordinate mean and standard deviation over every entity in every
//                   training snapshot, i.e. x_n = (x - mean_x) / std_x (the scene's table
//                   region maps to about [-2, 2]); nothing depends on a particular start or
//                   goal, so new start-goal configurations in the same workspace need no
//                   retraining. Optional learned identity embedding per entity
//                   (`identity_embedding`, default on: it measured better,
//                   docs/bench/tgn_train.md),
//                   concatenated to (x, y).
//   spatial         3 x [GAT (2 heads, concatenated) -> BatchNorm -> ReLU -> dropout].
//                   GAT semantics are PyTorch Geometric's GATConv: x'_i = bias +
//                   ||_h sum_{j in N(i) u {i}} a^h_ij W^h x_j, a^h_ij = softmax_j LeakyReLU_0.2(
//                   <att_dst^h, W^h x_i> + <att_src^h, W^h x_j>), over each node's incoming
//                   edges plus a self-loop. The attention edges are E' made symmetric
//                   (an interaction informs both ends), plus self-loops.
//   pooling         mean over the entities -> one graph embedding per snapshot.
//   temporal        2-layer GRU over the snapshots of one demonstration, hidden state zero
//                   at the first snapshot; output k sees snapshots 0..k.
//   heads           linear, from the GRU output k: per entity the action of step k
//                   (classes: idle + vocabulary) and its target (classes: none + entities;
//                   the entity itself is masked out), and END (2 classes).
//   loss            sum of the three mean cross-entropies; Adam with the gradient norm clipped
//                   at 1; mini-batches of whole demonstrations in a seeded shuffled order.
//   stopping        at `max_epochs`, or at a plateau: the best loss of the last
//                   `plateau_patience` epochs differs by less than `plateau_delta` from the
//                   best loss of the `plateau_patience` epochs before them, and the last
//                   epoch's loss is within `plateau_delta` of that best too (never stop on a
//                   spike: the weights kept are the last epoch's).
//   determinism     torch::manual_seed(seed), at::set_num_threads(threads) (default 1: the
//                   tensors are tiny and one thread is both fastest and reproducible).
//
// Variant `gnn` (the paper's end-to-end baseline): the same encoder over the fully connected
// graph, run on every frame (row) instead of keyframes. Node features add the entity's
// current label (one-hot action, one-hot target); the heads predict, for the next frame,
// every entity's displacement (normalised by the training displacements' std), its label,
// and whether the demonstration ends there. Loss: MSE + cross-entropies. It does not
// predict steps: use rolloutGnn().
#pragma once

#include <cstdint>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

#include "ddace/graph/refinement.h"
#include "ddace/task/task_dir.h"

namespace ddace::tgn {

/// Format tag of manifest.yaml in a model directory.
inline constexpr const char* kModelFormat = "ddace-model/1";

struct TrainOptions {
  std::string variant = "ddace";  ///< ddace | full-graph | gnn
  int max_epochs = 400;
  uint64_t seed = 1;
  int heads = 2;                   ///< GAT heads (concatenated)
  int head_channels = 16;          ///< channels per head: node embedding = heads * head_channels
  int gat_layers = 3;
  int gru_layers = 2;
  int gru_hidden = 64;
  bool identity_embedding = true;  ///< learned per-entity embedding concatenated to (x, y)
  int identity_dim = 8;
  double dropout = 0.1;
  double learning_rate = 5e-3;
  int batch_demos = 8;             ///< at most this many demonstrations per mini-batch, and at
                                   ///< most a quarter of them (at least 4 steps per epoch)
  int plateau_patience = 20;       ///< epochs
  double plateau_delta = 1e-3;     ///< loss
  int threads = 1;                 ///< at::set_num_threads
  graph::RefinementOptions refinement;  ///< E' (variant ddace)

  /// Throws ddace::Error naming the first option out of range.
  void validate() const;
};

/// One training epoch, as printed and stored in loss.csv.
struct EpochRecord {
  int epoch = 0;               ///< 1-based
  double loss = 0;             ///< mean training loss over the epoch's mini-batches
  double step_accuracy = 0;    ///< ddace/full-graph: steps (incl. END) predicted exactly on the
                               ///< training demos (eval mode, true history); gnn: frames whose
                               ///< next labels are all right
  double seconds = 0;          ///< wall time since training started
};

struct Prediction {
  bool end = false;
  double end_probability = 0;
  std::vector<task::Token> tokens;          ///< the next step, sorted by entity (empty when end)
  std::vector<double> token_probabilities;  ///< one per token: p(action) * p(target)
};

/// Everything a model directory records besides the weights (manifest.yaml, loss.csv).
struct ModelInfo {
  std::string variant;
  TrainOptions options;                  ///< hyper-parameters and seed used
  std::vector<std::string> vocabulary;   ///< actions; class 0 of the action head is idle
  graph::RefinedGraph refined;           ///< the spectral refinement (ddace; computed for all variants)
  std::vector<graph::Edge> attention_edges;  ///< directed edges the GAT attends over (no self-loops)
  double mean[2] = {0, 0}, std[2] = {1, 1};  ///< position normalisation, metres
  double delta_std[2] = {1, 1};          ///< gnn: displacement normalisation, metres per frame
  double frame_dt_s = 0.05;              ///< gnn: time between rolled-out frames
  std::vector<EpochRecord> history;      ///< loss per epoch
  std::string stop_reason;               ///< "plateau" or "max_epochs"
};

class SequenceModel {
 public:
  /// Trains on the demonstrations of `train` (spec + demos). One progress line per epoch
  /// ("epoch 12/400  loss 0.4310  step accuracy 0.873  1.2 s") goes to `progress` when not
  /// null. Throws ddace::Error for bad options or unusable data (no demonstrations, no steps).
  static SequenceModel train(const task::TaskDir& train, const TrainOptions& options,
                             std::ostream* progress);
  /// Writes manifest.yaml, task.yaml, weights.pt and loss.csv into `model_dir` (created).
  void save(const std::string& model_dir) const;
  /// Reads a model directory. A missing, truncated, corrupted or mismatched file throws
  /// ddace::Error naming the file.
  static SequenceModel load(const std::string& model_dir);

  /// The next step given the keyframe snapshots so far (positions of all entities in task
  /// order, metres, oldest first; at least one). Throws ddace::Error for the gnn variant,
  /// an empty history or a snapshot with the wrong number of entities.
  Prediction predictNext(const std::vector<task::Snapshot>& history) const;

  const task::TaskSpec& spec() const;
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
task::Demonstration rolloutGnn(const SequenceModel& model, const task::Demonstration& test_demo,
                               int max_rows);

}  // namespace ddace::tgn
