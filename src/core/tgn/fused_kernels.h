// Fused kernels of the temporal graph network, with hand-written backward passes.
//
// Why: the network's tensors are tiny (12 nodes, 2 heads x 16 channels, batches of 8
// sequences), so an op-by-op formulation spends its time in the dispatcher and the
// autograd graph, not in arithmetic: a 2-layer GRU over T steps alone records ~25 T
// autograd nodes. Each kernel here is one autograd node whose forward and backward are
// plain loops (Eigen for the matrix products). The semantics are exactly PyTorch's;
// test/unit/tgn/test_fused_kernels.cpp checks values and gradients against autograd of
// the op-by-op formulation.
//
// Internal to the tgn module: includes <torch/torch.h>, never include it from include/.
#pragma once

#include <torch/torch.h>

#include <vector>

namespace ddace::tgn::fused {

/// The incoming edges of every node (self-loops included), grouped by target (CSR):
/// node i receives from source[k] for k in [offset[i], offset[i+1]).
struct InEdges {
  torch::Tensor offset;  ///< [N + 1] int64
  torch::Tensor source;  ///< [E] int64
};

/// mask[i][j] = node i receives from node j.
InEdges inEdgesFromMask(const torch::Tensor& mask);

/// GATConv's attention and aggregation (LeakyReLU slope 0.2, softmax over each node's
/// incoming edges, no attention dropout): h [S, N, H, C] is the linear transform of the
/// node features, att_src / att_dst [H, C]. Returns [S, N, H, C]:
///   out_i^h = sum_{j in in(i)} alpha_ij^h h_j^h,
///   alpha_ij^h = softmax_j LeakyReLU(<att_dst^h, h_i^h> + <att_src^h, h_j^h>).
/// Differentiable in h, att_src and att_dst.
torch::Tensor gatAttention(const torch::Tensor& h, const torch::Tensor& att_src, const torch::Tensor& att_dst,
                           const InEdges& edges);

/// The scene network's attention layer (src/core/tgn/scene_network.h) on dense pairs: for
/// every receiver i, head h and sender j in in(i) (self-loop included), with the message
/// m_ij = hs_j + he_ij and LeakyReLU slope 0.2,
///   logit_ij = <att, LeakyReLU(hd_i + m_ij)>   (GATv2 with edge features),
///   out_i = sum_{j in in(i)} softmax_j(logit_ij) m_ij + bias.
/// hs (sender), hd (receiver) [S, N, H, C], he [S, N, N, H, C] (pair i <- j; pairs that are
/// not edges are never read), att [H, C], bias [H * C]. Returns [S, N, H * C];
/// differentiable in hs, hd, he, att and bias (he's gradient is 0 off the edges).
torch::Tensor sceneAttentionV2(const torch::Tensor& hs, const torch::Tensor& hd, const torch::Tensor& he,
                               const torch::Tensor& att, const torch::Tensor& bias, const InEdges& edges);

/// The scene network's pointer scores without the output bias: for every pair (i, j),
///   score_ij = <v, ReLU(a_i + b_j + r_ij + z)>,
/// a [P, M, K] (the M rows asked for), b [P, N, K], r [P, M, N, K], z [P, K], v [K].
/// Returns [P, M, N]; differentiable in all.
torch::Tensor pointerScores(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& r,
                            const torch::Tensor& z, const torch::Tensor& v);

/// One GRU layer's recurrence with PyTorch's gate equations (gate order r, z, n):
///   r = sigmoid(gi_r + gh_r), z = sigmoid(gi_z + gh_z), n = tanh(gi_n + r * gh_n),
///   h' = (1 - z) * n + z * h,  with gh = h w_hh^T + b_hh,
/// where gi [B, T, 3H] = x w_ih^T + b_ih is computed by the caller for all steps at once.
/// h0 [B, H]. Returns the hidden states [B, T, H]; differentiable in gi, w_hh, b_hh, h0.
torch::Tensor gruRecurrence(const torch::Tensor& gi, const torch::Tensor& w_hh, const torch::Tensor& b_hh,
                            const torch::Tensor& h0);

/// A multi-layer GRU (batch first, no inter-layer dropout) with the parameters of a
/// torch::nn::GRU module (weight_ih_l<k>, weight_hh_l<k>, bias_ih_l<k>, bias_hh_l<k>).
/// x [B, T, I], h0 [L, B, H] or undefined (zeros). Returns {output [B, T, H], h_n [L, B, H]}.
std::pair<torch::Tensor, torch::Tensor> gru(torch::nn::GRU& module, const torch::Tensor& x,
                                            const torch::Tensor& h0 = {});

/// All parameters of a module as views of one flat buffer, their gradients as views of
/// another, so that zeroing, norm clipping and Adam are a few ops in all instead of a few
/// per tensor (the network has ~30 parameter tensors).
class FlatParameters {
 public:
  explicit FlatParameters(std::vector<torch::Tensor> parameters);
  /// Gives every parameter its own storage again (e.g. before saving).
  ~FlatParameters();
  FlatParameters(const FlatParameters&) = delete;
  FlatParameters& operator=(const FlatParameters&) = delete;

  void zeroGrad() { grad_.zero_(); }
  /// torch::nn::utils::clip_grad_norm_ (2-norm over all gradients); returns the norm before clipping.
  double clipGradNorm(double max_norm);
  /// One step of torch.optim.Adam (betas 0.9/0.999, eps 1e-8, L2 weight decay as its
  /// `weight_decay`: the gradient gets weight_decay * parameter; no amsgrad).
  void adamStep(double learning_rate, double weight_decay = 0);

 private:
  std::vector<torch::Tensor> parameters_;
  torch::Tensor data_, grad_, exp_avg_, exp_avg_sq_;
  int64_t step_ = 0;
};

}  // namespace ddace::tgn::fused
