// FlatParameters: every parameter a view of one buffer, Adam in a few ops (fused_kernels.h).
#include <cmath>

#include "fused_kernels.h"

namespace ddace::tgn::fused {

using torch::Tensor;

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
