// The GRU recurrence kernel and the fused multi-layer GRU (fused_kernels.h).
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "ddace/common/error.h"
#include "fused_kernels.h"
#include "kernel_common.h"

namespace ddace::tgn::fused {

namespace {

float sigmoid(float v) {
  return 1.f / (1.f + std::exp(-v));
}

struct GruRecurrenceFn : torch::autograd::Function<GruRecurrenceFn> {
  static Tensor forward(AutogradContext* ctx, Tensor gi, Tensor w_hh, Tensor b_hh, Tensor h0) {
    gi = gi.contiguous();
    w_hh = w_hh.contiguous();
    b_hh = b_hh.contiguous();
    const int64_t b_n = gi.size(0), t_n = gi.size(1), g_n = gi.size(2), h_n = g_n / 3;
    Tensor hs = torch::empty({b_n, t_n, h_n}), h_prev = torch::empty({b_n, t_n, h_n});
    Tensor gates = torch::empty({b_n, t_n, g_n});  // r, z, n after their nonlinearity
    Tensor gh_n = torch::empty({b_n, t_n, h_n});   // w_hn h + b_hn (the part r multiplies)
    const Eigen::Map<const RowMatrix> w(w_hh.data_ptr<float>(), g_n, h_n);
    const Eigen::Map<const RowVector> bias(b_hh.data_ptr<float>(), g_n);
    RowMatrix h = Eigen::Map<const RowMatrix>(h0.contiguous().data_ptr<float>(), b_n, h_n);
    RowMatrix gh(b_n, g_n);
    const float* gip = gi.data_ptr<float>();
    float *hsp = hs.data_ptr<float>(), *hpp = h_prev.data_ptr<float>(), *gp = gates.data_ptr<float>(),
          *ghp = gh_n.data_ptr<float>();
    for (int64_t t = 0; t < t_n; ++t) {
      gh.noalias() = h * w.transpose();
      gh.rowwise() += bias;
      for (int64_t b = 0; b < b_n; ++b) {
        const int64_t row = b * t_n + t;
        const float* x = gip + row * g_n;
        float* g = gp + row * g_n;
        for (int64_t u = 0; u < h_n; ++u) {
          const float r = sigmoid(x[u] + gh(b, u));
          const float z = sigmoid(x[h_n + u] + gh(b, h_n + u));
          const float hn = gh(b, 2 * h_n + u);
          const float n = std::tanh(x[2 * h_n + u] + r * hn);
          g[u] = r;
          g[h_n + u] = z;
          g[2 * h_n + u] = n;
          ghp[row * h_n + u] = hn;
          hpp[row * h_n + u] = h(b, u);
          h(b, u) = (1 - z) * n + z * h(b, u);
          hsp[row * h_n + u] = h(b, u);
        }
      }
    }
    save(ctx, {{"w_hh", w_hh}, {"h_prev", h_prev}, {"gates", gates}, {"gh_n", gh_n}});
    return hs;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    const Tensor w_hh = saved(ctx, "w_hh"), h_prev = saved(ctx, "h_prev"), gates = saved(ctx, "gates"),
                 gh_n = saved(ctx, "gh_n");
    const int64_t b_n = gates.size(0), t_n = gates.size(1), g_n = gates.size(2), h_n = g_n / 3;
    const Tensor dhs = grads[0].defined() ? grads[0].contiguous() : torch::zeros({b_n, t_n, h_n});
    Tensor dgi = torch::empty({b_n, t_n, g_n}), dw = torch::empty({g_n, h_n}), db = torch::empty({g_n}),
           dh0 = torch::empty({b_n, h_n});
    const Eigen::Map<const RowMatrix> w(w_hh.data_ptr<float>(), g_n, h_n);
    Eigen::Map<RowMatrix> dw_m(dw.data_ptr<float>(), g_n, h_n);
    Eigen::Map<RowVector> db_m(db.data_ptr<float>(), g_n);
    Eigen::Map<RowMatrix> dh(dh0.data_ptr<float>(), b_n, h_n);  // carried dL/dh, ends as dL/dh0
    dw_m.setZero();
    db_m.setZero();
    dh.setZero();
    RowMatrix dgh(b_n, g_n);
    const float *go = dhs.data_ptr<float>(), *gp = gates.data_ptr<float>(), *ghp = gh_n.data_ptr<float>(),
                *hpp = h_prev.data_ptr<float>();
    float* dgip = dgi.data_ptr<float>();
    for (int64_t t = t_n - 1; t >= 0; --t) {
      for (int64_t b = 0; b < b_n; ++b) {
        const int64_t row = b * t_n + t;
        const float* g = gp + row * g_n;
        float* dx = dgip + row * g_n;
        for (int64_t u = 0; u < h_n; ++u) {
          const float r = g[u], z = g[h_n + u], n = g[2 * h_n + u];
          const float d = dh(b, u) + go[row * h_n + u];
          const float dn_pre = d * (1 - z) * (1 - n * n);
          const float dr_pre = dn_pre * ghp[row * h_n + u] * r * (1 - r);
          const float dz_pre = d * (hpp[row * h_n + u] - n) * z * (1 - z);
          dx[u] = dr_pre;
          dx[h_n + u] = dz_pre;
          dx[2 * h_n + u] = dn_pre;
          dgh(b, u) = dr_pre;
          dgh(b, h_n + u) = dz_pre;
          dgh(b, 2 * h_n + u) = dn_pre * r;
          dh(b, u) = d * z;
        }
      }
      const StridedRows hp(hpp + t * h_n, b_n, h_n, Eigen::OuterStride<>(t_n * h_n));
      dw_m.noalias() += dgh.transpose() * hp;
      db_m += dgh.colwise().sum();
      dh.noalias() += dgh * w;
    }
    return {dgi, dw, db, dh0};
  }
};

}  // namespace

torch::Tensor gruRecurrence(const torch::Tensor& gi, const torch::Tensor& w_hh, const torch::Tensor& b_hh,
                            const torch::Tensor& h0) {
  if (gi.dim() != 3 || gi.size(2) % 3 != 0 || w_hh.size(0) != gi.size(2) || w_hh.size(1) * 3 != gi.size(2) ||
      b_hh.size(0) != gi.size(2) || h0.size(0) != gi.size(0) || h0.size(1) != w_hh.size(1))
    throw Error("gru recurrence: gi must be [B, T, 3H], w_hh [3H, H], b_hh [3H], h0 [B, H]");
  return GruRecurrenceFn::apply(gi, w_hh, b_hh, h0);
}

std::pair<torch::Tensor, torch::Tensor> gru(torch::nn::GRU& module, const torch::Tensor& x, const torch::Tensor& h0) {
  const auto& o = module->options;
  if (!o.batch_first() || o.bidirectional() || o.dropout() != 0 || !o.bias())
    throw Error("fused gru: only batch-first, unidirectional GRUs with biases and no dropout");
  const int64_t layers = o.num_layers(), hidden = o.hidden_size();
  if (x.dim() != 3 || x.size(1) < 1 || x.size(2) != o.input_size())
    throw Error("fused gru: x must be [B, T >= 1, " + std::to_string(o.input_size()) + "]");
  const int64_t b_n = x.size(0), t_n = x.size(1);
  if (h0.defined() && (h0.dim() != 3 || h0.size(0) != layers || h0.size(1) != b_n || h0.size(2) != hidden))
    throw Error("fused gru: h0 must be [layers, B, hidden]");
  const auto params = module->named_parameters(false);
  Tensor in = x;
  std::vector<Tensor> last;
  for (int64_t l = 0; l < layers; ++l) {
    const std::string k = "_l" + std::to_string(l);
    const Tensor gi = torch::linear(in, params["weight_ih" + k], params["bias_ih" + k]);
    const Tensor start = h0.defined() ? h0[l] : torch::zeros({b_n, hidden});
    in = gruRecurrence(gi, params["weight_hh" + k], params["bias_hh" + k], start);
    last.push_back(in.select(1, t_n - 1));
  }
  return {in, torch::stack(last)};
}

}  // namespace ddace::tgn::fused
