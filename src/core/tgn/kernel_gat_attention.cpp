// The paper network's GAT attention kernel (fused_kernels.h).
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "ddace/common/error.h"
#include "fused_kernels.h"
#include "kernel_common.h"

namespace ddace::tgn::fused {

namespace {

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

}  // namespace ddace::tgn::fused
