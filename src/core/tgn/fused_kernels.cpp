#include "fused_kernels.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "ddace/common/error.h"

namespace ddace::tgn::fused {

namespace {

using torch::Tensor;
using torch::autograd::AutogradContext;
using torch::autograd::variable_list;
using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using RowVector = Eigen::Matrix<float, 1, Eigen::Dynamic>;
using StridedRows = Eigen::Map<const RowMatrix, 0, Eigen::OuterStride<>>;

constexpr float kSlope = 0.2f;  // GATConv's LeakyReLU negative slope

float dot(const float* a, const float* b, int64_t n) {
  float s = 0;
  for (int64_t c = 0; c < n; ++c) s += a[c] * b[c];
  return s;
}

void axpy(float alpha, const float* x, float* y, int64_t n) {
  for (int64_t c = 0; c < n; ++c) y[c] += alpha * x[c];
}

Tensor saved(AutogradContext* ctx, const char* name) {
  return ctx->saved_data.at(name).toTensor();
}

// ------------------------------------------------------------------ GAT attention

struct GatAttentionFn : torch::autograd::Function<GatAttentionFn> {
  static Tensor forward(AutogradContext* ctx, Tensor h, Tensor att_src, Tensor att_dst, Tensor offset, Tensor source) {
    h = h.contiguous();
    att_src = att_src.contiguous();
    att_dst = att_dst.contiguous();
    const int64_t s_n = h.size(0), n_n = h.size(1), h_n = h.size(2), c_n = h.size(3), e_n = source.size(0);
    Tensor out = torch::zeros_like(h);
    Tensor alpha = torch::empty({s_n, e_n, h_n});
    Tensor a_src = torch::empty({s_n, n_n, h_n}), a_dst = torch::empty({s_n, n_n, h_n});
    const float* hp = h.data_ptr<float>();
    const float* ws = att_src.data_ptr<float>();
    const float* wd = att_dst.data_ptr<float>();
    float* op = out.data_ptr<float>();
    float* al = alpha.data_ptr<float>();
    float* as = a_src.data_ptr<float>();
    float* ad = a_dst.data_ptr<float>();
    const int64_t* off = offset.data_ptr<int64_t>();
    const int64_t* src = source.data_ptr<int64_t>();
    for (int64_t r = 0; r < s_n * n_n; ++r)
      for (int64_t k = 0; k < h_n; ++k) {
        as[r * h_n + k] = dot(hp + (r * h_n + k) * c_n, ws + k * c_n, c_n);
        ad[r * h_n + k] = dot(hp + (r * h_n + k) * c_n, wd + k * c_n, c_n);
      }
    for (int64_t s = 0; s < s_n; ++s)
      for (int64_t i = 0; i < n_n; ++i)
        for (int64_t k = 0; k < h_n; ++k) {
          const float di = ad[(s * n_n + i) * h_n + k];
          float top = -std::numeric_limits<float>::infinity();
          for (int64_t e = off[i]; e < off[i + 1]; ++e) {
            const float pre = di + as[(s * n_n + src[e]) * h_n + k];
            const float v = pre > 0 ? pre : kSlope * pre;
            al[(s * e_n + e) * h_n + k] = v;
            top = std::max(top, v);
          }
          float sum = 0;
          for (int64_t e = off[i]; e < off[i + 1]; ++e) {
            float& v = al[(s * e_n + e) * h_n + k];
            v = std::exp(v - top);
            sum += v;
          }
          float* oi = op + ((s * n_n + i) * h_n + k) * c_n;
          for (int64_t e = off[i]; e < off[i + 1]; ++e) {
            float& v = al[(s * e_n + e) * h_n + k];
            v /= sum;
            axpy(v, hp + ((s * n_n + src[e]) * h_n + k) * c_n, oi, c_n);
          }
        }
    for (const auto& [name, t] : {std::pair<const char*, Tensor>{"h", h},
                                  {"att_src", att_src},
                                  {"att_dst", att_dst},
                                  {"alpha", alpha},
                                  {"a_src", a_src},
                                  {"a_dst", a_dst},
                                  {"offset", offset},
                                  {"source", source}})
      ctx->saved_data[name] = t;
    return out;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    const Tensor h = saved(ctx, "h"), att_src = saved(ctx, "att_src"), att_dst = saved(ctx, "att_dst");
    const Tensor alpha = saved(ctx, "alpha"), a_src = saved(ctx, "a_src"), a_dst = saved(ctx, "a_dst");
    const Tensor offset = saved(ctx, "offset"), source = saved(ctx, "source");
    const Tensor dout = grads[0].contiguous();
    const int64_t s_n = h.size(0), n_n = h.size(1), h_n = h.size(2), c_n = h.size(3), e_n = source.size(0);
    Tensor dh = torch::zeros_like(h), dws = torch::zeros_like(att_src), dwd = torch::zeros_like(att_dst);
    const float* hp = h.data_ptr<float>();
    const float* ws = att_src.data_ptr<float>();
    const float* wd = att_dst.data_ptr<float>();
    const float* go = dout.data_ptr<float>();
    const float* al = alpha.data_ptr<float>();
    const float* as = a_src.data_ptr<float>();
    const float* ad = a_dst.data_ptr<float>();
    const int64_t* off = offset.data_ptr<int64_t>();
    const int64_t* src = source.data_ptr<int64_t>();
    float* dhp = dh.data_ptr<float>();
    float* dwsp = dws.data_ptr<float>();
    float* dwdp = dwd.data_ptr<float>();
    std::vector<float> d_as(static_cast<size_t>(n_n)), d_ad(static_cast<size_t>(n_n)),
        d_alpha(static_cast<size_t>(e_n));
    for (int64_t s = 0; s < s_n; ++s)
      for (int64_t k = 0; k < h_n; ++k) {
        std::fill(d_as.begin(), d_as.end(), 0.f);
        std::fill(d_ad.begin(), d_ad.end(), 0.f);
        for (int64_t i = 0; i < n_n; ++i) {
          const float* gi = go + ((s * n_n + i) * h_n + k) * c_n;
          // out_i = sum_e alpha_e h_src(e): gradients to alpha and to the sources' h.
          float weighted = 0;
          for (int64_t e = off[i]; e < off[i + 1]; ++e) {
            const int64_t j = src[e];
            const float a = al[(s * e_n + e) * h_n + k];
            d_alpha[static_cast<size_t>(e)] = dot(gi, hp + ((s * n_n + j) * h_n + k) * c_n, c_n);
            weighted += a * d_alpha[static_cast<size_t>(e)];
            axpy(a, gi, dhp + ((s * n_n + j) * h_n + k) * c_n, c_n);
          }
          // Softmax, then LeakyReLU (derivative as torch's: slope where the input is not > 0).
          const float di = ad[(s * n_n + i) * h_n + k];
          for (int64_t e = off[i]; e < off[i + 1]; ++e) {
            const int64_t j = src[e];
            const float de = al[(s * e_n + e) * h_n + k] * (d_alpha[static_cast<size_t>(e)] - weighted);
            const float pre = di + as[(s * n_n + j) * h_n + k];
            const float dpre = pre > 0 ? de : kSlope * de;
            d_ad[static_cast<size_t>(i)] += dpre;
            d_as[static_cast<size_t>(j)] += dpre;
          }
        }
        // a_src_j = <att_src, h_j>, a_dst_i = <att_dst, h_i>.
        for (int64_t n = 0; n < n_n; ++n) {
          const float* hn = hp + ((s * n_n + n) * h_n + k) * c_n;
          float* dhn = dhp + ((s * n_n + n) * h_n + k) * c_n;
          const float gs = d_as[static_cast<size_t>(n)], gd = d_ad[static_cast<size_t>(n)];
          axpy(gs, ws + k * c_n, dhn, c_n);
          axpy(gd, wd + k * c_n, dhn, c_n);
          axpy(gs, hn, dwsp + k * c_n, c_n);
          axpy(gd, hn, dwdp + k * c_n, c_n);
        }
      }
    return {dh, dws, dwd, Tensor(), Tensor()};
  }
};

// ------------------------------------------------------------------ GRU recurrence

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
    for (const auto& [name, t] :
         {std::pair<const char*, Tensor>{"w_hh", w_hh}, {"h_prev", h_prev}, {"gates", gates}, {"gh_n", gh_n}})
      ctx->saved_data[name] = t;
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

InEdges inEdgesFromMask(const torch::Tensor& mask) {
  if (mask.dim() != 2 || mask.size(0) != mask.size(1)) throw Error("gat attention: the mask must be square");
  const Tensor m = mask.to(torch::kBool).contiguous();
  const int64_t n = m.size(0);
  auto a = m.accessor<bool, 2>();
  std::vector<int64_t> offset{0}, source;
  for (int64_t i = 0; i < n; ++i) {
    for (int64_t j = 0; j < n; ++j)
      if (a[i][j]) source.push_back(j);
    if (static_cast<int64_t>(source.size()) == offset.back())
      throw Error("gat attention: node " + std::to_string(i) + " receives from no node (not even itself)");
    offset.push_back(static_cast<int64_t>(source.size()));
  }
  return {torch::tensor(offset, torch::kLong), torch::tensor(source, torch::kLong)};
}

torch::Tensor gatAttention(const torch::Tensor& h, const torch::Tensor& att_src, const torch::Tensor& att_dst,
                           const InEdges& edges) {
  if (h.dim() != 4 || att_src.sizes() != att_dst.sizes() || att_src.size(0) != h.size(2) ||
      att_src.size(1) != h.size(3) || edges.offset.size(0) != h.size(1) + 1)
    throw Error("gat attention: h must be [S, N, H, C] with att [H, C] and N + 1 edge offsets");
  return GatAttentionFn::apply(h, att_src, att_dst, edges.offset, edges.source);
}

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

// ------------------------------------------------------------------ flat parameters

FlatParameters::FlatParameters(std::vector<torch::Tensor> parameters) : parameters_(std::move(parameters)) {
  torch::NoGradGuard no_grad;
  int64_t total = 0;
  for (const auto& p : parameters_) total += p.numel();
  data_ = torch::empty({total});
  grad_ = torch::zeros({total});
  int64_t at = 0;
  for (auto& p : parameters_) {
    const int64_t n = p.numel();
    data_.narrow(0, at, n).copy_(p.reshape({-1}));
    p.set_data(data_.narrow(0, at, n).view(p.sizes()));
    // Autograd accumulates into an existing gradient in place, so these stay views.
    p.mutable_grad() = grad_.narrow(0, at, n).view(p.sizes());
    at += n;
  }
  exp_avg_ = torch::zeros_like(data_);
  exp_avg_sq_ = torch::zeros_like(data_);
}

FlatParameters::~FlatParameters() {
  torch::NoGradGuard no_grad;
  for (auto& p : parameters_) {
    p.set_data(p.detach().clone());
    p.mutable_grad() = Tensor();
  }
}

double FlatParameters::clipGradNorm(double max_norm) {
  const double norm = grad_.norm().item<double>();
  const double coef = max_norm / (norm + 1e-6);
  if (coef < 1) grad_.mul_(coef);
  return norm;
}

void FlatParameters::adamStep(double learning_rate, double weight_decay) {
  constexpr double kBeta1 = 0.9, kBeta2 = 0.999, kEps = 1e-8;
  torch::NoGradGuard no_grad;
  ++step_;
  if (weight_decay != 0) grad_.add_(data_, weight_decay);
  exp_avg_.mul_(kBeta1).add_(grad_, 1 - kBeta1);
  exp_avg_sq_.mul_(kBeta2).addcmul_(grad_, grad_, 1 - kBeta2);
  const double bias1 = 1 - std::pow(kBeta1, static_cast<double>(step_));
  const double bias2 = 1 - std::pow(kBeta2, static_cast<double>(step_));
  const Tensor denom = (exp_avg_sq_.sqrt() / std::sqrt(bias2)).add_(kEps);
  data_.addcdiv_(exp_avg_, denom, -learning_rate / bias1);
}

}  // namespace ddace::tgn::fused
