// The network modules (see network.h); the fused kernels are in kernel_*.cpp, one per file.
#include "network.h"

#include <string>

namespace ddace::tgn {

using torch::Tensor;

Tensor maskFromEdges(int n, const std::vector<graph::Edge>& edges, bool symmetric) {
  Tensor m = torch::eye(n, torch::kBool);
  auto a = m.accessor<bool, 2>();
  for (const auto& e : edges) {
    a[e.target][e.source] = true;  // message source -> target
    if (symmetric) a[e.source][e.target] = true;
  }
  return m;
}

GatLayerImpl::GatLayerImpl(int in, int heads, int channels) : heads_(heads), channels_(channels) {
  lin = register_module("lin", torch::nn::Linear(torch::nn::LinearOptions(in, heads * channels).bias(false)));
  att_src = register_parameter("att_src", torch::empty({heads, channels}));
  att_dst = register_parameter("att_dst", torch::empty({heads, channels}));
  bias = register_parameter("bias", torch::zeros({heads * channels}));
  torch::nn::init::xavier_uniform_(lin->weight);
  torch::nn::init::xavier_uniform_(att_src);
  torch::nn::init::xavier_uniform_(att_dst);
}

Tensor GatLayerImpl::forward(const Tensor& x, const Attention& att) {
  const int64_t s = x.size(0), n = x.size(1);
  const Tensor h = lin(x).view({s, n, heads_, channels_});
  return fused::gatAttention(h, att_src, att_dst, att.in).view({s, n, heads_ * channels_}) + bias;
}

NetworkImpl::NetworkImpl(const NetConfig& c, Tensor attention) : cfg(c), att(std::move(attention)) {
  const TrainOptions& o = c.o;
  int in = c.features;
  if (c.identity_embedding) {
    identity = register_module("identity", torch::nn::Embedding(c.nodes, o.identity_dim));
    in += o.identity_dim;
  }
  const int width = o.heads * o.head_channels;
  for (int l = 0; l < o.gat_layers; ++l) {
    gat.push_back(register_module("gat" + std::to_string(l), GatLayer(l == 0 ? in : width, o.heads, o.head_channels)));
    bn.push_back(register_module("bn" + std::to_string(l), torch::nn::BatchNorm1d(width)));
  }
  gru = register_module(
      "gru", torch::nn::GRU(torch::nn::GRUOptions(width, o.gru_hidden).num_layers(o.gru_layers).batch_first(true)));
  head = register_module("head", torch::nn::Linear(o.gru_hidden, outputs()));
  // The target head never proposes the entity itself.
  self_mask = torch::zeros({c.nodes, c.targets});
  for (int i = 0; i < c.nodes; ++i) self_mask[i][i + 1] = -1e9;
}

Tensor Dropout::operator()(const Tensor& x, bool training) {
  if (!training || p_ <= 0) return x;
  Tensor mask = torch::empty(x.sizes());
  float* m = mask.data_ptr<float>();
  const int64_t n = mask.numel();
  const uint64_t keep_below = static_cast<uint64_t>((1 - p_) * 4294967296.0);  // 2^32 (1 - p)
  const float scale = static_cast<float>(1 / (1 - p_));
  for (int64_t i = 0; i < n; i += 2) {
    const uint64_t r = rng_.next();
    m[i] = (r & 0xffffffffULL) < keep_below ? scale : 0.f;
    if (i + 1 < n) m[i + 1] = (r >> 32) < keep_below ? scale : 0.f;
  }
  return x * mask;
}

int64_t NetworkImpl::outputs() const {
  return cfg.nodes * (cfg.actions + cfg.targets + (cfg.gnn ? 2 : 0)) + 2;
}

Tensor NetworkImpl::encode(Tensor x) {
  const int64_t s = x.size(0), n = x.size(1);
  if (identity) x = torch::cat({x, identity->weight.unsqueeze(0).expand({s, n, cfg.o.identity_dim})}, 2);
  for (size_t l = 0; l < gat.size(); ++l) {
    x = gat[l]->forward(x, att);
    const int64_t w = x.size(2);
    x = bn[l]->forward(x.reshape({s * n, w})).view({s, n, w});
    x = drop(torch::relu(x), is_training());
  }
  return x.mean(1);
}

Heads NetworkImpl::heads(const Tensor& z) {
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

}  // namespace ddace::tgn
