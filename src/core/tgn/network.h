// The network modules of the temporal graph network (see include/ddace/tgn/sequence_model.h).
// Internal to the tgn module: includes <torch/torch.h>, never include it from include/.
#pragma once

#include <torch/torch.h>

#include <vector>

#include "ddace/common/random.h"
#include "ddace/graph/refinement.h"
#include "ddace/tgn/sequence_model.h"
#include "fused_kernels.h"

namespace ddace::tgn {

/// Which node receives from which: mask[i][j] = node i receives from node j (self-loops
/// included), and the same as incoming edge lists for the fused attention.
struct Attention {
  torch::Tensor mask;
  fused::InEdges in;
  explicit Attention(torch::Tensor m) : mask(std::move(m)), in(fused::inEdgesFromMask(mask)) {}
};

/// mask[target][source] for every edge (and [source][target] when `symmetric`), plus self-loops.
torch::Tensor maskFromEdges(int n, const std::vector<graph::Edge>& edges, bool symmetric);

/// GATConv semantics; all snapshots of a batch at once (the attention is one fused kernel).
struct GatLayerImpl : torch::nn::Module {
  GatLayerImpl(int in, int heads, int channels);
  /// x [S, N, in] -> [S, N, heads * channels].
  torch::Tensor forward(const torch::Tensor& x, const Attention& att);

  int heads_, channels_;
  torch::nn::Linear lin{nullptr};
  torch::Tensor att_src, att_dst, bias;
};
TORCH_MODULE(GatLayer);

/// As torch::dropout (keep with probability 1 - p, scale kept values by 1 / (1 - p)), with
/// masks from the network's own SplitMix64 seeded with the model's seed: they do not
/// depend on what else draws from torch's process-wide generator, and two 32-bit draws per
/// 64-bit number are several times cheaper than bernoulli_'s locked per-element draws.
class Dropout {
 public:
  Dropout(double p, uint64_t seed) : p_(p), rng_(seed ^ 0x5DEECE66DULL) {}
  torch::Tensor operator()(const torch::Tensor& x, bool training);

 private:
  double p_;
  SplitMix64 rng_;
};

struct NetConfig {
  int nodes = 0;
  int actions = 1;   ///< classes of the action head: idle + vocabulary
  int targets = 1;   ///< classes of the target head: none + entities
  int features = 2;  ///< input features per node (before the identity embedding)
  bool gnn = false;
  TrainOptions o;                  ///< the requested hyper-parameters
  bool identity_embedding = true;  ///< the plan's (TrainingPlan)
  bool relative_features = true;   ///< the plan's (scene: "Fixed order")
};

/// The heads' outputs for a batch of sequence elements.
struct Heads {
  torch::Tensor action;  ///< [..., N, actions] logits
  torch::Tensor target;  ///< [..., N, targets] logits (self masked)
  torch::Tensor end;     ///< [..., 2]
  torch::Tensor delta;   ///< gnn: [..., N, 2]
};

/// The `paper` network (also `full-graph` and `gnn`).
struct NetworkImpl : torch::nn::Module {
  NetworkImpl(const NetConfig& c, torch::Tensor attention);

  int64_t outputs() const;
  /// x [S, N, F] -> graph embeddings [S, width].
  torch::Tensor encode(torch::Tensor x);
  /// GRU outputs [..., hidden] -> the heads.
  Heads heads(const torch::Tensor& z);

  NetConfig cfg;
  Attention att;
  Dropout drop{cfg.o.dropout, cfg.o.seed};
  torch::Tensor self_mask;
  torch::nn::Embedding identity{nullptr};
  std::vector<GatLayer> gat;
  std::vector<torch::nn::BatchNorm1d> bn;
  torch::nn::GRU gru{nullptr};
  torch::nn::Linear head{nullptr};
};
TORCH_MODULE(Network);

}  // namespace ddace::tgn
