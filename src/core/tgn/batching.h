// Demonstrations as tensors, and padded mini-batches of them (internal to the tgn module).
#pragma once

#include <torch/torch.h>

#include <vector>

#include <Eigen/Core>

#include "network.h"

namespace ddace::tgn {

/// One demonstration as tensors: T sequence elements (snapshots, or frames for gnn).
struct Sequence {
  torch::Tensor x;       ///< [T, N, F] normalised inputs
  torch::Tensor action;  ///< [T, N] long, 0 = idle
  torch::Tensor target;  ///< [T, N] long, 0 = none
  torch::Tensor end;     ///< [T] long
  torch::Tensor delta;   ///< gnn: [T, N, 2] normalised next displacement
  torch::Tensor rel;     ///< scene: [T, N, N, R] relative features of every pair
  /// scene: the snapshots' positions [T][N] (canonical order, metres), for the relative
  /// features of a step's later tokens ("Token by token").
  std::vector<std::vector<Eigen::Vector2d>> positions;
};

/// A padded mini-batch: the encoder sees only real elements (BatchNorm statistics
/// must not include padding), scattered into [B*T] slots for the GRU.
struct Batch {
  int64_t b = 0, t = 0;
  torch::Tensor x, slot, valid, action, target, end, delta;
  torch::Tensor rel;        ///< scene: [S, N, N, R], the real elements
  torch::Tensor rel_slots;  ///< scene: [B, T, N, N, R]
  /// scene, training with shuffled names: [S, N] long, the row of the identity embedding
  /// each entity reads (undefined: its own).
  torch::Tensor names;
  /// scene: every slot's positions (canonical order, metres; empty for padding), [B * T].
  std::vector<std::vector<Eigen::Vector2d>> positions;
  /// scene, training token by token: [B, T, N] float, 1 where an entity's token of the
  /// step is given (it takes no loss) ...
  torch::Tensor given;
  /// ... and 1 where an entity is a given token's target (no other entity may point at
  /// it: the step's targets are exclusive). rel_slots then holds the relative features
  /// with the given entities out of the nearness ranks. Undefined: nothing given.
  torch::Tensor taken;
  /// scene, training token by token: [N, 1 + N] float, 1 where an entity that does not act
  /// in a step may still be chosen for the pair (DemonstratedTokens::may_point): the
  /// decoder chooses who acts one token at a time too.
  torch::Tensor may_point;
  /// scene, training token by token with carried loads: [B, T, N, N] float, 1 where the
  /// object j is a load at entity i's place (SequenceModel::Impl::loadsAt): i's pairs are
  /// j's too, one decision (their pointer logits add), and j's own are none.
  torch::Tensor carried;
};

/// The sequences `which` of `seqs` as one batch.
Batch collate(const std::vector<Sequence>& seqs, const std::vector<size_t>& which, bool gnn);
/// Every sequence of `seqs`, in order, as one batch (the eval pass).
Batch collateAll(const std::vector<Sequence>& seqs, bool gnn);

}  // namespace ddace::tgn
