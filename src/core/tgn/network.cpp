// Network, trainer, predictor, weights I/O and the gnn rollout (see
// include/ddace/tgn/sequence_model.h); the fused kernels are in fused_kernels.cpp.
#include <torch/torch.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <ostream>
#include <set>
#include <sstream>

#include "ddace/common/error.h"
#include "ddace/common/random.h"
#include "ddace/tgn/sequence_model.h"
#include "fused_kernels.h"
#include "manifest.h"

namespace ddace::tgn {

namespace {

namespace fs = std::filesystem;
using torch::Tensor;

// ------------------------------------------------------------------ modules

/// Which node receives from which: mask[i][j] = node i receives from node j (self-loops
/// included), and the same as incoming edge lists for the fused attention.
struct Attention {
  Tensor mask;
  fused::InEdges in;
  explicit Attention(Tensor m) : mask(std::move(m)), in(fused::inEdgesFromMask(mask)) {}
};

/// GATConv semantics; all snapshots of a batch at once (the attention is one fused kernel).
struct GatLayerImpl : torch::nn::Module {
  GatLayerImpl(int in, int heads, int channels) : heads_(heads), channels_(channels) {
    lin = register_module("lin", torch::nn::Linear(torch::nn::LinearOptions(in, heads * channels).bias(false)));
    att_src = register_parameter("att_src", torch::empty({heads, channels}));
    att_dst = register_parameter("att_dst", torch::empty({heads, channels}));
    bias = register_parameter("bias", torch::zeros({heads * channels}));
    torch::nn::init::xavier_uniform_(lin->weight);
    torch::nn::init::xavier_uniform_(att_src);
    torch::nn::init::xavier_uniform_(att_dst);
  }

  /// x [S, N, in] -> [S, N, heads * channels].
  Tensor forward(const Tensor& x, const Attention& att) {
    const int64_t s = x.size(0), n = x.size(1);
    const Tensor h = lin(x).view({s, n, heads_, channels_});
    return fused::gatAttention(h, att_src, att_dst, att.in).view({s, n, heads_ * channels_}) + bias;
  }

  int heads_, channels_;
  torch::nn::Linear lin{nullptr};
  Tensor att_src, att_dst, bias;
};
TORCH_MODULE(GatLayer);

struct NetConfig {
  int nodes = 0;
  int actions = 1;   ///< classes of the action head: idle + vocabulary
  int targets = 1;   ///< classes of the target head: none + entities
  int features = 2;  ///< input features per node (before the identity embedding)
  bool gnn = false;
  TrainOptions o;
};

Tensor maskFromEdges(int n, const std::vector<graph::Edge>& edges, bool symmetric) {
  Tensor m = torch::eye(n, torch::kBool);
  auto a = m.accessor<bool, 2>();
  for (const auto& e : edges) {
    a[e.target][e.source] = true;  // message source -> target
    if (symmetric) a[e.source][e.target] = true;
  }
  return m;
}

struct NetworkImpl : torch::nn::Module {
  NetworkImpl(const NetConfig& c, Tensor attention) : cfg(c), att(std::move(attention)) {
    const TrainOptions& o = c.o;
    int in = c.features;
    if (o.identity_embedding) {
      identity = register_module("identity", torch::nn::Embedding(c.nodes, o.identity_dim));
      in += o.identity_dim;
    }
    const int width = o.heads * o.head_channels;
    for (int l = 0; l < o.gat_layers; ++l) {
      gat.push_back(register_module("gat" + std::to_string(l), GatLayer(l == 0 ? in : width, o.heads, o.head_channels)));
      bn.push_back(register_module("bn" + std::to_string(l), torch::nn::BatchNorm1d(width)));
    }
    gru = register_module("gru", torch::nn::GRU(torch::nn::GRUOptions(width, o.gru_hidden).num_layers(o.gru_layers).batch_first(true)));
    head = register_module("head", torch::nn::Linear(o.gru_hidden, outputs()));
    // The target head never proposes the entity itself.
    self_mask = torch::zeros({c.nodes, c.targets});
    for (int i = 0; i < c.nodes; ++i) self_mask[i][i + 1] = -1e9;
  }

