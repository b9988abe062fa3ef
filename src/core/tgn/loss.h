// The training loss and the exact-step criterion (internal to the tgn module).
#pragma once

#include <torch/torch.h>

#include "batching.h"

namespace ddace::tgn {

/// Gradient norm clipping (also in the Python reference).
inline constexpr double kClipNorm = 1.0;

/// Sum of the mean cross-entropies of the action, target and END heads (plus the
/// displacement MSE for gnn), over the batch's real elements. `acting_targets`: the target
/// loss only over the entities that act (the scene variant's pointer), else over all
/// (idle entities have the target "none", as the paper's network was trained).
torch::Tensor lossOf(const Heads& h, const Batch& batch, bool gnn, bool acting_targets);

/// Per element: 1 when the prediction equals the truth (a step, END, or a frame's labels).
torch::Tensor correctOf(const Heads& h, const Batch& batch, bool gnn);

}  // namespace ddace::tgn
