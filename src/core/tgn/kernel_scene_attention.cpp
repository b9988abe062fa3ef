// The scene network's attention kernel (GATv2 with edge features) (fused_kernels.h).
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "ddace/common/error.h"
#include "fused_kernels.h"
#include "kernel_common.h"

namespace ddace::tgn::fused {

namespace {

// ------------------------------------------------------------------ scene attention
//
// The inner loops run over all H * C channels of a pair at once (contiguous, independent
// elements the compiler vectorises); per-head sums over C channels use 8 partial sums.

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

// att [H, C]: GATv2's att.
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
          v2Terms(di, sj, eij, ap, mq, terms.data(), hc);
          for (int64_t k = 0; k < h_n; ++k) lq[k] = sum8(terms.data() + k * c_n, c_n);
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
          expand(dl.data(), h_n, c_n, dlc.data());
          v2PairBackward(di, mq, ap, dlc.data(), ac.data(), g, dap, ddi, dsj, deij, hc);
        }
      }
    return {dhs, dhd, dhe, datt, dbias, Tensor(), Tensor()};
  }
};

}  // namespace

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
  return SceneAttentionFn::apply(hs, hd, he, att, bias, edges.offset, edges.source);
}

}  // namespace ddace::tgn::fused