  /// As torch::dropout (keep with probability 1 - p, scale kept values by 1 / (1 - p)), with
  /// masks from this network's own SplitMix64 seeded with the model's seed: they do not
  /// depend on what else draws from torch's process-wide generator, and two 32-bit draws per
  /// 64-bit number are several times cheaper than bernoulli_'s locked per-element draws.
  Tensor dropout(const Tensor& x) {
    const double p = cfg.o.dropout;
    if (!is_training() || p <= 0) return x;
    Tensor mask = torch::empty(x.sizes());
    float* m = mask.data_ptr<float>();
    const int64_t n = mask.numel();
    const uint64_t keep_below = static_cast<uint64_t>((1 - p) * 4294967296.0);  // 2^32 (1 - p)
    const float scale = static_cast<float>(1 / (1 - p));
    for (int64_t i = 0; i < n; i += 2) {
      const uint64_t r = dropout_rng.next();
      m[i] = (r & 0xffffffffULL) < keep_below ? scale : 0.f;
      if (i + 1 < n) m[i + 1] = (r >> 32) < keep_below ? scale : 0.f;
    }
    return x * mask;
  }

  int64_t outputs() const { return cfg.nodes * (cfg.actions + cfg.targets + (cfg.gnn ? 2 : 0)) + 2; }

  /// x [S, N, F] -> graph embeddings [S, width].
  Tensor encode(Tensor x) {
    const int64_t s = x.size(0), n = x.size(1);
    if (identity) x = torch::cat({x, identity->weight.unsqueeze(0).expand({s, n, cfg.o.identity_dim})}, 2);
    for (size_t l = 0; l < gat.size(); ++l) {
      x = gat[l]->forward(x, att);
      const int64_t w = x.size(2);
      x = bn[l]->forward(x.reshape({s * n, w})).view({s, n, w});
      x = dropout(torch::relu(x));
    }
    return x.mean(1);
  }

  struct Heads {
    Tensor action;  ///< [..., N, actions] logits
    Tensor target;  ///< [..., N, targets] logits (self masked)
    Tensor end;     ///< [..., 2]
    Tensor delta;   ///< gnn: [..., N, 2]
  };

  Heads heads(const Tensor& z) {
    const Tensor y = head(z);
    std::vector<int64_t> lead(z.sizes().begin(), z.sizes().end() - 1);
    auto shaped = [&](int64_t from, int64_t per) {
      std::vector<int64_t> shape = lead;
      shape.push_back(cfg.nodes);
      shape.push_back(per);
      return y.narrow(-1, from, cfg.nodes * per).reshape(shape);
    };
    Heads h;
    int64_t at = 0;
    h.action = shaped(at, cfg.actions);
    at += cfg.nodes * cfg.actions;
    h.target = shaped(at, cfg.targets) + self_mask;
    at += cfg.nodes * cfg.targets;
    if (cfg.gnn) {
      h.delta = shaped(at, 2);
      at += cfg.nodes * 2;
    }
    h.end = y.narrow(-1, at, 2);
    return h;
  }

