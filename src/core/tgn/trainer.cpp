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

/// One network's training (trainNetwork): its sequences, collated once for the eval pass,
/// and the generators of the batch order, the shuffled names and the given tokens, each
/// its own so that a rule off leaves the others' draws as they were.
class NetworkTrainer {
 public:
  NetworkTrainer(const task::TaskDir& train, SequenceModel::Impl& impl)
      : impl_(impl),
        options_(impl.info.options),
        plan_(impl.info.plan),
        n_(impl.cfg.nodes),
        gnn_(impl.cfg.gnn),
        seqs_(impl.sequences(train.demos)),
        everything_(collateAll(seqs_, gnn_)),
        parameters_(impl.module().parameters()),
        rng_(options_.seed ^ 0xD1B54A32D192ED03ULL),
        name_rng_(options_.seed ^ 0x94D049BB133111EBULL),
        given_rng_(options_.seed ^ 0xBF58476D1CE4E5B9ULL),
        loads_carried_(!plan_.step_rules.load_actions.empty()) {
    order_.resize(seqs_.size());
    for (size_t i = 0; i < order_.size(); ++i) order_[i] = i;
    nameGroups();
    if (plan_.token_by_token) tokenByToken();
  }

  /// One epoch over shuffled mini-batches (at least 4 optimiser steps when there are few
  /// demonstrations): the mean loss.
  double epoch() {
    const size_t bs = std::min(static_cast<size_t>(options_.batch_demos), std::max<size_t>(1, (seqs_.size() + 3) / 4));
    for (size_t i = order_.size(); i > 1; --i) std::swap(order_[i - 1], order_[rng_.next() % i]);
    impl_.module().train();
    double total = 0;
    int batches = 0;
    for (size_t from = 0; from < order_.size(); from += bs) {
      const std::vector<size_t> which(order_.begin() + static_cast<long>(from),
                                      order_.begin() + static_cast<long>(std::min(order_.size(), from + bs)));
      Batch batch = collate(seqs_, which, gnn_);
      if (!name_groups_.empty()) batch.names = shuffledNames(which);
      if (plan_.token_by_token) giveTokens(batch, which);
      parameters_.zeroGrad();
      const Tensor loss = lossOf(impl_.run(batch), batch, gnn_, impl_.isScene());
      loss.backward();
      // GRUs on few sequences occasionally take a huge step; clipping keeps training monotone.
      parameters_.clipGradNorm(kClipNorm);
      parameters_.adamStep(options_.learning_rate, options_.weight_decay);
      total += loss.item<double>();
      ++batches;
    }
    return total / batches;
  }

  /// The step accuracy on every training sequence (predictNext's decoder).
  double accuracy() { return impl_.accuracy(everything_); }

 private:
  /// Shuffled names (docs/tgn.md): the plan's groups in canonical indices, groups sorted
  /// too: the draws must not depend on task.yaml's order.
  void nameGroups() {
    for (const auto& g : plan_.name_groups) {
      std::vector<int64_t> canonical;
      for (int e : g) canonical.push_back(impl_.order.canonical_of[static_cast<size_t>(e)]);
      std::sort(canonical.begin(), canonical.end());
      name_groups_.push_back(canonical);
    }
    std::sort(name_groups_.begin(), name_groups_.end());
  }

  /// The identity-embedding row each entity of each slot of `which` reads: its group's
  /// names permuted, one permutation per demonstration.
  Tensor shuffledNames(const std::vector<size_t>& which) {
    std::vector<int64_t> rows;
    for (size_t i : which) {
      std::vector<int64_t> row(static_cast<size_t>(n_));
      for (int64_t k = 0; k < n_; ++k) row[static_cast<size_t>(k)] = k;
      for (const auto& g : name_groups_) {
        std::vector<int64_t> perm = g;
        for (size_t k = perm.size(); k > 1; --k) std::swap(perm[k - 1], perm[name_rng_.next() % k]);
        for (size_t k = 0; k < g.size(); ++k) row[static_cast<size_t>(g[k])] = perm[k];
      }
      for (int64_t t = 0; t < seqs_[i].x.size(0); ++t) rows.insert(rows.end(), row.begin(), row.end());
    }
    return torch::tensor(rows, torch::kLong);
  }

  /// Token by token: what does not change from epoch to epoch, the pairs an entity may be
  /// chosen for and which load stands at which entity's place in every snapshot.
  void tokenByToken() {
    is_object_.resize(static_cast<size_t>(n_));
    for (size_t c = 0; c < is_object_.size(); ++c)
      is_object_[c] = impl_.spec.entities[static_cast<size_t>(impl_.order.task_of[c])].kind == task::EntityKind::Object;
    const std::vector<bool> pairs = impl_.demonstratedTokens().may_point;
    std::vector<float> m(pairs.begin(), pairs.end());
    may_point_ = torch::from_blob(m.data(), {n_, impl_.cfg.targets}, torch::kFloat).clone();
    if (!loads_carried_) return;
    for (const Sequence& s : seqs_) {
      std::vector<Tensor> snapshots;
      for (const auto& pos : s.positions) snapshots.push_back(impl_.carriedBy(impl_.loadsAt(pos)));
      carried_of_.push_back(torch::stack(snapshots));
    }
  }

