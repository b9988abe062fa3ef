#include "fused_kernels.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <initializer_list>
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

/// Keeps the tensors a backward pass reads, by name (saved() gets them back).
void save(AutogradContext* ctx, std::initializer_list<std::pair<const char*, Tensor>> tensors) {
  for (const auto& [name, t] : tensors) ctx->saved_data[name] = t;
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
    save(ctx, {{"h", h},
               {"att_src", att_src},
               {"att_dst", att_dst},
               {"alpha", alpha},
               {"a_src", a_src},
               {"a_dst", a_dst},
               {"offset", offset},
               {"source", source}});
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

// ------------------------------------------------------------------ scene attention
//
// The inner loops run over all H * C channels of a pair at once (contiguous, independent
// elements the compiler vectorises); per-head sums over C channels use 8 partial sums.

float leaky(float v) {
  return v > 0 ? v : kSlope * v;
}

/// sum_{c < n} x[c], in 8 partial sums (vectorisable; the order differs from a plain loop
/// only by float rounding).
float sum8(const float* __restrict x, int64_t n) {
  float part[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int64_t c = 0;
  for (; c + 8 <= n; c += 8)
    for (int l = 0; l < 8; ++l) part[l] += x[c + l];
  float s = 0;
  for (; c < n; ++c) s += x[c];
  return s + ((part[0] + part[4]) + (part[1] + part[5])) + ((part[2] + part[6]) + (part[3] + part[7]));
}

/// out[k * C + c] = per_head[k] for every head k and channel c.
void expand(const float* __restrict per_head, int64_t h_n, int64_t c_n, float* __restrict out) {
  for (int64_t k = 0; k < h_n; ++k) std::fill(out + k * c_n, out + (k + 1) * c_n, per_head[k]);
}

// GCC does not vectorise a select on a float comparison while it must keep the comparison's
// floating-point exception flags (-ftrapping-math); nothing here reads them, and the values
// are the same either way.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC push_options
#pragma GCC optimize("no-trapping-math")
#endif

/// m = s + e; t = att * LeakyReLU(d + m) (GATv2's logit terms).
void v2Terms(const float* __restrict d, const float* __restrict s, const float* __restrict e,
             const float* __restrict att, float* __restrict m, float* __restrict t, int64_t n) {
  for (int64_t c = 0; c < n; ++c) {
    m[c] = s[c] + e[c];
    const float pre = d[c] + m[c], neg = kSlope * pre;
    t[c] = att[c] * (pre > 0 ? pre : neg);
  }
}

/// The gradient through one GATv2 pair: dlogit (per channel: its head's), alpha (same),
/// g = dL/dout_i, m the message. LeakyReLU's derivative as torch's: the slope where the
/// input is not > 0.
void v2PairBackward(const float* __restrict d, const float* __restrict m, const float* __restrict att,
                    const float* __restrict dlogit, const float* __restrict alpha, const float* __restrict g,
                    float* __restrict datt, float* __restrict dd, float* __restrict ds, float* __restrict de,
                    int64_t n) {
  for (int64_t c = 0; c < n; ++c) {
    const float pre = d[c] + m[c], neg = kSlope * pre;
    const bool pos = pre > 0;
    datt[c] += dlogit[c] * (pos ? pre : neg);
    const float dpre = dlogit[c] * att[c] * (pos ? 1.f : kSlope);
    dd[c] += dpre;
    const float dm = alpha[c] * g[c] + dpre;
    ds[c] += dm;
    de[c] = dm;
  }
}

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC pop_options
#endif

/// The same for GATConv: dpre per channel is its head's gradient of the logit's LeakyReLU input.
void gatPairBackward(const float* __restrict d, const float* __restrict s, const float* __restrict e,
                     const float* __restrict att, const float* __restrict dpre, const float* __restrict alpha,
                     const float* __restrict g, float* __restrict datt, float* __restrict dd, float* __restrict ds,
                     float* __restrict de, int64_t n) {
  const float *ad = att, *as = att + n, *ae = att + 2 * n;
  float *dad = datt, *das = datt + n, *dae = datt + 2 * n;
  for (int64_t c = 0; c < n; ++c) {
    dd[c] += dpre[c] * ad[c];
    dad[c] += dpre[c] * d[c];
    das[c] += dpre[c] * s[c];
    dae[c] += dpre[c] * e[c];
    const float dm = alpha[c] * g[c];
    ds[c] += dm + dpre[c] * as[c];
    de[c] = dm + dpre[c] * ae[c];
  }
}

/// GATConv's logit input of head k: <att_dst, d> + <att_src, s> + <att_edge, e> over its C channels.
float gatPre(const float* d, const float* s, const float* e, const float* att, int64_t hc, int64_t k, int64_t c_n) {
  const int64_t at = k * c_n;
  return dot(att + at, d + at, c_n) + dot(att + hc + at, s + at, c_n) + dot(att + 2 * hc + at, e + at, c_n);
}

// att [A, H, C]: A = 1 is GATv2's att, A = 3 GATConv's att_dst, att_src, att_edge.
struct SceneAttentionFn : torch::autograd::Function<SceneAttentionFn> {
  static Tensor forward(AutogradContext* ctx, Tensor hs, Tensor hd, Tensor he, Tensor att, Tensor bias, Tensor offset,
                        Tensor source) {
    hs = hs.contiguous();
    hd = hd.contiguous();
    he = he.contiguous();
    att = att.contiguous();
    bias = bias.contiguous();
    const int64_t s_n = hs.size(0), n_n = hs.size(1), h_n = hs.size(2), c_n = hs.size(3), e_n = source.size(0);
    const int64_t hc = h_n * c_n;
    const bool v2 = att.size(0) == 1;
    Tensor out = torch::empty({s_n, n_n, hc});
    Tensor alpha = torch::empty({s_n, e_n, h_n});
    const float *hsp = hs.data_ptr<float>(), *hdp = hd.data_ptr<float>(), *hep = he.data_ptr<float>(),
                *ap = att.data_ptr<float>(), *bp = bias.data_ptr<float>();
    float* op = out.data_ptr<float>();
    float* al = alpha.data_ptr<float>();
    const int64_t* off = offset.data_ptr<int64_t>();
    const int64_t* src = source.data_ptr<int64_t>();
    std::vector<float> m(static_cast<size_t>(n_n * hc)), terms(static_cast<size_t>(hc)), ac(static_cast<size_t>(hc)),
        logit(static_cast<size_t>(n_n * h_n)), top(static_cast<size_t>(h_n)), sum(static_cast<size_t>(h_n));
    for (int64_t s = 0; s < s_n; ++s)
      for (int64_t i = 0; i < n_n; ++i) {
        const float* di = hdp + (s * n_n + i) * hc;
        const int64_t first = off[i], deg = off[i + 1] - first;
        std::fill(top.begin(), top.end(), -std::numeric_limits<float>::infinity());
        for (int64_t q = 0; q < deg; ++q) {
          const int64_t j = src[first + q];
          const float* sj = hsp + (s * n_n + j) * hc;
          const float* eij = hep + ((s * n_n + i) * n_n + j) * hc;
          float* mq = m.data() + q * hc;
          float* lq = logit.data() + q * h_n;
          if (v2) {
            v2Terms(di, sj, eij, ap, mq, terms.data(), hc);
            for (int64_t k = 0; k < h_n; ++k) lq[k] = sum8(terms.data() + k * c_n, c_n);
          } else {
            for (int64_t c = 0; c < hc; ++c) mq[c] = sj[c] + eij[c];
            for (int64_t k = 0; k < h_n; ++k) lq[k] = leaky(gatPre(di, sj, eij, ap, hc, k, c_n));
          }
          for (int64_t k = 0; k < h_n; ++k) top[k] = std::max(top[k], lq[k]);
        }
        // Softmax over i's incoming edges, per head.
        std::fill(sum.begin(), sum.end(), 0.f);
        for (int64_t q = 0; q < deg; ++q)
          for (int64_t k = 0; k < h_n; ++k) {
            float& v = logit[static_cast<size_t>(q * h_n + k)];
            v = std::exp(v - top[k]);
            sum[k] += v;
          }
        float* oi = op + (s * n_n + i) * hc;
        std::fill(oi, oi + hc, 0.f);
        for (int64_t q = 0; q < deg; ++q) {
          float* aq = al + (s * e_n + first + q) * h_n;
          for (int64_t k = 0; k < h_n; ++k) aq[k] = logit[static_cast<size_t>(q * h_n + k)] / sum[k];
          expand(aq, h_n, c_n, ac.data());
          const float* mq = m.data() + q * hc;
          for (int64_t c = 0; c < hc; ++c) oi[c] += ac[c] * mq[c];
        }
        for (int64_t c = 0; c < hc; ++c) oi[c] += bp[c];
      }
    save(ctx,
         {{"hs", hs}, {"hd", hd}, {"he", he}, {"att", att}, {"alpha", alpha}, {"offset", offset}, {"source", source}});
    return out;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    const Tensor hs = saved(ctx, "hs"), hd = saved(ctx, "hd"), he = saved(ctx, "he"), att = saved(ctx, "att");
    const Tensor alpha = saved(ctx, "alpha"), offset = saved(ctx, "offset"), source = saved(ctx, "source");
    const Tensor dout = grads[0].contiguous();
    const int64_t s_n = hs.size(0), n_n = hs.size(1), h_n = hs.size(2), c_n = hs.size(3), e_n = source.size(0);
    const bool v2 = att.size(0) == 1;
    const int64_t hc = h_n * c_n;
    // he's gradient is written at every edge; only pairs that are not edges need zeros.
    Tensor dhs = torch::zeros_like(hs), dhd = torch::zeros_like(hd),
           dhe = e_n == n_n * n_n ? torch::empty_like(he) : torch::zeros_like(he), datt = torch::zeros_like(att),
           dbias = torch::zeros({hc});
    const float *hsp = hs.data_ptr<float>(), *hdp = hd.data_ptr<float>(), *hep = he.data_ptr<float>(),
                *ap = att.data_ptr<float>(), *al = alpha.data_ptr<float>(), *go = dout.data_ptr<float>();
    float *dhsp = dhs.data_ptr<float>(), *dhdp = dhd.data_ptr<float>(), *dhep = dhe.data_ptr<float>(),
          *dap = datt.data_ptr<float>(), *dbp = dbias.data_ptr<float>();
    const int64_t* off = offset.data_ptr<int64_t>();
    const int64_t* src = source.data_ptr<int64_t>();
    std::vector<float> m(static_cast<size_t>(n_n * hc)), terms(static_cast<size_t>(hc)),
        d_alpha(static_cast<size_t>(n_n * h_n)), weighted(static_cast<size_t>(h_n)), dl(static_cast<size_t>(h_n)),
        dlc(static_cast<size_t>(hc)), ac(static_cast<size_t>(hc));
    for (int64_t s = 0; s < s_n; ++s)
      for (int64_t i = 0; i < n_n; ++i) {
        const float* g = go + (s * n_n + i) * hc;
        const float* di = hdp + (s * n_n + i) * hc;
        float* ddi = dhdp + (s * n_n + i) * hc;
        const int64_t first = off[i], deg = off[i + 1] - first;
        for (int64_t c = 0; c < hc; ++c) dbp[c] += g[c];
        // out_i = sum_q alpha_q m_q: the gradient to alpha, then through the softmax.
        std::fill(weighted.begin(), weighted.end(), 0.f);
        for (int64_t q = 0; q < deg; ++q) {
          const int64_t j = src[first + q];
          const float* sj = hsp + (s * n_n + j) * hc;
          const float* eij = hep + ((s * n_n + i) * n_n + j) * hc;
          float* mq = m.data() + q * hc;
          for (int64_t c = 0; c < hc; ++c) {
            mq[c] = sj[c] + eij[c];
            terms[c] = g[c] * mq[c];
          }
          const float* aq = al + (s * e_n + first + q) * h_n;
          for (int64_t k = 0; k < h_n; ++k) {
            const float d = sum8(terms.data() + k * c_n, c_n);
            d_alpha[static_cast<size_t>(q * h_n + k)] = d;
            weighted[static_cast<size_t>(k)] += aq[k] * d;
          }
        }
        for (int64_t q = 0; q < deg; ++q) {
          const int64_t j = src[first + q];
          const float* aq = al + (s * e_n + first + q) * h_n;
          for (int64_t k = 0; k < h_n; ++k)
            dl[static_cast<size_t>(k)] = aq[k] * (d_alpha[static_cast<size_t>(q * h_n + k)] - weighted[k]);
          expand(aq, h_n, c_n, ac.data());
          const float* mq = m.data() + q * hc;
          float* dsj = dhsp + (s * n_n + j) * hc;
          float* deij = dhep + ((s * n_n + i) * n_n + j) * hc;
          if (v2) {
            expand(dl.data(), h_n, c_n, dlc.data());
            v2PairBackward(di, mq, ap, dlc.data(), ac.data(), g, dap, ddi, dsj, deij, hc);
          } else {
            const float* sj = hsp + (s * n_n + j) * hc;
            const float* eij = hep + ((s * n_n + i) * n_n + j) * hc;
            for (int64_t k = 0; k < h_n; ++k)
              if (!(gatPre(di, sj, eij, ap, hc, k, c_n) > 0)) dl[static_cast<size_t>(k)] *= kSlope;
            expand(dl.data(), h_n, c_n, dlc.data());
            gatPairBackward(di, sj, eij, ap, dlc.data(), ac.data(), g, dap, ddi, dsj, deij, hc);
          }
        }
      }
    return {dhs, dhd, dhe, datt, dbias, Tensor(), Tensor()};
  }
};

// ------------------------------------------------------------------ pointer scores

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC push_options
#pragma GCC optimize("no-trapping-math")  // as for the scene attention above
#endif

/// t = v * ReLU(u + b + r), u = a_i + z.
void pointerTerms(const float* __restrict u, const float* __restrict b, const float* __restrict r,
                  const float* __restrict v, float* __restrict t, int64_t n) {
  for (int64_t c = 0; c < n; ++c) {
    const float pre = u[c] + b[c] + r[c];
    t[c] = v[c] * std::max(pre, 0.f);
  }
}

/// ReLU's derivative as torch's: 0 where the output is not > 0.
void pointerPairBackward(const float* __restrict u, const float* __restrict b, const float* __restrict r,
                         const float* __restrict v, float g, float* __restrict dv, float* __restrict du,
                         float* __restrict db, float* __restrict dr, int64_t n) {
  for (int64_t c = 0; c < n; ++c) {
    const float pre = u[c] + b[c] + r[c], dpre_pos = g * v[c], dv_pos = g * pre;
    const bool pos = pre > 0;
    const float dpre = pos ? dpre_pos : 0.f;
    dv[c] += pos ? dv_pos : 0.f;
    dr[c] = dpre;
    du[c] += dpre;
    db[c] += dpre;
  }
}

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC pop_options
#endif

struct PointerScoresFn : torch::autograd::Function<PointerScoresFn> {
  static Tensor forward(AutogradContext* ctx, Tensor a, Tensor b, Tensor r, Tensor z, Tensor v) {
    a = a.contiguous();
    b = b.contiguous();
    r = r.contiguous();
    z = z.contiguous();
    v = v.contiguous();
    const int64_t p_n = a.size(0), n_n = a.size(1), k_n = a.size(2);
    Tensor out = torch::empty({p_n, n_n, n_n});
    const float *ap = a.data_ptr<float>(), *bp = b.data_ptr<float>(), *rp = r.data_ptr<float>(),
                *zp = z.data_ptr<float>(), *vp = v.data_ptr<float>();
    float* op = out.data_ptr<float>();
    std::vector<float> u(static_cast<size_t>(k_n)), terms(static_cast<size_t>(k_n));
    for (int64_t p = 0; p < p_n; ++p)
      for (int64_t i = 0; i < n_n; ++i) {
        const float* ai = ap + (p * n_n + i) * k_n;
        const float* zz = zp + p * k_n;
        for (int64_t c = 0; c < k_n; ++c) u[static_cast<size_t>(c)] = ai[c] + zz[c];
        for (int64_t j = 0; j < n_n; ++j) {
          pointerTerms(u.data(), bp + (p * n_n + j) * k_n, rp + ((p * n_n + i) * n_n + j) * k_n, vp, terms.data(), k_n);
          op[(p * n_n + i) * n_n + j] = sum8(terms.data(), k_n);
        }
      }
    save(ctx, {{"a", a}, {"b", b}, {"r", r}, {"z", z}, {"v", v}});
    return out;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    const Tensor a = saved(ctx, "a"), b = saved(ctx, "b"), r = saved(ctx, "r"), z = saved(ctx, "z"),
                 v = saved(ctx, "v");
    const Tensor dout = grads[0].contiguous();
    const int64_t p_n = a.size(0), n_n = a.size(1), k_n = a.size(2);
    Tensor da = torch::zeros_like(a), db = torch::zeros_like(b), dr = torch::empty_like(r), dz = torch::zeros_like(z),
           dv = torch::zeros_like(v);
    const float *ap = a.data_ptr<float>(), *bp = b.data_ptr<float>(), *rp = r.data_ptr<float>(),
                *zp = z.data_ptr<float>(), *vp = v.data_ptr<float>(), *go = dout.data_ptr<float>();
    float *dap = da.data_ptr<float>(), *dbp = db.data_ptr<float>(), *drp = dr.data_ptr<float>(),
          *dzp = dz.data_ptr<float>(), *dvp = dv.data_ptr<float>();
    std::vector<float> u(static_cast<size_t>(k_n)), du(static_cast<size_t>(k_n));
    for (int64_t p = 0; p < p_n; ++p)
      for (int64_t i = 0; i < n_n; ++i) {
        const float* ai = ap + (p * n_n + i) * k_n;
        const float* zz = zp + p * k_n;
        for (int64_t c = 0; c < k_n; ++c) u[static_cast<size_t>(c)] = ai[c] + zz[c];
        std::fill(du.begin(), du.end(), 0.f);
        for (int64_t j = 0; j < n_n; ++j)
          pointerPairBackward(u.data(), bp + (p * n_n + j) * k_n, rp + ((p * n_n + i) * n_n + j) * k_n, vp,
                              go[(p * n_n + i) * n_n + j], dvp, du.data(), dbp + (p * n_n + j) * k_n,
                              drp + ((p * n_n + i) * n_n + j) * k_n, k_n);
        // u = a_i + z: both get du.
        float* dai = dap + (p * n_n + i) * k_n;
        float* dzz = dzp + p * k_n;
        for (int64_t c = 0; c < k_n; ++c) {
          dai[c] += du[static_cast<size_t>(c)];
          dzz[c] += du[static_cast<size_t>(c)];
        }
      }
    return {da, db, dr, dz, dv};
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

namespace {

void checkScene(const Tensor& hs, const Tensor& hd, const Tensor& he, const Tensor& att, const Tensor& bias,
                const InEdges& edges) {
  const bool ok = hs.dim() == 4 && hd.sizes() == hs.sizes() && he.dim() == 5 && he.size(0) == hs.size(0) &&
                  he.size(1) == hs.size(1) && he.size(2) == hs.size(1) && he.size(3) == hs.size(2) &&
                  he.size(4) == hs.size(3) && att.size(-2) == hs.size(2) && att.size(-1) == hs.size(3) &&
                  bias.dim() == 1 && bias.size(0) == hs.size(2) * hs.size(3) && edges.offset.size(0) == hs.size(1) + 1;
  if (!ok)
    throw Error(
        "scene attention: hs and hd must be [S, N, H, C], he [S, N, N, H, C], att [H, C], bias [H * C] and the "
        "edges N + 1 offsets");
}

}  // namespace

torch::Tensor sceneAttentionV2(const torch::Tensor& hs, const torch::Tensor& hd, const torch::Tensor& he,
                               const torch::Tensor& att, const torch::Tensor& bias, const InEdges& edges) {
  checkScene(hs, hd, he, att, bias, edges);
  if (att.dim() != 2) throw Error("scene attention: att must be [H, C]");
  return SceneAttentionFn::apply(hs, hd, he, att.unsqueeze(0), bias, edges.offset, edges.source);
}

torch::Tensor sceneAttentionGat(const torch::Tensor& hs, const torch::Tensor& hd, const torch::Tensor& he,
                                const torch::Tensor& att_dst, const torch::Tensor& att_src,
                                const torch::Tensor& att_edge, const torch::Tensor& bias, const InEdges& edges) {
  checkScene(hs, hd, he, att_dst, bias, edges);
  if (att_dst.dim() != 2 || att_src.sizes() != att_dst.sizes() || att_edge.sizes() != att_dst.sizes())
    throw Error("scene attention: att_dst, att_src and att_edge must be [H, C]");
  return SceneAttentionFn::apply(hs, hd, he, torch::stack({att_dst, att_src, att_edge}), bias, edges.offset,
                                 edges.source);
}

torch::Tensor pointerScores(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& r,
                            const torch::Tensor& z, const torch::Tensor& v) {
  const bool ok = a.dim() == 3 && b.sizes() == a.sizes() && r.dim() == 4 && r.size(0) == a.size(0) &&
                  r.size(1) == a.size(1) && r.size(2) == a.size(1) && r.size(3) == a.size(2) && z.dim() == 2 &&
                  z.size(0) == a.size(0) && z.size(1) == a.size(2) && v.dim() == 1 && v.size(0) == a.size(2);
  if (!ok) throw Error("pointer scores: a and b must be [P, N, K], r [P, N, N, K], z [P, K] and v [K]");
  return PointerScoresFn::apply(a, b, r, z, v);
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
