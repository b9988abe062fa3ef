// The `scene` network (the default variant): what decides a step can depend on the
// configuration. Internal to the tgn module (includes <torch/torch.h>).
//
//   node features   the entity kind (one-hot robot, object, goal) and an identity
//                   embedding keyed by the entity's name; no position (a decision depends
//                   on how the scene is arranged, not where it is on the table; the paper's
//                   two position slots stay 0).
//   edge features   the relational basis of the pair i <- j (model_impl.cpp, relative()):
//                   the distance; nearness ranks 1 / (1 + the number of entities of j's kind
//                   nearer to i than j), the same for i seen from j, and the farness ranks
//                   (farther instead of nearer: "the farthest"); the order of j and of i
//                   along the table's axes among their kind, 1 / (1 + the number before
//                   it) from the left, the right, the front and the back (these four
//                   depend on the table's own axes: "the leftmost"); and the last step:
//                   i went to j, j went to i (moved, and now stands where the other stood
//                   as the step began: "the one who received the box"); and each one's
//                   last move, however many steps ago: i's last move went to j, j's to i
//                   ("the giver follows the receiver" after the receiver moved on). Ranks and
//                   orders count only rivals: an entity parked with another is none of a
//                   free one's (a parked one's are every one of its kind), and token by
//                   token one already given its part is nobody's. Orders are strict but for
//                   two at one place. The first two slots are 0 (they held the
//                   displacement x_j - x_i, measured and not kept: docs/tgn.md).
//                   Entities within task::togetherDistance of each other (the end-point
//                   rule: contact plus the arrival radius) are at one place: distance 0,
//                   and they do not outrank each other.
//   spatial         `gat_layers` x attention over the attention edges plus self-loops; the
//                   message from j to i is W_s x_j + W_e r_ij (it carries the edge
//                   features: a convex combination of W x_j alone cannot form x_j - x_i);
//                   the logit is GATv2's a . LeakyReLU(W_d x_i + W_s x_j + W_e r_ij);
//                   softmax over i's incoming edges; then ReLU, dropout and,
//                   from the second layer, a residual connection.
//   temporal        the mean over the entities' embeddings -> the 2-layer GRU (as `paper`).
//   heads           per entity i, from its own embedding h_i and the GRU output z:
//                   action = MLP(h_i, z); the target is a pointer: score(i, j) =
//                   v . ReLU(P_i h_i + P_j h_j + P_r r_ij + P_z z) for every other entity j,
//                   and a "none" score (in-place action) from the action MLP's hidden layer;
//                   END = linear(z). No output slot belongs to an entity index, so the heads
//                   are equivariant under a permutation of the entities.
#pragma once

#include <cstdint>
#include <vector>

#include <torch/torch.h>

#include "fused_kernels.h"
#include "network.h"

namespace ddace::tgn {

/// The relational basis of a pair i <- j (see above), slot by slot (the first two are 0);
/// each axis group is from the left, the right, the front and the back.
namespace basis {
enum Slot : int {
  kDistance = 2,
  kNearJ,         ///< j's nearness rank among its kind, seen from i
  kNearI,         ///< i's among its kind, seen from j
  kFarJ,          ///< j's farness rank
  kFarI,          ///< i's farness rank
  kAxisJ,         ///< j's order along the axes (4)
  kAxisI = 11,    ///< i's order along the axes (4)
  kWentTo = 15,   ///< i went to j in the last step
  kCameFrom,      ///< j went to i in the last step
  kLastMoveTo,    ///< i's last move went to j
  kLastMoveFrom,  ///< j's last move went to i
  kCount,
};
}  // namespace basis
inline constexpr int kRelativeFeatures = basis::kCount;

/// taken [..., N] (1 = a target no entity may point at) -> [..., 1, 1 + N], added to the
/// pointer's logits [..., N, 1 + N]: -1e9 on the taken targets' columns ("none" stays).
torch::Tensor takenMask(const torch::Tensor& taken);

struct SceneLayerImpl : torch::nn::Module {
  SceneLayerImpl(int in, int heads, int channels);
  /// x [S, N, in], rel [S, N, N, R] (pair i <- j), `in` the incoming edges (i receives from
  /// j) -> [S, N, heads * channels]; the attention is one fused kernel (fused_kernels.h).
  torch::Tensor forward(const torch::Tensor& x, const torch::Tensor& rel, const fused::InEdges& in);