  NetConfig cfg;
  Attention att;
  SplitMix64 dropout_rng{cfg.o.seed ^ 0x5DEECE66DULL};
  Tensor self_mask;
  torch::nn::Embedding identity{nullptr};
  std::vector<GatLayer> gat;
  std::vector<torch::nn::BatchNorm1d> bn;
  torch::nn::GRU gru{nullptr};
  torch::nn::Linear head{nullptr};
};
TORCH_MODULE(Network);

// ------------------------------------------------------------------ data

/// One demonstration as tensors: T sequence elements (snapshots, or frames for gnn).
struct Sequence {
  Tensor x;       ///< [T, N, F] normalised inputs
  Tensor action;  ///< [T, N] long, 0 = idle
  Tensor target;  ///< [T, N] long, 0 = none
  Tensor end;     ///< [T] long
  Tensor delta;   ///< gnn: [T, N, 2] normalised next displacement
};

/// A padded mini-batch: the encoder sees only real elements (BatchNorm statistics
/// must not include padding), scattered into [B*T] slots for the GRU.
struct Batch {
  int64_t b = 0, t = 0;
  Tensor x, slot, valid, action, target, end, delta;
};

Batch collate(const std::vector<Sequence>& seqs, const std::vector<size_t>& which, bool gnn) {
  Batch batch;
  batch.b = static_cast<int64_t>(which.size());
  for (size_t i : which) batch.t = std::max(batch.t, seqs[i].x.size(0));
  std::vector<Tensor> xs, acts, tgts, ends, deltas;
  std::vector<int64_t> slots;
  for (size_t k = 0; k < which.size(); ++k) {
    const Sequence& s = seqs[which[k]];
    xs.push_back(s.x);
    acts.push_back(s.action);
    tgts.push_back(s.target);
    ends.push_back(s.end);
    if (gnn) deltas.push_back(s.delta);
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
  return batch;
}

NetworkImpl::Heads run(Network& net, const Batch& batch) {
  const Tensor emb = net->encode(batch.x);
  Tensor seq = torch::zeros({batch.b * batch.t, emb.size(1)}).index_copy(0, batch.slot, emb);
  return net->heads(fused::gru(net->gru, seq.view({batch.b, batch.t, emb.size(1)})).first);
}

Tensor nll(const Tensor& logits, const Tensor& target) {
  return -torch::log_softmax(logits, -1).gather(-1, target.unsqueeze(-1)).squeeze(-1);
}

Tensor lossOf(const NetworkImpl::Heads& h, const Batch& batch, bool gnn) {
  const Tensor valid = batch.valid;
  const Tensor count = valid.sum();
  const Tensor vn = valid.unsqueeze(-1);
  const int64_t n = batch.action.size(2);
  Tensor loss = (nll(h.action, batch.action) * vn).sum() / (count * n) +
                (nll(h.target, batch.target) * vn).sum() / (count * n) + (nll(h.end, batch.end) * valid).sum() / count;
  if (gnn) loss = loss + ((h.delta - batch.delta).pow(2) * vn.unsqueeze(-1)).sum() / (count * n * 2);
  return loss;
}

/// Per element: 1 when the prediction equals the truth (a step, END, or a frame's labels).
Tensor correctOf(const NetworkImpl::Heads& h, const Batch& batch, bool gnn) {
  const Tensor act = h.action.argmax(-1), tgt = h.target.argmax(-1), end = h.end.argmax(-1);
  const Tensor entity_ok = act.eq(batch.action).logical_and(batch.action.eq(0).logical_or(tgt.eq(batch.target)));
  const Tensor labels_ok = entity_ok.all(-1);
  if (gnn) return labels_ok;
  return end.eq(batch.end).logical_and(batch.end.eq(1).logical_or(labels_ok));
}

constexpr double kClipNorm = 1.0;  // gradient norm clipping (also in the Python reference)

}  // namespace

// ------------------------------------------------------------------ the model

struct SequenceModel::Impl {
  task::TaskSpec spec;
  ModelInfo info;
  NetConfig cfg;
  Network net{nullptr};

  int vocabIndex(const std::string& action) const {
    const auto it = std::find(info.vocabulary.begin(), info.vocabulary.end(), action);
    return it == info.vocabulary.end() ? -1 : static_cast<int>(it - info.vocabulary.begin());
  }

  void build() {
    cfg.nodes = static_cast<int>(spec.entities.size());
    cfg.actions = static_cast<int>(info.vocabulary.size()) + 1;
    cfg.targets = cfg.nodes + 1;
    cfg.gnn = info.variant == "gnn";
    cfg.features = cfg.gnn ? 2 + cfg.actions + cfg.targets : 2;
    cfg.o = info.options;
    net = Network(cfg, maskFromEdges(cfg.nodes, info.attention_edges, true));
  }

  /// build() with the weights initialised from the model's seed (the initialisers draw
  /// from torch's process-wide generator).
  void seededBuild() {
    torch::manual_seed(info.options.seed);
    build();
  }

