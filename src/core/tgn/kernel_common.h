// Helpers the fused kernels share (internal to the tgn module; fused_kernels.h is their
// interface). One kernel per file: kernel_gat_attention.cpp, kernel_scene_attention.cpp,
// kernel_pointer_scores.cpp, kernel_gru.cpp; flat_parameters.cpp holds the optimiser's buffers.
#pragma once

#include <torch/torch.h>

#include <Eigen/Core>
#include <initializer_list>
#include <utility>

namespace ddace::tgn::fused {

using torch::Tensor;
using torch::autograd::AutogradContext;
using torch::autograd::variable_list;
using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using RowVector = Eigen::Matrix<float, 1, Eigen::Dynamic>;
using StridedRows = Eigen::Map<const RowMatrix, 0, Eigen::OuterStride<>>;

constexpr float kSlope = 0.2f;  // GATConv's LeakyReLU negative slope

inline float dot(const float* a, const float* b, int64_t n) {
  float s = 0;
  for (int64_t c = 0; c < n; ++c) s += a[c] * b[c];
  return s;
}

inline void axpy(float alpha, const float* x, float* y, int64_t n) {
  for (int64_t c = 0; c < n; ++c) y[c] += alpha * x[c];
}

inline Tensor saved(AutogradContext* ctx, const char* name) {
  return ctx->saved_data.at(name).toTensor();
}

/// Keeps the tensors a backward pass reads, by name (saved() gets them back).
inline void save(AutogradContext* ctx, std::initializer_list<std::pair<const char*, Tensor>> tensors) {
  for (const auto& [name, t] : tensors) ctx->saved_data[name] = t;
}

/// sum_{c < n} x[c], in 8 partial sums (vectorisable; the order differs from a plain loop
/// only by float rounding).
inline float sum8(const float* __restrict x, int64_t n) {
  float part[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int64_t c = 0;
  for (; c + 8 <= n; c += 8)
    for (int l = 0; l < 8; ++l) part[l] += x[c + l];
  float s = 0;
  for (; c < n; ++c) s += x[c];
  return s + ((part[0] + part[4]) + (part[1] + part[5])) + ((part[2] + part[6]) + (part[3] + part[7]));
}

}  // namespace ddace::tgn::fused
