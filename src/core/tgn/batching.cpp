#include "batching.h"

#include <algorithm>

namespace ddace::tgn {

using torch::Tensor;

Batch collate(const std::vector<Sequence>& seqs, const std::vector<size_t>& which, bool gnn) {
  Batch batch;
  batch.b = static_cast<int64_t>(which.size());
  for (size_t i : which) batch.t = std::max(batch.t, seqs[i].x.size(0));
  std::vector<Tensor> xs, acts, tgts, ends, deltas, rels;
  std::vector<int64_t> slots;
  for (size_t k = 0; k < which.size(); ++k) {
    const Sequence& s = seqs[which[k]];
    xs.push_back(s.x);
    acts.push_back(s.action);
    tgts.push_back(s.target);
    ends.push_back(s.end);
    if (gnn) deltas.push_back(s.delta);
    if (s.rel.defined()) rels.push_back(s.rel);
    for (int64_t j = 0; j < s.x.size(0); ++j) slots.push_back(static_cast<int64_t>(k) * batch.t + j);
  }
  batch.x = torch::cat(xs);
  batch.slot = torch::tensor(slots, torch::kLong);
  const int64_t n = batch.x.size(1), bt = batch.b * batch.t;
  auto scatter = [&](const Tensor& values, std::vector<int64_t> shape) {
    std::vector<int64_t> flat = {bt};
    flat.insert(flat.end(), values.sizes().begin() + 1, values.sizes().end());
    Tensor out = torch::zeros(flat, values.options()).index_copy(0, batch.slot, values);
    return out.view(shape);
  };
  batch.valid = scatter(torch::ones({batch.x.size(0)}), {batch.b, batch.t});
  batch.action = scatter(torch::cat(acts), {batch.b, batch.t, n});
  batch.target = scatter(torch::cat(tgts), {batch.b, batch.t, n});
  batch.end = scatter(torch::cat(ends), {batch.b, batch.t});
  if (gnn) batch.delta = scatter(torch::cat(deltas), {batch.b, batch.t, n, 2});
  if (!rels.empty()) {
    batch.positions.resize(static_cast<size_t>(bt));
    for (size_t k = 0; k < which.size(); ++k) {
      const Sequence& s = seqs[which[k]];
      for (size_t j = 0; j < s.positions.size(); ++j)
        batch.positions[k * static_cast<size_t>(batch.t) + j] = s.positions[j];
    }
    batch.rel = torch::cat(rels);
    batch.rel_slots = scatter(batch.rel, {batch.b, batch.t, n, n, batch.rel.size(3)});
  }
  return batch;
}

Batch collateAll(const std::vector<Sequence>& seqs, bool gnn) {
  std::vector<size_t> all(seqs.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = i;
  return collate(seqs, all, gnn);
}

}  // namespace ddace::tgn
