// SequenceModel::train: mini-batches, Adam on the flat parameters, the plateau rule.
#include <torch/torch.h>

#include <algorithm>
#include <chrono>
#include <iomanip>
#include <limits>
#include <ostream>

#include "ddace/common/random.h"
#include "ddace/tgn/detail.h"
#include "fused_kernels.h"
#include "loss.h"
#include "model_impl.h"

namespace ddace::tgn {

using torch::Tensor;

namespace {

/// `threads` intra-op threads while training, the process's own count again afterwards.
class ThreadCount {
 public:
  explicit ThreadCount(int threads) : saved_(at::get_num_threads()) { at::set_num_threads(threads); }
  ~ThreadCount() { at::set_num_threads(saved_); }
  ThreadCount(const ThreadCount&) = delete;
  ThreadCount& operator=(const ThreadCount&) = delete;

 private:
  int saved_;
};

/// One training run with exactly `options`.
std::shared_ptr<SequenceModel::Impl> trainNetwork(const task::TaskDir& train, const TrainOptions& options,
                                                  std::ostream* progress) {
  auto impl = prepare(train, options);
  const auto started = std::chrono::steady_clock::now();
  const ThreadCount threads(options.threads);
  impl->build();
  torch::nn::Module& net = impl->module();
  const bool gnn = impl->cfg.gnn, acting_targets = impl->isScene();
  const std::vector<Sequence> seqs = impl->sequences(train.demos);
  // The eval pass after every epoch reads every sequence, collated once: the data do not
  // change and the pass only reads the batch (the same losses and weights to the bit).
  const Batch everything = collateAll(seqs, gnn);
  fused::FlatParameters parameters(net.parameters());  // Adam as torch::optim::Adam, in a few ops
  SplitMix64 rng(options.seed ^ 0xD1B54A32D192ED03ULL);
  std::vector<size_t> order(seqs.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  ModelInfo& info = impl->info;
  info.stop_reason = "max_epochs";
  // At least 4 optimiser steps per epoch when there are few demonstrations (few-shot).
  const size_t bs = std::min(static_cast<size_t>(options.batch_demos), std::max<size_t>(1, (seqs.size() + 3) / 4));
  for (int epoch = 1; epoch <= options.max_epochs; ++epoch) {
    for (size_t i = order.size(); i > 1; --i) std::swap(order[i - 1], order[rng.next() % i]);
    net.train();
    double total = 0;
    int batches = 0;
    for (size_t from = 0; from < order.size(); from += bs) {
      const std::vector<size_t> which(order.begin() + static_cast<long>(from),
                                      order.begin() + static_cast<long>(std::min(order.size(), from + bs)));
      const Batch batch = collate(seqs, which, gnn);
      parameters.zeroGrad();
      const Tensor loss = lossOf(impl->run(batch), batch, gnn, acting_targets);
      loss.backward();
      // GRUs on few sequences occasionally take a huge step; clipping keeps training monotone.
      parameters.clipGradNorm(kClipNorm);
      parameters.adamStep(options.learning_rate, options.weight_decay);
      total += loss.item<double>();
      ++batches;
    }
    EpochRecord rec;
    rec.epoch = epoch;
    rec.loss = total / batches;
    rec.step_accuracy = impl->accuracy(everything);
    rec.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    info.history.push_back(rec);
    if (progress) {
      const std::ios::fmtflags flags = progress->flags();
      const std::streamsize precision = progress->precision();
      *progress << "epoch " << epoch << "/" << options.max_epochs << "  loss " << std::fixed << std::setprecision(4)
                << rec.loss << "  " << (gnn ? "frame label accuracy " : "step accuracy ") << std::setprecision(3)
                << rec.step_accuracy << "  " << std::setprecision(1) << rec.seconds << " s" << std::endl;
      progress->flags(flags);
      progress->precision(precision);
    }
    if (detail::atPlateau(info.history, options.plateau_patience, options.plateau_delta)) {
      info.stop_reason = "plateau";
      break;
    }
  }
  net.eval();
  return impl;
}

}  // namespace

TrainOptions withFixedOrderRule(const task::TaskDir& train, const TrainOptions& requested) {
  // Fixed order: when every demonstration has the same steps, the configuration decided
  // nothing in them, and what the relative features could teach is only coincidence of
  // the few start configurations seen (measured: Task 2 with 10 demonstrations and 2 mm
  // position noise, OSR 0.73 with them, 1.00 without). Then the decision is the names' and
  // the steps so far: a new configuration cannot change it.
  TrainOptions options = requested;
  const bool fixed_order =
      train.demos.size() >= 2 && std::all_of(train.demos.begin(), train.demos.end(), [&](const auto& d) {
        return task::sameSteps(d.steps, train.demos.front().steps);
      });
  if (options.variant == Variant::Scene && options.relative_features && options.fixed_order_rule && fixed_order)
    options.relative_features = false;
  return options;
}

SequenceModel SequenceModel::train(const task::TaskDir& train, const TrainOptions& requested, std::ostream* progress) {
  const TrainOptions options = withFixedOrderRule(train, requested);
  if (progress && options.relative_features != requested.relative_features)
    *progress << "every demonstration has the same " << train.demos.front().steps.size()
              << " steps: training without the relative features (a decision cannot depend on the configuration; "
                 "--relative keeps them)"
              << std::endl;
  std::shared_ptr<Impl> impl = trainNetwork(train, options, progress);
  // The identity embedding lets the scene network tell entities apart by name, which the
  // fixed-order tasks need; where the decision is the scene's (nearest_goal), it can also
  // settle on fitting the demonstrations by name and stall short of them. Then a network
  // that must decide from the scene alone is trained too, and kept when it fits better.
  const double fit = impl->info.history.back().step_accuracy;
  if (options.variant == Variant::Scene && options.identity_embedding && fit < 1) {
    TrainOptions without = options;
    without.identity_embedding = false;
    if (progress)
      *progress << "step accuracy " << fit << " with the identity embedding: training without it" << std::endl;
    std::shared_ptr<Impl> alternative = trainNetwork(train, without, progress);
    const double alternative_fit = alternative->info.history.back().step_accuracy;
    const bool better = alternative_fit > fit;
    if (progress)
      *progress << "step accuracy " << alternative_fit << " without the identity embedding: keeping the network "
                << (better ? "without" : "with") << " it" << std::endl;
    if (better) impl = alternative;
  }
  return SequenceModel(impl);
}

namespace detail {

bool atPlateau(const std::vector<EpochRecord>& history, int patience, double delta) {
  // The best loss of the last `p` epochs within delta of the best of the `p` before them (a
  // recovering spike is not a plateau), and the last epoch's too: the weights kept are the
  // last epoch's, and an epoch that just took a bad step (Adam now and then does, even with
  // clipping) must not end training.
  const int64_t p = patience, n = static_cast<int64_t>(history.size());
  if (p < 1 || n < 2 * p) return false;
  double before = std::numeric_limits<double>::infinity(), recent = before;
  for (int64_t e = n - 2 * p; e < n; ++e) {
    double& best = e < n - p ? before : recent;
    best = std::min(best, history[static_cast<size_t>(e)].loss);
  }
  return std::abs(before - recent) < delta && history.back().loss - recent < delta;
}

}  // namespace detail

}  // namespace ddace::tgn