  int heads_, channels_;
  torch::nn::Linear lin_src{nullptr}, lin_dst{nullptr}, lin_edge{nullptr};
  torch::Tensor att, bias;
};
TORCH_MODULE(SceneLayer);

struct SceneNetworkImpl : torch::nn::Module {
  /// `attention`: [N, N] bool, i receives from j (self-loops included).
  SceneNetworkImpl(const NetConfig& c, const torch::Tensor& attention);

  /// x [S, N, F], rel [S, N, N, R] -> node embeddings [S, N, width]: the last layer's output, and
  /// without the relative features each entity's own input beside it. `names` [S, N] long,
  /// when defined: the identity embedding's row each entity reads (shuffled names).
  torch::Tensor encode(const torch::Tensor& x, const torch::Tensor& rel, const torch::Tensor& names = {});
  /// nodes [..., N, width], rel [..., N, N, R], z [..., hidden] -> the heads.
  Heads heads(const torch::Tensor& nodes, const torch::Tensor& rel, const torch::Tensor& z);

  /// The pointer's terms that do not depend on the relative features: token by token
  /// (docs/tgn.md) they stay from token to token of a step while `rel` changes, so a
  /// token costs one pointerLogits, not the whole heads.
  struct PointerParts {
    torch::Tensor pi, pj;       ///< P_i h_i, P_j h_j: [P, N, k]
    torch::Tensor pz;           ///< P_z z: [P, k]
    torch::Tensor none;         ///< the "none" score: [..., N, 1]
    std::vector<int64_t> lead;  ///< the leading sizes of the scores: [..., N, N]
  };
  /// nodes [..., N, width], z [..., hidden], `hidden` the action MLP's hidden layer
  /// (hiddenOf) -> the parts.
  PointerParts pointerParts(const torch::Tensor& nodes, const torch::Tensor& z, const torch::Tensor& hidden);
  /// The action MLP's hidden layer ReLU(A_h h_i + A_z z): [..., N, hidden].
  torch::Tensor hiddenOf(const torch::Tensor& nodes, const torch::Tensor& z);
  /// The pointer's logits [..., N, 1 + N] ("none", then every entity; self masked) on `rel`
  /// [..., N, N, R]: heads().target.
  torch::Tensor pointerLogits(const PointerParts& parts, const torch::Tensor& rel);
  /// The same for the entities `rows` [M] only (one scene: `parts` of nodes [N, width]):
  /// `rel` [M, N, R], the rows' relative features -> [M, 1 + N].
  torch::Tensor pointerLogits(const PointerParts& parts, const torch::Tensor& rel, const torch::Tensor& rows);

  NetConfig cfg;
  torch::Tensor mask;       ///< [1, N, N, 1]
  fused::InEdges in_edges;  ///< the same as incoming edge lists
  Dropout drop;
  torch::Tensor self_mask;  ///< [N, N]: -1e9 on the diagonal
  torch::nn::Embedding identity{nullptr};
  std::vector<SceneLayer> layers;
  torch::nn::GRU gru{nullptr};
  torch::nn::Linear act_h{nullptr}, act_z{nullptr}, act_out{nullptr}, none_out{nullptr};
  torch::nn::Linear ptr_i{nullptr}, ptr_j{nullptr}, ptr_r{nullptr}, ptr_z{nullptr}, ptr_out{nullptr};
  torch::nn::Linear end{nullptr};
};
TORCH_MODULE(SceneNetwork);

}  // namespace ddace::tgn
