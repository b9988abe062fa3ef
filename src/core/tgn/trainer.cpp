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

/// Trains the network `prepared` describes (options and plan; prepare()) on `train`.
std::shared_ptr<SequenceModel::Impl> trainNetwork(const task::TaskDir& train,
                                                  const std::shared_ptr<const SequenceModel::Impl>& prepared,
                                                  std::ostream* progress) {
  auto impl = std::make_shared<SequenceModel::Impl>(*prepared);
  const TrainOptions& options = impl->info.options;
  const TrainingPlan& plan = impl->info.plan;
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
  // Shuffled names (docs/tgn.md): the plan's groups in canonical indices, whose identity
  // embeddings each demonstration of a batch permutes; its own generator, so that without
  // groups training is the same to the bit.
  std::vector<std::vector<int64_t>> name_groups;
  for (const auto& g : plan.name_groups) {
    std::vector<int64_t> canonical;
    for (int e : g) canonical.push_back(impl->order.canonical_of[static_cast<size_t>(e)]);
    std::sort(canonical.begin(), canonical.end());
    name_groups.push_back(canonical);
  }
  // In canonical order, groups too: the draws must not depend on task.yaml's order.
  std::sort(name_groups.begin(), name_groups.end());
  SplitMix64 name_rng(options.seed ^ 0x94D049BB133111EBULL);
  const auto shuffledNames = [&](const std::vector<size_t>& which) {
    const int64_t n = impl->cfg.nodes;
    std::vector<int64_t> rows;
    for (size_t i : which) {
      std::vector<int64_t> row(static_cast<size_t>(n));
      for (int64_t k = 0; k < n; ++k) row[static_cast<size_t>(k)] = k;
      for (const auto& g : name_groups) {
        std::vector<int64_t> perm = g;
        for (size_t k = perm.size(); k > 1; --k) std::swap(perm[k - 1], perm[name_rng.next() % k]);
        for (size_t k = 0; k < g.size(); ++k) row[static_cast<size_t>(g[k])] = perm[k];
      }
      for (int64_t t = 0; t < seqs[i].x.size(0); ++t) rows.insert(rows.end(), row.begin(), row.end());
    }
    return torch::tensor(rows, torch::kLong);
  };
  // Token by token (docs/tgn.md): each step of a batch gets a random part of its tokens
  // given (fewer than all; none as often as any other count), as predictNext will have
  // chosen them before deciding the rest. Its own generator: elsewhere training is the same
  // to the bit.
  const bool token_by_token = plan.token_by_token;
  SplitMix64 given_rng(options.seed ^ 0xBF58476D1CE4E5B9ULL);
  const bool loads_carried = !plan.step_rules.load_actions.empty();
  std::vector<bool> is_object(static_cast<size_t>(impl->cfg.nodes));
  for (size_t c = 0; c < is_object.size(); ++c)
    is_object[c] = impl->spec.entities[static_cast<size_t>(impl->order.task_of[c])].kind == task::EntityKind::Object;
  Tensor may_point;
  if (token_by_token) {
    const std::vector<bool> pairs = impl->demonstratedTokens().may_point;
    std::vector<float> m(pairs.begin(), pairs.end());
    may_point = torch::from_blob(m.data(), {impl->cfg.nodes, impl->cfg.targets}, torch::kFloat).clone();
  }
  // Carried loads: which load stands at which entity's place, in every snapshot (they do
  // not change from epoch to epoch).
  std::vector<Tensor> carried_of;
  if (token_by_token && loads_carried)
    for (const Sequence& s : seqs) {
      std::vector<Tensor> snapshots;
      for (const auto& pos : s.positions) snapshots.push_back(impl->carriedBy(impl->loadsAt(pos)));
      carried_of.push_back(torch::stack(snapshots));
    }
  const auto giveTokens = [&](Batch& batch, const std::vector<size_t>& which) {
    const int64_t n = impl->cfg.nodes;
    batch.may_point = may_point;
    if (!carried_of.empty()) {
      batch.carried = torch::zeros({batch.b, batch.t, n, n});
      for (size_t b = 0; b < which.size(); ++b) {
        const Tensor& c = carried_of[which[b]];
        batch.carried[static_cast<int64_t>(b)].narrow(0, 0, c.size(0)).copy_(c);
      }
    }
    batch.given = torch::zeros({batch.b, batch.t, n});
    batch.taken = torch::zeros({batch.b, batch.t, n});  // rel_slots is this batch's own copy (collate)
    auto given = batch.given.accessor<float, 3>();
    auto taken = batch.taken.accessor<float, 3>();
    for (size_t b = 0; b < which.size(); ++b) {
      const Sequence& s = seqs[which[b]];
      auto act = s.action.accessor<int64_t, 2>();
      auto tgt = s.target.accessor<int64_t, 2>();
      for (int64_t t = 0; t < s.x.size(0); ++t) {
        // The decisions: a carried load is given with its carrier (the same token; targets
        // are exclusive, so no other carrier has it), never on its own.
        std::vector<int64_t> acting;
        for (int64_t i = 0; i < n; ++i)
          if (act[t][i] > 0 && !(loads_carried && is_object[static_cast<size_t>(i)])) acting.push_back(i);
        if (acting.size() < 2) continue;
        const size_t count = given_rng.next() % acting.size();
        if (count == 0) continue;
        for (size_t k = acting.size(); k > 1; --k) std::swap(acting[k - 1], acting[given_rng.next() % k]);
        std::vector<bool> competing(static_cast<size_t>(n), true);
        for (size_t k = 0; k < count; ++k) {
          const int64_t i = acting[k];
          given[static_cast<int64_t>(b)][t][i] = 1;
          competing[static_cast<size_t>(i)] = false;
          for (int64_t o = 0; loads_carried && o < n; ++o)
            if (is_object[static_cast<size_t>(o)] && act[t][o] == act[t][i] && tgt[t][o] == tgt[t][i]) {
              given[static_cast<int64_t>(b)][t][o] = 1;
              competing[static_cast<size_t>(o)] = false;
            }
          if (tgt[t][i] > 0) {
            taken[static_cast<int64_t>(b)][t][tgt[t][i] - 1] = 1;
            competing[static_cast<size_t>(tgt[t][i] - 1)] = false;
          }
        }
        impl->relative(s.positions.data(), static_cast<size_t>(t) + 1,
                       batch.rel_slots[static_cast<int64_t>(b)][t].data_ptr<float>(), &competing);
      }
    }
  };
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
      Batch batch = collate(seqs, which, gnn);
      if (!name_groups.empty()) batch.names = shuffledNames(which);
      if (token_by_token) giveTokens(batch, which);
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

SequenceModel SequenceModel::train(const task::TaskDir& train, const TrainOptions& options, std::ostream* progress) {
  const std::shared_ptr<const Impl> prepared = prepare(train, options);
  const TrainingPlan& plan = prepared->info.plan;
  if (progress && plan.fixed_order && !plan.relative_features && options.uses(Rule::Relative)) {
    *progress << "every demonstration has the same steps";
    if (plan.slips > 0)
      *progress << " but for " << plan.slips << " labelling slip" << (plan.slips == 1 ? "" : "s")
                << " (ddace validate lists them)";
    *progress << ": training without the relative features (a decision cannot depend on the configuration; "
                 "--without fixed-order keeps them)"
              << std::endl;
  }
  std::shared_ptr<Impl> impl = trainNetwork(train, prepared, progress);
  // A network that fits its training demonstrations short of every step may have been
  // denied what it needed; the plan's alternatives are trained in turn and each kept when it
  // fits better (the fit: the accuracy check, predictNext's decoder).
  const auto tryInstead = [&](const TrainingPlan& alternative_plan, const std::string& what) {
    const double fit = impl->info.history.back().step_accuracy;
    if (fit >= 1) return;
    auto without = std::make_shared<Impl>(*prepared);
    without->info.plan = alternative_plan;
    if (progress) *progress << "step accuracy " << fit << ": training " << what << std::endl;
    std::shared_ptr<Impl> alternative = trainNetwork(train, without, progress);
    const double alternative_fit = alternative->info.history.back().step_accuracy;
    const bool better = alternative_fit > fit;
    if (progress)
      *progress << "step accuracy " << alternative_fit << " " << what << ": keeping " << (better ? "it" : "the first")
                << std::endl;
    if (better) impl = alternative;
  };
  // Names or the scene: the identity embedding lets the scene network tell entities apart
  // by name, which the fixed-order tasks need; where the decision is the scene's
  // (nearest_goal), it can also settle on fitting the demonstrations by name and stall
  // short of them. Then a network that must decide from the scene alone is tried.
  if (plan.names_or_scene) tryInstead(plan.withoutIdentity(), "without the identity embedding");
  // Shuffled names, unless they cost the fit: the groups are read from the tokens, but a
  // rule may refer to an entity no token tells apart ("the robot 2nd farthest from G1",
  // G1 a target only in some demonstrations, as G2): shuffled with G2, G1's name is lost.
  // Where the network then fits short of the demonstrations, the names are kept (a fit
  // reached by other coincidences of the scenes is not caught: docs/tgn-log.md).
  if (!impl->info.plan.name_groups.empty()) tryInstead(impl->info.plan.withNamesKept(), "with the names kept");
  // Ensemble: the other members trained as the first (with its identity embedding or
  // not), each from a seed of its own; each decodes a step and the majority decides
  // (detail::majorityDecision).
  const int members = impl->info.plan.ensemble;
  for (int k = 1; k < members; ++k) {
    auto member = std::make_shared<Impl>(*prepared);
    member->info.plan = impl->info.plan;
    member->info.options.seed = memberSeed(options.seed, k);
    if (progress)
      *progress << "ensemble: network " << k + 1 << " of " << members << " (seed " << member->info.options.seed << ")"
                << std::endl;
    impl->others.push_back(trainNetwork(train, member, progress)->scene);
  }
  if (progress && members > 1)
    *progress << "ensemble of " << members << ": step accuracy " << impl->accuracy(impl->sequences(train.demos))
              << std::endl;
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