  /// Normalised node features of one row / snapshot.
  void features(const std::vector<Eigen::Vector2d>& pos, const std::vector<task::Label>* labels, float* out) const {
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

  Sequence keyframeSequence(const task::Demonstration& d) const {
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

  Sequence frameSequence(const task::Demonstration& d) const {
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

  std::vector<Sequence> sequences(const std::vector<task::Demonstration>& demos) const {
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

  double accuracy(const std::vector<Sequence>& seqs) {
    torch::NoGradGuard no_grad;
    net->eval();
    std::vector<size_t> all(seqs.size());
    for (size_t i = 0; i < all.size(); ++i) all[i] = i;
    const Batch batch = collate(seqs, all, cfg.gnn);
    const Tensor ok = correctOf(run(net, batch), batch, cfg.gnn).to(torch::kFloat) * batch.valid;
    return (ok.sum() / batch.valid.sum()).item<double>();
  }
};

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

/// Spec, vocabulary, E', attention edges and normalisation: everything but the weights.
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

}  // namespace

SequenceModel SequenceModel::train(const task::TaskDir& train, const TrainOptions& options, std::ostream* progress) {
  auto impl = prepare(train, options);
  const auto started = std::chrono::steady_clock::now();
  at::set_num_threads(options.threads);
  impl->seededBuild();
  Network& net = impl->net;
  const bool gnn = impl->cfg.gnn;
  const std::vector<Sequence> seqs = impl->sequences(train.demos);
  fused::FlatParameters parameters(net->parameters());  // Adam as torch::optim::Adam, in a few ops
  SplitMix64 rng(options.seed ^ 0xD1B54A32D192ED03ULL);
  std::vector<size_t> order(seqs.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  ModelInfo& info = impl->info;
  info.stop_reason = "max_epochs";
  // At least 4 optimiser steps per epoch when there are few demonstrations (few-shot).
  const size_t bs = std::min(static_cast<size_t>(options.batch_demos), std::max<size_t>(1, (seqs.size() + 3) / 4));
  for (int epoch = 1; epoch <= options.max_epochs; ++epoch) {
    for (size_t i = order.size(); i > 1; --i) std::swap(order[i - 1], order[rng.next() % i]);
    net->train();
    double total = 0;
    int batches = 0;
    for (size_t from = 0; from < order.size(); from += bs) {
      const std::vector<size_t> which(order.begin() + static_cast<long>(from),
                                      order.begin() + static_cast<long>(std::min(order.size(), from + bs)));
      const Batch batch = collate(seqs, which, gnn);
      parameters.zeroGrad();
      const Tensor loss = lossOf(run(net, batch), batch, gnn);
      loss.backward();
      // GRUs on few sequences occasionally take a huge step; clipping keeps training monotone.
      parameters.clipGradNorm(kClipNorm);
      parameters.adamStep(options.learning_rate);
      total += loss.item<double>();
      ++batches;
    }
    EpochRecord rec;
    rec.epoch = epoch;
    rec.loss = total / batches;
    rec.step_accuracy = impl->accuracy(seqs);
    rec.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    info.history.push_back(rec);
    if (progress) {
      const std::ios::fmtflags flags = progress->flags();
      const std::streamsize precision = progress->precision();
      *progress << "epoch " << epoch << "/" << options.max_epochs << "  loss " << std::fixed << std::setprecision(4)
                << rec.loss << "  " << (gnn ? "frame label accuracy " : "step accuracy ") << std::setprecision(3)
                << rec.step_accuracy << "  " << std::setprecision(1) << rec.seconds << " s" << std::endl;
      progress->flags(flags);
      progress->precision(precision);
    }
    if (detail::atPlateau(info.history, options.plateau_patience, options.plateau_delta)) {
      info.stop_reason = "plateau";
      break;
    }
  }
  net->eval();
  return SequenceModel(impl);
}

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

task::Demonstration rolloutGnn(const SequenceModel& model, const task::Demonstration& test_demo, int max_rows) {
  const SequenceModel::Impl& m = *model.impl_;
  if (!m.cfg.gnn) throw Error("rolloutGnn: the model is of variant '" + m.info.variant + "', not gnn");
  const int n = m.cfg.nodes;
  if (test_demo.entities() != static_cast<size_t>(n) || test_demo.rows() == 0)
    throw Error(Diagnostic{test_demo.source, 0, 0, "does not fit the model's task (" + std::to_string(n) + " entities)"});
  if (max_rows < 1) throw Error("rolloutGnn: max_rows must be at least 1");
  torch::NoGradGuard no_grad;
  Network net = m.net;
  task::Demonstration out;
  out.source = "gnn rollout of " + test_demo.source;
  out.has_label_columns = test_demo.has_label_columns;
  out.t.push_back(0);
  out.positions.push_back(test_demo.positions[0]);
  out.labels.push_back(test_demo.labels[0]);
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
  out.analyze();
  return out;
}

// ------------------------------------------------------------------ files

void SequenceModel::save(const std::string& model_dir) const {
  std::error_code ec;
  fs::create_directories(model_dir, ec);
  if (ec) throw Error(Diagnostic{model_dir, 0, 0, "cannot create the model directory: " + ec.message()});
  const std::string weights = (fs::path(model_dir) / files::kWeights).string();
  try {
    torch::serialize::OutputArchive archive;
    impl_->net->save(archive);
    archive.save_to(weights);
  } catch (const c10::Error& e) {
    throw Error(Diagnostic{weights, 0, 0, std::string("cannot write the weights: ") + e.what_without_backtrace()});
  }
  task::writeTaskYaml(impl_->spec, (fs::path(model_dir) / files::kTask).string());
  files::writeFile((fs::path(model_dir) / files::kLoss).string(), files::lossCsvText(impl_->info.history));
  files::writeFile((fs::path(model_dir) / files::kManifest).string(),
                   files::manifestText(impl_->info, impl_->spec, files::fileHash(weights), fs::file_size(weights)));
}

SequenceModel SequenceModel::load(const std::string& model_dir) {
  const fs::path dir(model_dir);
  if (!fs::is_directory(dir)) throw Error(Diagnostic{model_dir, 0, 0, "not a model directory (does not exist)"});
  auto impl = std::make_shared<Impl>();
  const std::string manifest = (dir / files::kManifest).string(), weights = (dir / files::kWeights).string();
  if (!fs::exists(manifest))
    throw Error(Diagnostic{manifest, 0, 0, "missing: " + model_dir + " is not a model directory (ddace train writes one)"});
  impl->spec = task::readTaskYaml((dir / files::kTask).string());
  uint64_t hash = 0, bytes = 0;
  impl->info = files::parseManifest(manifest, impl->spec, &hash, &bytes);
  impl->info.history = files::readLossCsv((dir / files::kLoss).string());
  std::error_code ec;
  const uint64_t size = fs::file_size(weights, ec);
  if (ec) throw Error(Diagnostic{weights, 0, 0, "cannot read the weights (missing?)"});
  if (size != bytes)
    throw Error(Diagnostic{weights, 0, 0, "truncated or replaced: " + std::to_string(size) + " bytes, the manifest says " +
                                              std::to_string(bytes)});
  if (files::fileHash(weights) != hash)
    throw Error(Diagnostic{weights, 0, 0, "corrupted: its checksum does not match " + manifest});
  at::set_num_threads(impl->info.options.threads);
  impl->seededBuild();
  // Module::load replaces tensors whatever their shape, so the shapes are checked here.
  std::vector<std::pair<std::string, std::vector<int64_t>>> expected;
  for (const auto& p : impl->net->named_parameters()) expected.emplace_back(p.key(), p.value().sizes().vec());
  for (const auto& b : impl->net->named_buffers()) expected.emplace_back(b.key(), b.value().sizes().vec());
  try {
    torch::serialize::InputArchive archive;
    archive.load_from(weights);
    impl->net->load(archive);
  } catch (const c10::Error& e) {
    throw Error(Diagnostic{weights, 0, 0, std::string("does not fit the manifest's network: ") + e.what_without_backtrace()});
  }
  std::map<std::string, std::vector<int64_t>> loaded;
  for (const auto& p : impl->net->named_parameters()) loaded[p.key()] = p.value().sizes().vec();
  for (const auto& b : impl->net->named_buffers()) loaded[b.key()] = b.value().sizes().vec();
  for (const auto& [name, shape] : expected)
    if (loaded[name] != shape)
      throw Error(Diagnostic{weights, 0, 0, "does not fit the network of " + manifest + ": tensor '" + name +
                                                "' has another shape"});
  impl->net->eval();
  return SequenceModel(impl);
}

void writeTrainingTensors(const task::TaskDir& train, const TrainOptions& options, const std::string& path) {
  auto impl = prepare(train, options);
  impl->build();
  const std::vector<Sequence> seqs = impl->sequences(train.demos);
  std::ostringstream out;
  const NetConfig& c = impl->cfg;
  out << "# ddace tgn training tensors (keyframe variants); read by bench/tgn_train_reference.py\n";
  out << "nodes " << c.nodes << "\nactions " << c.actions << "\ntargets " << c.targets << "\nfeatures " << c.features
      << "\ndemos " << seqs.size() << "\nmask";
  const Tensor mask = impl->net->att.mask.to(torch::kLong);
  for (int64_t i = 0; i < mask.numel(); ++i) out << ' ' << mask.view(-1)[i].item<int64_t>();
  out << '\n' << std::setprecision(9);
  for (const auto& s : seqs) {
    out << "sequence " << s.x.size(0) << "\nx";
    const Tensor x = s.x.contiguous().view(-1);
    for (int64_t i = 0; i < x.numel(); ++i) out << ' ' << x[i].item<float>();
    for (const auto& [name, t] : {std::pair<const char*, Tensor>{"action", s.action}, {"target", s.target}, {"end", s.end}}) {
      out << '\n' << name;
      const Tensor v = t.contiguous().view(-1);
      for (int64_t i = 0; i < v.numel(); ++i) out << ' ' << v[i].item<int64_t>();
    }
    out << '\n';
  }
  files::writeFile(path, out.str());
}

namespace detail {

bool atPlateau(const std::vector<EpochRecord>& history, int patience, double delta) {
  // The best loss of the last `p` epochs within delta of the best of the `p` before them (a
  // recovering spike is not a plateau), and the last epoch's too: the weights kept are the
  // last epoch's, and an epoch that just took a bad step (Adam now and then does, even with
  // clipping) must not end training.
  const int64_t p = patience, n = static_cast<int64_t>(history.size());
  if (p < 1 || n < 2 * p) return false;
  double before = std::numeric_limits<double>::infinity(), recent = before;
  for (int64_t e = n - 2 * p; e < n; ++e) {
    double& best = e < n - p ? before : recent;
    best = std::min(best, history[static_cast<size_t>(e)].loss);
  }
  return std::abs(before - recent) < delta && history.back().loss - recent < delta;
}

std::vector<float> gatForward(const GatWeights& w, const std::vector<float>& x, int nodes,
                              const std::vector<graph::Edge>& edges) {
  const int width = w.heads * w.channels;
  if (x.size() != static_cast<size_t>(nodes * w.in) || w.weight.size() != static_cast<size_t>(width * w.in) ||
      w.att_src.size() != static_cast<size_t>(width) || w.att_dst.size() != static_cast<size_t>(width) ||
      w.bias.size() != static_cast<size_t>(width))
    throw Error("gatForward: array sizes do not match in/heads/channels/nodes");
  for (const auto& e : edges)
    if (e.source < 0 || e.source >= nodes || e.target < 0 || e.target >= nodes)
      throw Error("gatForward: an edge names a node outside 0.." + std::to_string(nodes - 1));
  torch::NoGradGuard no_grad;
  GatLayer layer(w.in, w.heads, w.channels);
  auto from = [](const std::vector<float>& v, std::vector<int64_t> shape) {
    return torch::from_blob(const_cast<float*>(v.data()), shape).clone();
  };
  layer->lin->weight.copy_(from(w.weight, {width, w.in}));
  layer->att_src.copy_(from(w.att_src, {w.heads, w.channels}));
  layer->att_dst.copy_(from(w.att_dst, {w.heads, w.channels}));
  layer->bias.copy_(from(w.bias, {width}));
  const Tensor y = layer->forward(from(x, {1, nodes, w.in}), Attention(maskFromEdges(nodes, edges, false))).contiguous();
  return std::vector<float>(y.data_ptr<float>(), y.data_ptr<float>() + y.numel());
}

}  // namespace detail
}  // namespace ddace::tgn
