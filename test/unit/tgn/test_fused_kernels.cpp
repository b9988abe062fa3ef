// The fused kernels (src/core/tgn/fused_kernels.h: GAT attention, the scene network's
// attention layer and pointer scores, the GRU) against autograd of the op-by-op PyTorch
// formulation: values and every gradient, and Adam on the flat buffer against
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

/// The scene layer's attention written op by op on dense [S, i, j, H, C] tensors (as
/// SceneLayer did before the fused kernel, and as bench/tgn_train_reference.py does).
Tensor sceneReference(const Tensor& hs, const Tensor& hd, const Tensor& he, const Tensor& att, const Tensor& bias,
                      const Tensor& mask) {
  const int64_t s = hs.size(0), n = hs.size(1), h = hs.size(2), c = hs.size(3);
  const Tensor src = hs.view({s, 1, n, h, c}), dst = hd.view({s, n, 1, h, c});
  const Tensor msg = src + he;
  const Tensor logit = (torch::leaky_relu(dst + msg, 0.2) * att).sum(-1);
  const Tensor alpha = torch::softmax(logit.masked_fill(mask.logical_not().view({1, n, n, 1}), -1e30), 2);
  return (alpha.unsqueeze(-1) * msg).sum(2).view({s, n, h * c}) + bias;
}

/// Gradients of `leaves`, cleared afterwards.
std::vector<Tensor> gradsOf(const std::vector<Tensor>& leaves) {
  std::vector<Tensor> out;
  for (const auto& l : leaves) {
    out.push_back(l.grad().clone());
    l.mutable_grad().zero_();
  }
  return out;
}

void checkScene(const Tensor& mask) {
  const int64_t s = 3, n = mask.size(0), h = 2, c = 4;
  const Tensor hs = leaf({s, n, h, c}), hd = leaf({s, n, h, c}), he = leaf({s, n, n, h, c}), bias = leaf({h * c}),
               att = leaf({h, c});
  const std::vector<Tensor> leaves{hs, hd, he, bias, att};
  const Tensor weights = torch::randn({s, n, h * c});
  const fused::InEdges edges = fused::inEdgesFromMask(mask);
  const Tensor out = fused::sceneAttentionV2(hs, hd, he, att, bias, edges);
  (out * weights).sum().backward();
  const std::vector<Tensor> fused_grads = gradsOf(leaves);
  const Tensor ref = sceneReference(hs, hd, he, att, bias, mask);
  (ref * weights).sum().backward();
  const std::vector<Tensor> ref_grads = gradsOf(leaves);
  expectClose(out, ref, 1e-5, "output");
  const char* names[] = {"hs", "hd", "he", "bias", "att"};
  for (size_t i = 0; i < leaves.size(); ++i)
    expectClose(fused_grads[i], ref_grads[i], 1e-4, std::string("d/d") + names[i]);
}

}  // namespace

TEST(FusedKernels, SceneAttentionEqualsTheOpByOpFormulationAndItsGradients) {
  torch::manual_seed(11);
  const Tensor random = torch::rand({7, 7}).lt(0.4).logical_or(torch::eye(7, torch::kBool));
  ASSERT_GT(random.sum().item<int64_t>(), 7) << "the random mask has edges besides the self-loops";
  ASSERT_LT(random.sum().item<int64_t>(), 49) << "the random mask is not the full graph";
  checkScene(random);
  checkScene(torch::ones({5, 5}, torch::kBool));
}

TEST(FusedKernels, SceneAttentionRefusesMisshapenInputs) {
  const fused::InEdges edges = fused::inEdgesFromMask(torch::ones({4, 4}, torch::kBool));
  const Tensor h = torch::zeros({2, 4, 2, 3}), he = torch::zeros({2, 4, 4, 2, 3}), att = torch::zeros({2, 3}),
               bias = torch::zeros({6});
  torch::NoGradGuard no_grad;
  EXPECT_EQ(fused::sceneAttentionV2(h, h, he, att, bias, edges).sizes(), (std::vector<int64_t>{2, 4, 6}));
  EXPECT_THROW(fused::sceneAttentionV2(h, h, torch::zeros({2, 4, 3, 2, 3}), att, bias, edges), ddace::Error) << "pairs";
  EXPECT_THROW(fused::sceneAttentionV2(h, h, he, torch::zeros({2, 4}), bias, edges), ddace::Error) << "att";
  EXPECT_THROW(fused::sceneAttentionV2(h, h, he, att, torch::zeros({5}), edges), ddace::Error) << "bias";
  EXPECT_THROW(fused::sceneAttentionV2(torch::zeros({2, 5, 2, 3}), torch::zeros({2, 5, 2, 3}),
                                       torch::zeros({2, 5, 5, 2, 3}), att, bias, edges),
               ddace::Error)
      << "nodes against the edges";
}

// Every pair of the N entities (training), and some rows only (M of them: token by token
// asks for the rows still to be decided).
TEST(FusedKernels, PointerScoresEqualTheOpByOpFormulationAndItsGradients) {
  torch::manual_seed(13);
  const int64_t p = 4, n = 6, k = 5;
  for (const int64_t m : {n, int64_t{3}}) {
    const Tensor a = leaf({p, m, k}), b = leaf({p, n, k}), r = leaf({p, m, n, k}), z = leaf({p, k}), v = leaf({k});
    const std::vector<Tensor> leaves{a, b, r, z, v};
    const Tensor weights = torch::randn({p, m, n});
    const Tensor out = fused::pointerScores(a, b, r, z, v);
    (out * weights).sum().backward();
    const std::vector<Tensor> fused_grads = gradsOf(leaves);
    const Tensor pre = a.unsqueeze(-2) + b.unsqueeze(-3) + r + z.unsqueeze(-2).unsqueeze(-2);
    const Tensor ref = torch::matmul(torch::relu(pre), v);
    (ref * weights).sum().backward();
    const std::vector<Tensor> ref_grads = gradsOf(leaves);
    expectClose(out, ref, 1e-5, "scores, rows " + std::to_string(m));
    const char* names[] = {"a", "b", "r", "z", "v"};
    for (size_t i = 0; i < leaves.size(); ++i)
      expectClose(fused_grads[i], ref_grads[i], 1e-4, std::string("d/d") + names[i] + ", rows " + std::to_string(m));
    torch::NoGradGuard no_grad;
    EXPECT_THROW(fused::pointerScores(a, b, torch::zeros({p, m, n - 1, k}), z, v), ddace::Error) << "pairs";
    EXPECT_THROW(fused::pointerScores(a, b, torch::zeros({p, m + 1, n, k}), z, v), ddace::Error) << "rows";
    EXPECT_THROW(fused::pointerScores(a, b, r, z, torch::zeros({k + 1})), ddace::Error) << "v";
  }
}

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