  /// Token by token (docs/tgn.md): each step of a batch gets a random part of its tokens
  /// given (fewer than all; none as often as any other count), as predictNext will have
  /// chosen them before deciding the rest.
  void giveTokens(Batch& batch, const std::vector<size_t>& which) {
    batch.may_point = may_point_;
    if (!carried_of_.empty()) {
      batch.carried = torch::zeros({batch.b, batch.t, n_, n_});
      for (size_t b = 0; b < which.size(); ++b) {
        const Tensor& c = carried_of_[which[b]];
        batch.carried[static_cast<int64_t>(b)].narrow(0, 0, c.size(0)).copy_(c);
      }
    }
    batch.given = torch::zeros({batch.b, batch.t, n_});
    batch.taken = torch::zeros({batch.b, batch.t, n_});  // rel_slots is this batch's own copy (collate)
    for (size_t b = 0; b < which.size(); ++b)
      for (int64_t t = 0; t < seqs_[which[b]].x.size(0); ++t)
        giveStep(batch, static_cast<int64_t>(b), seqs_[which[b]], t);
  }

  /// Step t of sequence s, slot b of the batch: a random part of its decisions given (a
  /// carried load with its carrier: the same token; targets are exclusive, so no other
  /// carrier has it), their targets taken, and the relative features with them out of the
  /// ranks.
  void giveStep(Batch& batch, int64_t b, const Sequence& s, int64_t t) {
    auto act = s.action.accessor<int64_t, 2>();
    auto tgt = s.target.accessor<int64_t, 2>();
    std::vector<int64_t> acting;
    for (int64_t i = 0; i < n_; ++i)
      if (act[t][i] > 0 && !(loads_carried_ && is_object_[static_cast<size_t>(i)])) acting.push_back(i);
    if (acting.size() < 2) return;
    const size_t count = given_rng_.next() % acting.size();
    if (count == 0) return;
    for (size_t k = acting.size(); k > 1; --k) std::swap(acting[k - 1], acting[given_rng_.next() % k]);
    auto given = batch.given.accessor<float, 3>();
    auto taken = batch.taken.accessor<float, 3>();
    std::vector<bool> competing(static_cast<size_t>(n_), true);
    for (size_t k = 0; k < count; ++k) {
      const int64_t i = acting[k];
      given[b][t][i] = 1;
      competing[static_cast<size_t>(i)] = false;
      for (int64_t o = 0; loads_carried_ && o < n_; ++o)
        if (is_object_[static_cast<size_t>(o)] && act[t][o] == act[t][i] && tgt[t][o] == tgt[t][i]) {
          given[b][t][o] = 1;
          competing[static_cast<size_t>(o)] = false;
        }
      if (tgt[t][i] > 0) {
        taken[b][t][tgt[t][i] - 1] = 1;
        competing[static_cast<size_t>(tgt[t][i] - 1)] = false;
      }
    }
    impl_.relative(s.positions.data(), static_cast<size_t>(t) + 1, batch.rel_slots[b][t].data_ptr<float>(), &competing);
  }

  SequenceModel::Impl& impl_;
  const TrainOptions& options_;
  const TrainingPlan& plan_;
  const int64_t n_;
  const bool gnn_;
  const std::vector<Sequence> seqs_;
  const Batch everything_;
  fused::FlatParameters parameters_;  // Adam as torch::optim::Adam, in a few ops
  SplitMix64 rng_, name_rng_, given_rng_;
  const bool loads_carried_;
  std::vector<size_t> order_;
  std::vector<std::vector<int64_t>> name_groups_;
  std::vector<bool> is_object_;
  Tensor may_point_;
  std::vector<Tensor> carried_of_;
};

/// The epoch's line of `ddace train`'s progress.
void printEpoch(std::ostream& out, const EpochRecord& rec, int max_epochs, bool gnn) {
  const std::ios::fmtflags flags = out.flags();
  const std::streamsize precision = out.precision();
  out << "epoch " << rec.epoch << "/" << max_epochs << "  loss " << std::fixed << std::setprecision(4) << rec.loss
      << "  " << (gnn ? "frame label accuracy " : "step accuracy ") << std::setprecision(3) << rec.step_accuracy << "  "
      << std::setprecision(1) << rec.seconds << " s" << std::endl;
  out.flags(flags);
  out.precision(precision);
}

/// Trains the network `prepared` describes (options and plan; prepare()) on `train`, to
/// the plateau or max_epochs.
std::shared_ptr<SequenceModel::Impl> trainNetwork(const task::TaskDir& train,
                                                  const std::shared_ptr<const SequenceModel::Impl>& prepared,
                                                  std::ostream* progress) {
  auto impl = std::make_shared<SequenceModel::Impl>(*prepared);
  const TrainOptions& options = impl->info.options;
  const auto started = std::chrono::steady_clock::now();
  const ThreadCount threads(options.threads);
  impl->build();
  NetworkTrainer trainer(train, *impl);
  ModelInfo& info = impl->info;
  info.stop_reason = "max_epochs";
  for (int epoch = 1; epoch <= options.max_epochs; ++epoch) {
    EpochRecord rec;
    rec.epoch = epoch;
    rec.loss = trainer.epoch();
    rec.step_accuracy = trainer.accuracy();
    rec.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    info.history.push_back(rec);
    if (progress) printEpoch(*progress, rec, options.max_epochs, impl->cfg.gnn);
    if (detail::atPlateau(info.history, options.plateau_patience, options.plateau_delta)) {
      info.stop_reason = "plateau";
      break;
    }
  }
  impl->module().eval();
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
