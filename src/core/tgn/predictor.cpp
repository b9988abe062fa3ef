// SequenceModel::predictNext and stepAccuracy.
#include <torch/torch.h>

#include "ddace/common/error.h"
#include "model_impl.h"

namespace ddace::tgn {

using torch::Tensor;

double SequenceModel::stepAccuracy(const std::vector<task::Demonstration>& demos) const {
  if (demos.empty()) throw Error("step accuracy: no demonstrations");
  return impl_->accuracy(impl_->sequences(demos));
}

Prediction SequenceModel::predictNext(const std::vector<task::Snapshot>& history) const {
  const Impl& m = *impl_;
  if (m.cfg.gnn) throw Error("the gnn variant does not predict steps; use tgn::rolloutGnn");
  if (history.empty()) throw Error("predictNext: the snapshot history is empty");
  const int64_t t = static_cast<int64_t>(history.size()), n = m.cfg.nodes;
  for (size_t k = 0; k < history.size(); ++k)
    if (history[k].positions.size() != static_cast<size_t>(n))
      throw Error("predictNext: snapshot " + std::to_string(k) + " has " + std::to_string(history[k].positions.size()) +
                  " positions, the task has " + std::to_string(n) + " entities");
  torch::NoGradGuard no_grad;
  Tensor x = torch::zeros({t, n, m.cfg.features});
  for (int64_t k = 0; k < t; ++k) m.features(history[k].positions, nullptr, x[k].data_ptr<float>());
  Network net = m.net;
  const Tensor emb = net->encode(x);
  const Tensor out = fused::gru(net->gru, emb.unsqueeze(0)).first.select(1, t - 1).squeeze(0);
  const auto h = net->heads(out);
  const Tensor pa = torch::softmax(h.action, -1), pt = torch::softmax(h.target, -1);
  Prediction p;
  p.end_probability = torch::softmax(h.end, -1)[1].item<double>();
  p.end = p.end_probability > 0.5;
  if (p.end) return p;
  auto a = pa.accessor<float, 2>();
  auto tg = pt.accessor<float, 2>();
  for (int64_t i = 0; i < n; ++i) {
    int best = 0;
    for (int c = 1; c < m.cfg.actions; ++c)
      if (a[i][c] > a[i][best]) best = c;
    if (best == 0) continue;
    int target = 0;
    for (int c = 1; c < m.cfg.targets; ++c)
      if (tg[i][c] > tg[i][target]) target = c;
    p.tokens.push_back({static_cast<int>(i), m.info.vocabulary[static_cast<size_t>(best - 1)], target - 1});
    p.token_probabilities.push_back(static_cast<double>(a[i][best]) * tg[i][target]);
  }
  return p;
}

}  // namespace ddace::tgn
