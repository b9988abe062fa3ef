// The step decoder (Impl::decide), SequenceModel::predictNext and stepAccuracy.
#include <torch/torch.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "ddace/common/error.h"
#include "ddace/task/end_point.h"
#include "ddace/tgn/detail.h"
#include "loss.h"
#include "model_impl.h"

namespace ddace::tgn {

using torch::Tensor;

double SequenceModel::stepAccuracy(const std::vector<task::Demonstration>& demos) const {
  if (demos.empty()) throw Error("step accuracy: no demonstrations");
  return impl_->accuracy(impl_->sequences(demos));
}

DemonstratedTokens SequenceModel::Impl::demonstratedTokens() const {
  const int64_t n = cfg.nodes, actions = cfg.actions, targets = cfg.targets;
  std::vector<bool> action_ok(static_cast<size_t>(n * actions), true),
      target_ok(static_cast<size_t>(n * targets), true);
  if (!isScene()) return {action_ok, target_ok, {}};  // the paper's networks decode as the paper's
  const auto kindOf = [&](int64_t c) {
    return std::string(task::toString(spec.entities[static_cast<size_t>(order.task_of[static_cast<size_t>(c)])].kind));
  };
  for (int64_t i = 0; i < n; ++i) {
    const std::string kind = kindOf(i);
    for (int64_t a = 1; a < actions; ++a) action_ok[static_cast<size_t>(i * actions + a)] = false;
    for (int64_t t = 0; t < targets; ++t) target_ok[static_cast<size_t>(i * targets + t)] = false;
    // token_types: "kind:action" (in place) or "kind:action:target kind", task::fingerprintOf.
    for (const std::string& type : info.fingerprint.token_types) {
      const size_t c1 = type.find(':');
      if (type.compare(0, c1, kind) != 0) continue;
      const size_t c2 = type.find(':', c1 + 1);
      const int a = vocabIndex(type.substr(c1 + 1, c2 == std::string::npos ? std::string::npos : c2 - c1 - 1));
      if (a >= 0) action_ok[static_cast<size_t>(i * actions + a + 1)] = true;
      if (c2 == std::string::npos) {
        target_ok[static_cast<size_t>(i * targets)] = true;
        continue;
      }
      for (int64_t j = 0; j < n; ++j)
        if (j != i && kindOf(j) == type.substr(c2 + 1)) target_ok[static_cast<size_t>(i * targets + j + 1)] = true;
    }
    // an entity that never acts keeps its (unread) target head as it is
    if (std::none_of(target_ok.begin() + i * targets, target_ok.begin() + (i + 1) * targets, [](bool b) { return b; }))
      std::fill(target_ok.begin() + i * targets, target_ok.begin() + (i + 1) * targets, true);
  }
  // Token by token, an entity left idle may be given a token at an entity it could act on:
  // its kind acted, and it is no carried load (a load's token is its carrier's).
  const bool loads_carried = !info.plan.step_rules.load_actions.empty();
  std::vector<bool> may_point(static_cast<size_t>(n * targets), false);
  for (int64_t i = 0; i < n; ++i) {
    const bool acts = std::any_of(action_ok.begin() + i * actions + 1, action_ok.begin() + (i + 1) * actions,
                                  [](bool b) { return b; });
    if (!acts || (loads_carried && kindOf(i) == task::toString(task::EntityKind::Object))) continue;
    for (int64_t t = 1; t < targets; ++t)
      may_point[static_cast<size_t>(i * targets + t)] = target_ok[static_cast<size_t>(i * targets + t)];
  }
  return {action_ok, target_ok, may_point};
}

double SequenceModel::Impl::endProbability(double p_end, const std::vector<Eigen::Vector2d>& pos) const {
  const EndScene& end = info.plan.end_scene;
  if (end.counts.empty()) return p_end;
  return detail::endProbability(p_end, end, end_waits, spec, inTaskOrder(pos));
}

std::string SequenceModel::Impl::endSceneShort(const std::vector<Eigen::Vector2d>& pos) const {
  const EndScene& end = info.plan.end_scene;
  return end.counts.empty() ? "" : detail::endSceneShort(end, spec, inTaskOrder(pos));
}

std::vector<Eigen::Vector2d> SequenceModel::Impl::inTaskOrder(const std::vector<Eigen::Vector2d>& pos) const {
  std::vector<Eigen::Vector2d> out(pos.size());
  for (size_t c = 0; c < pos.size(); ++c) out[static_cast<size_t>(order.task_of[c])] = pos[c];
  return out;
}

std::vector<detail::Load> SequenceModel::Impl::loadsAt(const std::vector<Eigen::Vector2d>& pos) const {
  return detail::loadsAt(spec, order.task_of, pos);
}

Tensor SequenceModel::Impl::carriedBy(const std::vector<detail::Load>& loads) const {
  const int64_t n = cfg.nodes;
  std::vector<float> m(static_cast<size_t>(n * n), 0.f);
  for (const detail::Load& load : loads)
    for (int c : load.carriers) m[static_cast<size_t>(c * n + load.object)] = 1.f;
  return torch::from_blob(m.data(), {n, n}, torch::kFloat).clone();
}

detail::StepDecision SequenceModel::Impl::decide(double p_end, const std::vector<double>& la_net,
                                                 std::vector<double>& lt, const Tensor& target_logits,
                                                 const Tensor& nodes, const Tensor& z,
                                                 const std::vector<Eigen::Vector2d>* history, size_t count,
                                                 const DemonstratedTokens& demonstrated, int member) const {
  const int64_t n = cfg.nodes;
  const std::vector<Eigen::Vector2d>& pos = history[count - 1];
  const StepRules& rules = info.plan.step_rules;
  // End scene: END waits for what every demonstration's last scene had (docs/tgn.md).
  p_end = endProbability(p_end, pos);
  // Demonstrated tokens only: an entity takes an action, and points at a kind of target,
  // that its kind took in the training demonstrations (the fingerprint's token types; a
  // goal never moves, whatever the step size asks).
  std::vector<double> la = la_net;
  const std::vector<bool>& action_ok = demonstrated.action_ok;
  const std::vector<bool>& target_ok = demonstrated.target_ok;
  for (size_t k = 0; k < la.size(); ++k)
    if (!action_ok[k]) la[k] = -1e9;
  // Next targets: and only at a kind its kind took after a last move like its own (a box
  // handed to a teammate goes on to a goal, however many teammates there are).
  const std::vector<bool> next_ok =
      detail::nextTargetsAllowed(info.plan.next_targets, spec, order.task_of, history, count);
  for (size_t k = 0; k < lt.size(); ++k)
    if (!target_ok[k] || !next_ok[k]) lt[k] = -1e9;
  // Carried loads (StepRules::load_actions): a load and the entities at its place decide as
  // one. The joint decoder sees the decisions only: each load's heads join those of the
  // entities at its place (log p(carrier's token) + log p(the load's: the same load action
  // and target, else idle)) and the load itself stays out; it then takes the token of the
  // one who carries it.
  std::vector<detail::Load> loads;
  std::vector<bool> load_action(static_cast<size_t>(cfg.actions), false);
  std::vector<double> la_joint = la, lt_joint = lt;
  if (!rules.load_actions.empty()) {
    loads = loadsAt(pos);
    for (const std::string& a : rules.load_actions)
      if (vocabIndex(a) >= 0) load_action[static_cast<size_t>(vocabIndex(a) + 1)] = true;
    const int64_t actions = cfg.actions, targets = cfg.targets;
    for (const detail::Load& load : loads) {
      const int64_t o = load.object;
      for (int c : load.carriers) {
        int best = 1;  // the carrier's most probable acting class, with the load's part
        for (int64_t a = 0; a < actions; ++a) {
          la_joint[static_cast<size_t>(c * actions + a)] +=
              la[static_cast<size_t>(o * actions + (load_action[static_cast<size_t>(a)] ? a : 0))];
          if (a > 0 &&
              la_joint[static_cast<size_t>(c * actions + a)] > la_joint[static_cast<size_t>(c * actions + best)])
            best = static_cast<int>(a);
        }
        if (load_action[static_cast<size_t>(best)])
          for (int64_t t = 0; t < targets; ++t)
            lt_joint[static_cast<size_t>(c * targets + t)] += lt[static_cast<size_t>(o * targets + t)];
      }
      for (int64_t a = 0; a < actions; ++a) la_joint[static_cast<size_t>(o * actions + a)] = a == 0 ? 0.0 : -1e9;
    }
  }
  detail::StepDecision decision = detail::decideStep(p_end, la_joint, cfg.actions, lt_joint, cfg.targets, rules);
  if (decision.end) return decision;
  if (info.plan.token_by_token) {
    // Token by token (docs/tgn.md): how many act is the decoded step's; who, and at what,
    // is chosen one token at a time. An entity chosen that the heads left idle takes its
    // most probable acting class.
    std::vector<bool> acting(static_cast<size_t>(n));
    for (int64_t i = 0; i < n; ++i)
      acting[static_cast<size_t>(i)] = decision.tokens[static_cast<size_t>(i)].action != 0;
    // A carrier's pairs are its loads' too (one decision): their pointer logits join.
    const Tensor carried = rules.load_actions.empty() ? Tensor() : carriedBy(loads);
    // The pairs allowed: the demonstrated ones under next targets; a carrier taking its load
    // with it, only those its load may take too.
    DemonstratedTokens allowed = demonstrated;
    const auto onlyWhere = [&](int64_t i, int64_t by) {
      for (int64_t t = 0; t < cfg.targets; ++t) {
        const size_t k = static_cast<size_t>(i * cfg.targets + t);
        const bool ok = next_ok[static_cast<size_t>(by * cfg.targets + t)];
        allowed.target_ok[k] = allowed.target_ok[k] && ok;
        allowed.may_point[k] = allowed.may_point[k] && ok;
      }
    };
    for (int64_t i = 0; i < n; ++i) onlyWhere(i, i);
    for (const detail::Load& load : loads)
      for (int c : load.carriers)
        if (load_action[static_cast<size_t>(decision.tokens[static_cast<size_t>(c)].action)]) onlyWhere(c, load.object);
    const auto [target, log_p] =
        chooseTokens(target_logits, nodes, z, history, count, acting, allowed, carried, member);
    for (int64_t i = 0; i < n; ++i) {
      detail::DecodedToken& token = decision.tokens[static_cast<size_t>(i)];
      if (target[static_cast<size_t>(i)] < 0) {
        token = {};
        continue;
      }
      if (token.action == 0) {
        token.action = 1;
        for (int64_t a = 2; a < cfg.actions; ++a)
          if (la_joint[static_cast<size_t>(i * cfg.actions + a)] >
              la_joint[static_cast<size_t>(i * cfg.actions + token.action)])
            token.action = static_cast<int>(a);
      }
      token.target = target[static_cast<size_t>(i)];
      lt[static_cast<size_t>(i * cfg.targets + token.target)] = log_p[static_cast<size_t>(i)];
    }
  }
  if (!rules.load_actions.empty()) {
    for (const detail::Load& load : loads)
      for (int c : load.carriers)
        if (load_action[static_cast<size_t>(decision.tokens[static_cast<size_t>(c)].action)]) {
          decision.tokens[static_cast<size_t>(load.object)] = decision.tokens[static_cast<size_t>(c)];
          break;
        }
    // Where two carriers took a load action with one load: the more probable of the ways
    // the rule allows (detail::coupleLoads).
    detail::coupleLoads(decision.tokens, la, cfg.actions, lt, cfg.targets, loads, load_action);
  }
  return decision;
}

std::pair<std::vector<int>, std::vector<double>> SequenceModel::Impl::chooseTokens(
    const Tensor& target_logits, const Tensor& nodes, const Tensor& z, const std::vector<Eigen::Vector2d>* history,
    size_t count, const std::vector<bool>& acting, const DemonstratedTokens& demonstrated, const Tensor& carried,
    int member) const {
  const int64_t n = cfg.nodes, targets = cfg.targets;
  const size_t cells = static_cast<size_t>(n * targets);
  // The loads at each entity's place (carried [N, N]): their pointer logits join its own.
  std::vector<std::vector<int64_t>> loads_of(static_cast<size_t>(n));
  if (carried.defined()) {
    const Tensor c = carried.contiguous();
    const float* cp = c.data_ptr<float>();
    for (int64_t i = 0; i < n; ++i)
      for (int64_t o = 0; o < n; ++o)
        if (cp[i * n + o] > 0) loads_of[static_cast<size_t>(i)].push_back(o);
  }
  // The pairs each entity may be chosen for: an acting one any demonstrated target, another
  // the pairs it may point at.
  std::vector<float> mask(cells, -1e9f);
  std::vector<bool> open(static_cast<size_t>(n), false), competing(static_cast<size_t>(n), true);
  for (int64_t i = 0; i < n; ++i)
    for (int64_t j = 0; j < targets; ++j) {
      const size_t k = static_cast<size_t>(i * targets + j);
      if (acting[static_cast<size_t>(i)] ? demonstrated.target_ok[k] : demonstrated.may_point[k]) {
        mask[k] = 0.f;
        open[static_cast<size_t>(i)] = true;
      }
    }
  std::vector<int> target(static_cast<size_t>(n), -1);
  std::vector<double> log_p(static_cast<size_t>(n), 0);
  std::vector<bool> taken(static_cast<size_t>(targets), false);  // slot 0, "none", is never taken
  int64_t left = std::count(acting.begin(), acting.end(), true);
  SceneNetwork net = members().at(static_cast<size_t>(member));
  // The pointer's terms that stay from token to token, computed once.
  const SceneNetworkImpl::PointerParts parts = net->pointerParts(nodes, z, net->hiddenOf(nodes, z));
  const PairRelations relations(*this, history, count);  // the features of each token's competing ones
  std::vector<float> own(cells), logit(cells);
  {
    const Tensor t = target_logits.contiguous();
    std::copy(t.data_ptr<float>(), t.data_ptr<float>() + cells, own.begin());
  }
  while (left > 0) {
    // The logits of every pair: its own, its loads' added, the masks (as floats, in the
    // order the training's tensors add them).
    for (int64_t i = 0; i < n; ++i)
      for (int64_t j = 0; j < targets; ++j) {
        const size_t k = static_cast<size_t>(i * targets + j);
        float joined = 0;
        for (int64_t o : loads_of[static_cast<size_t>(i)]) joined += own[static_cast<size_t>(o * targets + j)];
        logit[k] = own[k] + joined + (taken[static_cast<size_t>(j)] ? -1e9f : 0.f) + mask[k];
      }
    int64_t bi = -1, bj = -1;
    double best = -std::numeric_limits<double>::infinity();
    for (int64_t i = 0; i < n; ++i) {
      if (!open[static_cast<size_t>(i)]) continue;
      for (int64_t j = 0; j < targets; ++j)
        if (logit[static_cast<size_t>(i * targets + j)] > best)
          best = logit[static_cast<size_t>(i * targets + j)], bi = i, bj = j;  // the first on ties: canonical order
    }
    if (bi < 0) break;  // no entity left that may act (unreachable: the acting ones are open)
    // The chosen pair's log-probability among its entity's pairs (a log-softmax of its row).
    const float* row = logit.data() + bi * targets;
    const double top = *std::max_element(row, row + targets);
    double sum = 0;
    for (int64_t j = 0; j < targets; ++j) sum += std::exp(static_cast<double>(row[j]) - top);
    target[static_cast<size_t>(bi)] = static_cast<int>(bj);
    log_p[static_cast<size_t>(bi)] = static_cast<double>(row[bj]) - top - std::log(sum);
    open[static_cast<size_t>(bi)] = false;
    competing[static_cast<size_t>(bi)] = false;
    for (int64_t o : loads_of[static_cast<size_t>(bi)]) competing[static_cast<size_t>(o)] = false;  // given with it
    if (bj > 0) {
      competing[static_cast<size_t>(bj - 1)] = false;
      taken[static_cast<size_t>(bj)] = true;
    }
    if (--left == 0) break;
    // The heads again with the given ones out of the ranks, for the rows read from here
    // on only: the entities still open and their loads.
    std::vector<bool> read(static_cast<size_t>(n), false);
    for (int64_t i = 0; i < n; ++i)
      if (open[static_cast<size_t>(i)]) {
        read[static_cast<size_t>(i)] = true;
        for (int64_t o : loads_of[static_cast<size_t>(i)]) read[static_cast<size_t>(o)] = true;
      }
    std::vector<int64_t> rows;
    for (int64_t i = 0; i < n; ++i)
      if (read[static_cast<size_t>(i)]) rows.push_back(i);
    Tensor given = torch::empty({static_cast<int64_t>(rows.size()), n, kRelativeFeatures});
    relations.write(given.data_ptr<float>(), &competing, &rows);
    const Tensor heads_logits =
        net->pointerLogits(parts, given, torch::tensor(rows, torch::kLong)).contiguous();  // [rows, targets]
    for (size_t q = 0; q < rows.size(); ++q)
      std::copy(heads_logits.data_ptr<float>() + q * targets, heads_logits.data_ptr<float>() + (q + 1) * targets,
                own.begin() + rows[q] * targets);
  }
  return {target, log_p};
}

Prediction SequenceModel::predictNext(const std::vector<task::Snapshot>& history) const {
  const Impl& m = *impl_;
  if (m.cfg.gnn) throw Error("the gnn variant does not predict steps; use tgn::rolloutGnn");
  if (history.empty()) throw Error("predictNext: the snapshot history is empty");
  const int64_t t = static_cast<int64_t>(history.size()), n = m.cfg.nodes;
  for (size_t k = 0; k < history.size(); ++k)
    if (history[k].positions.size() != static_cast<size_t>(n))
      throw Error("predictNext: snapshot " + std::to_string(k) + " has " + std::to_string(history[k].positions.size()) +
                  " positions, the task has " + std::to_string(n) + " entities");
  for (size_t k = 0; k < history.size(); ++k) requireFinite(history[k].positions, m.spec, "predictNext", "snapshot", k);
  torch::NoGradGuard no_grad;
  Tensor x = torch::zeros({t, n, m.cfg.features});
  Tensor rel = m.isScene() ? torch::zeros({t, n, n, kRelativeFeatures}) : Tensor();
  // The snapshots in canonical order.
  std::vector<std::vector<Eigen::Vector2d>> canonical(static_cast<size_t>(t), std::vector<Eigen::Vector2d>(n));
  for (int64_t k = 0; k < t; ++k) {
    for (int64_t c = 0; c < n; ++c)
      canonical[static_cast<size_t>(k)][static_cast<size_t>(c)] =
          history[static_cast<size_t>(k)].positions[static_cast<size_t>(m.order.task_of[static_cast<size_t>(c)])];
    m.features(canonical[static_cast<size_t>(k)], nullptr, x[k].data_ptr<float>());
    if (m.isScene()) m.relative(canonical.data(), static_cast<size_t>(k) + 1, rel[k].data_ptr<float>());
  }
  const auto logSoftmax = [](const Tensor& logits) {
    const Tensor v = torch::log_softmax(logits, -1).to(torch::kDouble).contiguous();
    return std::vector<double>(v.data_ptr<double>(), v.data_ptr<double>() + v.numel());
  };
  // Each network decides (an ensemble's members each; docs/tgn.md), the majority is kept.
  struct Decided {
    double p_end = 0;
    std::vector<double> la, lt;  ///< [N][actions], [N][targets], canonical order
    detail::StepDecision decision;
  };
  std::vector<Decided> decided;
  const bool by_token = m.info.plan.token_by_token;
  const DemonstratedTokens demonstrated = m.demonstratedTokens();
  if (m.isScene()) {
    const std::vector<SceneNetwork> members = m.members();
    for (size_t k = 0; k < members.size(); ++k) {
      SceneNetwork net = members[k];
      const Tensor nodes = net->encode(x, rel);  // the node embeddings and the GRU output, for token by token
      const Tensor z = fused::gru(net->gru, nodes.mean(1).unsqueeze(0)).first.select(1, t - 1).squeeze(0);
      const Heads h = net->heads(nodes[t - 1], rel[t - 1], z);
      Decided d{m.endProbability(torch::softmax(h.end, -1)[1].item<double>(), canonical.back()),
                logSoftmax(h.action),
                logSoftmax(h.target),
                {}};
      d.decision = m.decide(d.p_end, d.la, d.lt, by_token ? h.target : Tensor(), by_token ? nodes[t - 1] : Tensor(), z,
                            canonical.data(), static_cast<size_t>(t), demonstrated, static_cast<int>(k));
      decided.push_back(std::move(d));
      // A majority already: the networks left cannot change the decision (nor which
      // network's it is: the first of the most voted), so they are not run.
      const detail::StepDecision& last = decided.back().decision;
      const size_t votes = static_cast<size_t>(std::count_if(
          decided.begin(), decided.end(), [&](const Decided& o) { return detail::sameDecision(o.decision, last); }));
      if (2 * votes > members.size()) break;
    }
  } else {
    Network net = m.net;
    const Tensor emb = net->encode(x);
    const Heads h = net->heads(fused::gru(net->gru, emb.unsqueeze(0)).first.select(1, t - 1).squeeze(0));
    Decided d{torch::softmax(h.end, -1)[1].item<double>(), logSoftmax(h.action), logSoftmax(h.target), {}};
    d.decision = m.decide(d.p_end, d.la, d.lt, Tensor(), Tensor(), Tensor(), canonical.data(), static_cast<size_t>(t),
                          demonstrated);
    decided.push_back(std::move(d));
  }
  std::vector<detail::StepDecision> decisions;
  for (const Decided& d : decided) decisions.push_back(d.decision);
  const Decided& kept = decided[detail::majorityDecision(decisions)];
  const detail::StepDecision& decision = kept.decision;
  const std::vector<double>& la = kept.la;
  const std::vector<double>& lt = kept.lt;
  Prediction p;
  p.end_probability = kept.p_end;
  p.end = decision.end;
  if (p.end) {
    p.end_short = m.endSceneShort(canonical.back());
    return p;
  }
  const std::vector<detail::DecodedToken>& step = decision.tokens;
  std::vector<std::pair<task::Token, double>> scored;
  for (int64_t i = 0; i < n; ++i) {
    const detail::DecodedToken& d = step[static_cast<size_t>(i)];
    if (d.action == 0) continue;
    // Back from the canonical order to the task's.
    const int entity = m.order.task_of[static_cast<size_t>(i)];
    const int to = d.target == 0 ? -1 : m.order.task_of[static_cast<size_t>(d.target - 1)];
    scored.push_back({{entity, m.info.vocabulary[static_cast<size_t>(d.action - 1)], to},
                      std::exp(la[static_cast<size_t>(i * m.cfg.actions + d.action)] +
                               lt[static_cast<size_t>(i * m.cfg.targets + d.target)])});
  }
  std::sort(scored.begin(), scored.end(), [](const auto& u, const auto& v) { return u.first.entity < v.first.entity; });
  for (const auto& [token, q] : scored) {
    p.tokens.push_back(token);
    p.token_probabilities.push_back(q);
  }
  return p;
}

}  // namespace ddace::tgn
