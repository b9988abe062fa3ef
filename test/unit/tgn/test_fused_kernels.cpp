// The fused kernels (src/core/tgn/fused_kernels.h) against autograd of the op-by-op
// PyTorch formulation: values and every gradient, and Adam on the flat buffer against
// torch::optim::Adam.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <limits>

#include "ddace/common/error.h"
#include "fused_kernels.h"

using namespace ddace::tgn;
using torch::Tensor;

namespace {

/// GATConv attention + aggregation written op by op (as PyTorch Geometric does).
Tensor gatReference(const Tensor& h, const Tensor& att_src, const Tensor& att_dst, const Tensor& mask) {
  const int64_t n = h.size(1);
  const Tensor a_src = (h * att_src).sum(-1);  // [S, N, H]
  const Tensor a_dst = (h * att_dst).sum(-1);
  Tensor e = torch::leaky_relu(a_dst.unsqueeze(2) + a_src.unsqueeze(1), 0.2);  // [S, i, j, H]
  e = e.masked_fill(mask.logical_not().view({1, n, n, 1}), -std::numeric_limits<float>::infinity());
  const Tensor alpha = torch::softmax(e, 2);
  return torch::einsum("sijh,sjhc->sihc", {alpha, h});
}

void expectClose(const Tensor& a, const Tensor& b, double tol, const std::string& what) {
  ASSERT_TRUE(a.defined() && b.defined()) << what;
  ASSERT_EQ(a.sizes(), b.sizes()) << what;
  EXPECT_LT((a - b).abs().max().item<double>(), tol) << what;
}

Tensor leaf(std::vector<int64_t> shape) {
  return torch::randn(shape).requires_grad_(true);
}

void checkGat(const Tensor& mask) {
  const Tensor h = leaf({3, mask.size(0), 2, 4}), ws = leaf({2, 4}), wd = leaf({2, 4});
  const Tensor weights = torch::randn({3, mask.size(0), 2, 4});  // a loss that weighs every output
  const Tensor fused_out = fused::gatAttention(h, ws, wd, fused::inEdgesFromMask(mask));
  (fused_out * weights).sum().backward();
  const Tensor gh = h.grad().clone(), gs = ws.grad().clone(), gd = wd.grad().clone();
  h.mutable_grad().zero_();
  ws.mutable_grad().zero_();
  wd.mutable_grad().zero_();
  const Tensor ref = gatReference(h, ws, wd, mask);
  (ref * weights).sum().backward();
  expectClose(fused_out, ref, 1e-5, "output");
  expectClose(gh, h.grad(), 1e-4, "d/dh");
  expectClose(gs, ws.grad(), 1e-4, "d/datt_src");
  expectClose(gd, wd.grad(), 1e-4, "d/datt_dst");
}

}  // namespace

TEST(FusedKernels, GatAttentionEqualsTheOpByOpFormulationAndItsGradients) {
  torch::manual_seed(3);
  // A sparse directed graph with self-loops (node 4 hears only itself) and the full graph.
  Tensor sparse = torch::eye(5, torch::kBool);
  for (auto [i, j] : std::vector<std::pair<int, int>>{{0, 1}, {1, 2}, {2, 0}, {3, 0}, {3, 1}, {0, 4}})
    sparse[i][j] = true;
  checkGat(sparse);
  checkGat(torch::ones({6, 6}, torch::kBool));
}

TEST(FusedKernels, GatAttentionRefusesANodeThatHearsNobody) {
  Tensor mask = torch::eye(3, torch::kBool);
  mask[1][1] = false;
  EXPECT_THROW(fused::inEdgesFromMask(mask), ddace::Error);
}

