// The scene network's pointer-score kernel (fused_kernels.h).
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "ddace/common/error.h"
#include "fused_kernels.h"
#include "kernel_common.h"

namespace ddace::tgn::fused {

namespace {

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC push_options
#pragma GCC optimize("no-trapping-math")  // as in kernel_scene_attention.cpp
#endif

/// t = v * ReLU(u + b + r), u = a_i + z.
void pointerTerms(const float* __restrict u, const float* __restrict b, const float* __restrict r,
                  const float* __restrict v, float* __restrict t, int64_t n) {
  for (int64_t c = 0; c < n; ++c) {
    const float pre = u[c] + b[c] + r[c];
    t[c] = v[c] * (pre < 0.f ? 0.f : pre);  // std::max, which the optimize pragma keeps from inlining
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
    const int64_t p_n = a.size(0), m_n = a.size(1), n_n = b.size(1), k_n = a.size(2);
    Tensor out = torch::empty({p_n, m_n, n_n});
    const float *ap = a.data_ptr<float>(), *bp = b.data_ptr<float>(), *rp = r.data_ptr<float>(),
                *zp = z.data_ptr<float>(), *vp = v.data_ptr<float>();
    float* op = out.data_ptr<float>();
    std::vector<float> u(static_cast<size_t>(k_n)), terms(static_cast<size_t>(k_n));
    for (int64_t p = 0; p < p_n; ++p)
      for (int64_t i = 0; i < m_n; ++i) {
        const float* ai = ap + (p * m_n + i) * k_n;
        const float* zz = zp + p * k_n;
        for (int64_t c = 0; c < k_n; ++c) u[static_cast<size_t>(c)] = ai[c] + zz[c];
        for (int64_t j = 0; j < n_n; ++j) {
          pointerTerms(u.data(), bp + (p * n_n + j) * k_n, rp + ((p * m_n + i) * n_n + j) * k_n, vp, terms.data(), k_n);
          op[(p * m_n + i) * n_n + j] = sum8(terms.data(), k_n);
        }
      }
    save(ctx, {{"a", a}, {"b", b}, {"r", r}, {"z", z}, {"v", v}});
    return out;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    const Tensor a = saved(ctx, "a"), b = saved(ctx, "b"), r = saved(ctx, "r"), z = saved(ctx, "z"),
                 v = saved(ctx, "v");
    const Tensor dout = grads[0].contiguous();
    const int64_t p_n = a.size(0), m_n = a.size(1), n_n = b.size(1), k_n = a.size(2);
    Tensor da = torch::zeros_like(a), db = torch::zeros_like(b), dr = torch::empty_like(r), dz = torch::zeros_like(z),
           dv = torch::zeros_like(v);
    const float *ap = a.data_ptr<float>(), *bp = b.data_ptr<float>(), *rp = r.data_ptr<float>(),
                *zp = z.data_ptr<float>(), *vp = v.data_ptr<float>(), *go = dout.data_ptr<float>();
    float *dap = da.data_ptr<float>(), *dbp = db.data_ptr<float>(), *drp = dr.data_ptr<float>(),
          *dzp = dz.data_ptr<float>(), *dvp = dv.data_ptr<float>();
    std::vector<float> u(static_cast<size_t>(k_n)), du(static_cast<size_t>(k_n));
    for (int64_t p = 0; p < p_n; ++p)
      for (int64_t i = 0; i < m_n; ++i) {
        const float* ai = ap + (p * m_n + i) * k_n;
        const float* zz = zp + p * k_n;
        for (int64_t c = 0; c < k_n; ++c) u[static_cast<size_t>(c)] = ai[c] + zz[c];
        std::fill(du.begin(), du.end(), 0.f);
        for (int64_t j = 0; j < n_n; ++j)
          pointerPairBackward(u.data(), bp + (p * n_n + j) * k_n, rp + ((p * m_n + i) * n_n + j) * k_n, vp,
                              go[(p * m_n + i) * n_n + j], dvp, du.data(), dbp + (p * n_n + j) * k_n,
                              drp + ((p * m_n + i) * n_n + j) * k_n, k_n);
        // u = a_i + z: both get du.
        float* dai = dap + (p * m_n + i) * k_n;
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

torch::Tensor pointerScores(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& r,
                            const torch::Tensor& z, const torch::Tensor& v) {
  const bool ok = a.dim() == 3 && b.dim() == 3 && b.size(0) == a.size(0) && b.size(2) == a.size(2) && r.dim() == 4 &&
                  r.size(0) == a.size(0) && r.size(1) == a.size(1) && r.size(2) == b.size(1) &&
                  r.size(3) == a.size(2) && z.dim() == 2 && z.size(0) == a.size(0) && z.size(1) == a.size(2) &&
                  v.dim() == 1 && v.size(0) == a.size(2);
  if (!ok) throw Error("pointer scores: a must be [P, M, K], b [P, N, K], r [P, M, N, K], z [P, K] and v [K]");
  return PointerScoresFn::apply(a, b, r, z, v);
}

}  // namespace ddace::tgn::fused
