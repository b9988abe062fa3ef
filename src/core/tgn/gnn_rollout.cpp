// The gnn baseline's closed loop (tgn::rolloutGnn).
#include <torch/torch.h>

#include "ddace/common/error.h"
#include "model_impl.h"

namespace ddace::tgn {

using torch::Tensor;

task::Demonstration rolloutGnn(const SequenceModel& model, const task::Demonstration& test_demo, int max_rows) {
  const SequenceModel::Impl& m = *model.impl_;
  if (!m.cfg.gnn)
    throw Error("rolloutGnn: the model is of variant '" + std::string(toString(m.info.variant)) + "', not gnn");
  const int n = m.cfg.nodes;
  if (test_demo.entities() != static_cast<size_t>(n) || test_demo.rows() == 0)
    throw Error(
        Diagnostic{test_demo.source, 0, 0, "does not fit the model's task (" + std::to_string(n) + " entities)"});
  if (max_rows < 1) throw Error("rolloutGnn: max_rows must be at least 1");
  requireFinite(test_demo.positions[0], m.spec, test_demo.source, "row", 0);
  torch::NoGradGuard no_grad;
  Network net = m.net;
  // Rolled out in the canonical entity order, returned in the task's.
  const task::Demonstration start = m.order.toCanonical(test_demo);
  task::Demonstration out;
  out.source = "gnn rollout of " + test_demo.source;
  out.has_label_columns = start.has_label_columns;
  out.t.push_back(0);
  out.positions.push_back(start.positions[0]);
  out.labels.push_back(start.labels[0]);
  Tensor hidden;
  Tensor x = torch::zeros({1, n, m.cfg.features});
  while (static_cast<int>(out.rows()) < max_rows) {
    m.features(out.positions.back(), &out.labels.back(), x.data_ptr<float>());
    const Tensor emb = net->encode(x);  // [1, width]
    auto [y, h] = fused::gru(net->gru, emb.unsqueeze(0), hidden);
    hidden = h;
    const auto heads = net->heads(y.squeeze(0).squeeze(0));
    const Tensor act = heads.action.argmax(-1), tgt = heads.target.argmax(-1);
    auto a = act.accessor<int64_t, 1>();
    auto tg = tgt.accessor<int64_t, 1>();
    auto d = heads.delta.accessor<float, 2>();
    std::vector<Eigen::Vector2d> pos = out.positions.back();
    std::vector<task::Label> labels(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) {
      pos[i] += Eigen::Vector2d(d[i][0] * m.info.delta_std[0], d[i][1] * m.info.delta_std[1]);
      if (a[i] > 0 && out.has_label_columns[i])
        labels[i] = {m.info.vocabulary[static_cast<size_t>(a[i] - 1)], static_cast<int>(tg[i]) - 1};
    }
    out.t.push_back(out.t.back() + m.info.frame_dt_s);
    out.positions.push_back(pos);
    out.labels.push_back(labels);
    if (torch::softmax(heads.end, -1)[1].item<double>() > 0.5) break;
  }
  task::Demonstration result = m.order.rowsToTask(out);
  result.analyze();
  return result;
}

}  // namespace ddace::tgn