TEST(FusedKernels, GruEqualsTorchGruAndItsGradients) {
  torch::manual_seed(5);
  torch::nn::GRU reference(torch::nn::GRUOptions(6, 4).num_layers(2).batch_first(true));
  for (const bool with_h0 : {false, true}) {
    const Tensor x = leaf({3, 5, 6});
    const Tensor h0 = with_h0 ? leaf({2, 3, 4}) : Tensor();
    const Tensor w_out = torch::randn({3, 5, 4}), w_last = torch::randn({2, 3, 4});
    auto check_pass = [&](bool use_fused) {
      for (auto& p : reference->parameters())
        if (p.grad().defined()) p.mutable_grad().zero_();
      if (x.grad().defined()) x.mutable_grad().zero_();
      if (with_h0 && h0.grad().defined()) h0.mutable_grad().zero_();
      std::pair<Tensor, Tensor> y;
      if (use_fused) {
        y = fused::gru(reference, x, h0);
      } else {
        auto r = with_h0 ? reference->forward(x, h0) : reference->forward(x);
        y = {std::get<0>(r), std::get<1>(r)};
      }
      ((y.first * w_out).sum() + (y.second * w_last).sum()).backward();
      std::vector<Tensor> grads{x.grad().clone()};
      if (with_h0) grads.push_back(h0.grad().clone());
      for (auto& p : reference->parameters()) grads.push_back(p.grad().clone());
      return std::make_pair(y, grads);
    };
    const auto [fy, fg] = check_pass(true);
    const auto [ry, rg] = check_pass(false);
    expectClose(fy.first, ry.first, 1e-5, "output");
    expectClose(fy.second, ry.second, 1e-5, "h_n");
    ASSERT_EQ(fg.size(), rg.size());
    for (size_t i = 0; i < fg.size(); ++i) expectClose(fg[i], rg[i], 1e-4, "gradient " + std::to_string(i));
  }
}

TEST(FusedKernels, GruRefusesMisshapenInputs) {
  torch::nn::GRU gru(torch::nn::GRUOptions(6, 4).num_layers(2).batch_first(true));
  torch::NoGradGuard no_grad;
  EXPECT_THROW(fused::gru(gru, torch::zeros({3, 5, 7})), ddace::Error) << "input size";
  EXPECT_THROW(fused::gru(gru, torch::zeros({3, 0, 6})), ddace::Error) << "no steps";
  EXPECT_THROW(fused::gru(gru, torch::zeros({3, 5, 6}), torch::zeros({2, 2, 4})), ddace::Error) << "h0 batch";
  EXPECT_THROW(fused::gru(gru, torch::zeros({3, 5, 6}), torch::zeros({1, 3, 4})), ddace::Error) << "h0 layers";
  EXPECT_EQ(fused::gru(gru, torch::zeros({3, 1, 6}), torch::zeros({2, 3, 4})).first.sizes(),
            (std::vector<int64_t>{3, 1, 4}));
}

TEST(FusedKernels, FlatAdamWithClippingEqualsTorchAdam) {
  torch::manual_seed(7);
  torch::nn::Linear a(3, 4), b(3, 4);
  {
    torch::NoGradGuard no_grad;
    b->weight.copy_(a->weight);
    b->bias.copy_(a->bias);
  }
  torch::optim::Adam reference(b->parameters(), torch::optim::AdamOptions(0.01));
  {
    fused::FlatParameters flat(a->parameters());
    for (int step = 0; step < 5; ++step) {
      const Tensor x = torch::randn({8, 3}) * 10;  // gradients well above the clipping norm
      flat.zeroGrad();
      a(x).pow(2).sum().backward();
      flat.clipGradNorm(1.0);
      flat.adamStep(0.01);
      reference.zero_grad();
      b(x).pow(2).sum().backward();
      torch::nn::utils::clip_grad_norm_(b->parameters(), 1.0);
      reference.step();
      expectClose(a->weight, b->weight, 1e-6, "weight after step " + std::to_string(step));
      expectClose(a->bias, b->bias, 1e-6, "bias after step " + std::to_string(step));
    }
  }
  // Released: the parameters own their storage again and training state is gone.
  EXPECT_FALSE(a->weight.grad().defined());
  EXPECT_NE(a->weight.storage().data(), a->bias.storage().data());
  expectClose(a->weight, b->weight, 1e-6, "weight after release");
}
