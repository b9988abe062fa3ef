// SequenceModel::Impl: building the network and turning demonstrations into tensors.
#include "model_impl.h"

#include <algorithm>
#include <cmath>

#include "ddace/common/error.h"
#include "loss.h"

namespace ddace::tgn {

using torch::Tensor;

int SequenceModel::Impl::vocabIndex(const std::string& action) const {
  const auto it = std::find(info.vocabulary.begin(), info.vocabulary.end(), action);
  return it == info.vocabulary.end() ? -1 : static_cast<int>(it - info.vocabulary.begin());
}

void SequenceModel::Impl::build() {
  cfg.nodes = static_cast<int>(spec.entities.size());
  cfg.actions = static_cast<int>(info.vocabulary.size()) + 1;
  cfg.targets = cfg.nodes + 1;
  cfg.gnn = info.variant == "gnn";
  cfg.features = cfg.gnn ? 2 + cfg.actions + cfg.targets : 2;
  cfg.o = info.options;
  net = Network(cfg, maskFromEdges(cfg.nodes, info.attention_edges, true));
}

void SequenceModel::Impl::seededBuild() {
  torch::manual_seed(info.options.seed);
  build();
}

void SequenceModel::Impl::features(const std::vector<Eigen::Vector2d>& pos, const std::vector<task::Label>* labels, float* out) const {
  const int f = cfg.features;
  for (int i = 0; i < cfg.nodes; ++i) {
    float* row = out + i * f;
    std::fill(row, row + f, 0.f);
    row[0] = static_cast<float>((pos[i].x() - info.mean[0]) / info.std[0]);
    row[1] = static_cast<float>((pos[i].y() - info.mean[1]) / info.std[1]);
    if (labels) {
      const task::Label& l = (*labels)[i];
      const int a = l.isNull() ? 0 : vocabIndex(l.action) + 1;
      row[2 + std::max(a, 0)] = 1;
      row[2 + cfg.actions + (l.isNull() ? 0 : l.target + 1)] = 1;
    }
  }
}

Sequence SequenceModel::Impl::keyframeSequence(const task::Demonstration& d) const {
  const int64_t t = static_cast<int64_t>(d.snapshots.size()), n = cfg.nodes;
  Sequence s;
  s.x = torch::zeros({t, n, cfg.features});
  s.action = torch::zeros({t, n}, torch::kLong);
  s.target = torch::zeros({t, n}, torch::kLong);
  s.end = torch::zeros({t}, torch::kLong);
  auto act = s.action.accessor<int64_t, 2>();
  auto tgt = s.target.accessor<int64_t, 2>();
  for (int64_t k = 0; k < t; ++k) {
    features(d.snapshots[k].positions, nullptr, s.x[k].data_ptr<float>());
    if (d.snapshots[k].end) {
      s.end[k] = 1;
      continue;
    }
    for (const auto& tok : d.steps.at(static_cast<size_t>(k)).tokens) {
      act[k][tok.entity] = vocabIndex(tok.action) + 1;
      tgt[k][tok.entity] = tok.target + 1;
    }
  }
  return s;
}

Sequence SequenceModel::Impl::frameSequence(const task::Demonstration& d) const {
  const int64_t t = static_cast<int64_t>(d.rows()) - 1, n = cfg.nodes;
  Sequence s;
  s.x = torch::zeros({t, n, cfg.features});
  s.action = torch::zeros({t, n}, torch::kLong);
  s.target = torch::zeros({t, n}, torch::kLong);
  s.end = torch::zeros({t}, torch::kLong);
  s.delta = torch::zeros({t, n, 2});
  auto act = s.action.accessor<int64_t, 2>();
  auto tgt = s.target.accessor<int64_t, 2>();
  auto del = s.delta.accessor<float, 3>();
  for (int64_t r = 0; r < t; ++r) {
    features(d.positions[r], &d.labels[r], s.x[r].data_ptr<float>());
    for (int64_t i = 0; i < n; ++i) {
      const task::Label& l = d.labels[r + 1][i];
      act[r][i] = l.isNull() ? 0 : vocabIndex(l.action) + 1;
      tgt[r][i] = l.isNull() ? 0 : l.target + 1;
      const Eigen::Vector2d dp = d.positions[r + 1][i] - d.positions[r][i];
      del[r][i][0] = static_cast<float>(dp.x() / info.delta_std[0]);
      del[r][i][1] = static_cast<float>(dp.y() / info.delta_std[1]);
    }
  }
  s.end[t - 1] = 1;
  return s;
}

std::vector<Sequence> SequenceModel::Impl::sequences(const std::vector<task::Demonstration>& demos) const {
  std::vector<Sequence> out;
  for (const auto& d : demos) {
    if (d.entities() != static_cast<size_t>(cfg.nodes))
      throw Error(Diagnostic{d.source, 0, 0, "has " + std::to_string(d.entities()) + " entities, the model's task has " +
                                                 std::to_string(cfg.nodes)});
    for (const auto& step : d.steps)
      for (const auto& tok : step.tokens)
        if (vocabIndex(tok.action) < 0)
          throw Error(Diagnostic{d.source, 0, 0, "action '" + tok.action + "' is not in the model's vocabulary"});
    if (cfg.gnn) {
      if (d.rows() < 2) throw Error(Diagnostic{d.source, 0, 0, "needs at least two rows"});
      out.push_back(frameSequence(d));
    } else {
      out.push_back(keyframeSequence(d));
    }
  }
  return out;
}

double SequenceModel::Impl::accuracy(const std::vector<Sequence>& seqs) {
  torch::NoGradGuard no_grad;
  net->eval();
  std::vector<size_t> all(seqs.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = i;
  const Batch batch = collate(seqs, all, cfg.gnn);
  const Tensor ok = correctOf(run(net, batch), batch, cfg.gnn).to(torch::kFloat) * batch.valid;
  return (ok.sum() / batch.valid.sum()).item<double>();
}

SequenceModel::SequenceModel(std::shared_ptr<Impl> impl) : impl_(std::move(impl)) {}
SequenceModel::~SequenceModel() = default;

const task::TaskSpec& SequenceModel::spec() const { return impl_->spec; }
std::string SequenceModel::variant() const { return impl_->info.variant; }
const ModelInfo& SequenceModel::info() const { return impl_->info; }

namespace {

/// Mean/std of positions over every entity; frame_dt and displacement std for gnn.
void normalisation(const task::TaskDir& dir, bool gnn, ModelInfo& info) {
  double sum[2] = {0, 0}, sq[2] = {0, 0}, dsq[2] = {0, 0};
  double count = 0, dcount = 0, dt = 0;
  for (const auto& d : dir.demos) {
    auto add = [&](const std::vector<Eigen::Vector2d>& pos) {
      for (const auto& p : pos)
        for (int c = 0; c < 2; ++c) {
          sum[c] += p[c];
          sq[c] += p[c] * p[c];
        }
      count += static_cast<double>(pos.size());
    };
    if (gnn) {
      for (size_t r = 0; r < d.rows(); ++r) {
        add(d.positions[r]);
        if (r + 1 < d.rows()) {
          for (size_t i = 0; i < d.entities(); ++i)
            for (int c = 0; c < 2; ++c) dsq[c] += std::pow(d.positions[r + 1][i][c] - d.positions[r][i][c], 2);
          dcount += static_cast<double>(d.entities());
          dt += d.t[r + 1] - d.t[r];
        }
      }
    } else {
      for (const auto& s : d.snapshots) add(s.positions);
    }
  }
  for (int c = 0; c < 2; ++c) {
    info.mean[c] = sum[c] / count;
    info.std[c] = std::max(1e-3, std::sqrt(std::max(0.0, sq[c] / count - info.mean[c] * info.mean[c])));
    info.delta_std[c] = dcount > 0 ? std::max(1e-5, std::sqrt(dsq[c] / dcount)) : 1.0;
  }
  // Every displacement is counted once per entity; dt once per row pair.
  const double pairs = dcount > 0 ? dcount / static_cast<double>(dir.spec.entities.size()) : 0;
  info.frame_dt_s = pairs > 0 ? dt / pairs : 0.05;
}

}  // namespace

std::shared_ptr<SequenceModel::Impl> prepare(const task::TaskDir& train, const TrainOptions& options) {
  options.validate();
  if (train.demos.empty()) throw Error(Diagnostic{train.path, 0, 0, "no demonstrations to train on"});
  auto impl = std::make_shared<SequenceModel::Impl>();
  impl->spec = train.spec;
  ModelInfo& info = impl->info;
  info.variant = options.variant;
  info.options = options;
  info.options.refinement.seed = options.seed;
  info.vocabulary = train.vocabulary();
  const int n = static_cast<int>(train.spec.entities.size());
  size_t steps = 0;
  for (const auto& d : train.demos) steps += d.steps.size();
  if (steps == 0) throw Error(Diagnostic{train.path, 0, 0, "the demonstrations have no steps (no labelled actions)"});
  info.refined = graph::refine(train.demos, n, info.options.refinement);
  info.attention_edges = options.variant == "ddace" ? info.refined.kept : graph::fullyConnected(n);
  normalisation(train, options.variant == "gnn", info);
  return impl;
}

}  // namespace ddace::tgn
