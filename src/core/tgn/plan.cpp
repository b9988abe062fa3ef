// planTraining: what the training demonstrations decide about training (TrainingPlan), in
// one place. Every rule's enabling condition is stated here (plan_check.cpp reads them
// backwards for the manifest reader); the trainer, the network, the decoder and the manifest
// read the plan (docs/tgn.md, "The training plan").
#include <algorithm>
#include <map>
#include <set>

#include "ddace/common/error.h"
#include "ddace/task/end_point.h"
#include "ddace/tgn/detail.h"
#include "ddace/tgn/sequence_model.h"
#include "scene_network.h"

namespace ddace::tgn {

namespace {

/// The rules every step of `train`'s demonstrations kept (StepRules). Where a carrier and
/// its load are one decision (carried loads), the step size and the exclusive targets count
/// decisions: the load's token is its carrier's, not a second actor nor a second use of the
/// target.
StepRules stepRulesOf(const task::TaskDir& train) {
  StepRules r;
  // [0]: every token; [1]: the decisions (objects' tokens left out).
  bool exclusive[2] = {true, true};
  std::set<size_t> sizes[2];
  std::set<std::string> loads;
  bool carried = true;
  std::vector<int> identity(train.spec.entities.size());
  for (size_t i = 0; i < identity.size(); ++i) identity[i] = static_cast<int>(i);
  const auto isObject = [&](int e) {
    return train.spec.entities[static_cast<size_t>(e)].kind == task::EntityKind::Object;
  };
  for (const auto& d : train.demos)
    for (const auto& t : d.segments)
      if (isObject(t.token.entity)) loads.insert(t.token.action);
  for (const auto& d : train.demos)
    for (size_t k = 0; k < d.steps.size(); ++k) {
      const auto& step = d.steps[k];
      for (int decisions = 0; decisions < 2; ++decisions) {
        std::set<int> targets;
        size_t size = 0;
        for (const auto& t : step.tokens) {
          if (decisions == 1 && isObject(t.entity)) continue;
          ++size;
          if (t.target >= 0 && !targets.insert(t.target).second) exclusive[decisions] = false;
        }
        sizes[decisions].insert(size);
      }
      // Carried loads: who can carry each object as the step begins (detail::loadsAt).
      std::map<int, const task::Token*> token;
      for (const auto& t : step.tokens) token[t.entity] = &t;
      const auto same = [&](int a, int b) {
        return token.count(a) && token.count(b) && token[a]->action == token[b]->action &&
               token[a]->target == token[b]->target;
      };
      for (const detail::Load& load : detail::loadsAt(train.spec, identity, d.snapshots[k].positions)) {
        bool with_carrier = false;
        for (int c : load.carriers) {
          with_carrier = with_carrier || same(load.object, c);
          if (token.count(c) && loads.count(token[c]->action) && !same(load.object, c)) carried = false;
        }
        if (token.count(load.object) && !with_carrier) carried = false;
      }
    }
  if (carried) r.load_actions.assign(loads.begin(), loads.end());
  const int by = r.load_actions.empty() ? 0 : 1;
  r.exclusive_targets = exclusive[by];
  r.step_size = sizes[by].size() == 1 ? static_cast<int>(*sizes[by].begin()) : 0;
  return r;
}

}  // namespace

std::vector<graph::Edge> detail::liftedToKinds(const std::vector<graph::Edge>& edges, const task::TaskSpec& from,
                                               const task::TaskSpec& to) {
  std::set<std::pair<task::EntityKind, task::EntityKind>> kinds;
  for (const auto& e : edges)
    kinds.insert(
        {from.entities[static_cast<size_t>(e.source)].kind, from.entities[static_cast<size_t>(e.target)].kind});
  std::vector<graph::Edge> out;
  const int n = static_cast<int>(to.entities.size());
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      if (i != j && kinds.count({to.entities[static_cast<size_t>(i)].kind, to.entities[static_cast<size_t>(j)].kind}))
        out.push_back({i, j});
  return out;
}

TrainingPlan planTraining(const task::TaskDir& train, const TrainOptions& options, const graph::RefinedGraph& refined) {
  options.validate();
  TrainingPlan p;
  std::vector<std::vector<task::Step>> steps_of;
  for (const auto& d : train.demos) steps_of.push_back(d.steps);
  const task::CommonSteps common = task::commonSteps(steps_of);
  // One demonstration shows no order: nothing is "the same in every one" yet.
  p.fixed_order = train.demos.size() >= 2 && common.fixed;
  p.slips = p.fixed_order ? static_cast<int>(common.slips.size()) : 0;
  p.identity_embedding = options.identity_embedding;
  const int n = static_cast<int>(train.spec.entities.size());
  switch (options.variant) {
    case Variant::Paper:
      p.attention_edges = refined.kept;
      break;
    case Variant::Scene:
      p.attention_edges = detail::liftedToKinds(refined.kept, train.spec, train.spec);
      break;
    case Variant::FullGraph:
    case Variant::Gnn:
      p.attention_edges = graph::fullyConnected(n);
      break;
  }
  if (options.variant != Variant::Scene) return p;  // the paper's networks: none of the rules below
  p.step_rules = stepRulesOf(train);
  // Fixed order: when every demonstration has the same steps, the configuration decided
  // nothing in them, and what the relative features could teach is only coincidence of
  // the few start configurations seen.
  p.relative_features = options.uses(Rule::Relative) && !(options.uses(Rule::FixedOrder) && p.fixed_order);
  if (!p.relative_features) return p;  // the rules below shape what the scene says
  p.parked_out_of_ranks = options.uses(Rule::Parked);
  // End scene: where the scene decides, END too is read from it (what every demonstration's
  // last scene had), not from the steps counted so far, which differ with the team's size.
  if (options.uses(Rule::EndScene)) p.end_scene = detail::endSceneOf(train);
  // Next targets: which kinds of target an entity takes next follows from its own last move
  // (a box handed to a teammate goes on to a goal), not from how many of each kind there are.
  if (options.uses(Rule::NextTargets)) p.next_targets = detail::nextTargetsOf(train);
  // Ensemble: where the scene decides, a few demonstrations are fitted exactly by networks
  // that generalise differently (the training seed's initial weights, dropout, batch order
  // and name draws); each of several networks decodes the step and the majority decides.
  // A fixed order is decided by the steps so far, which any seed learns: one network.
  p.ensemble = options.uses(Rule::Ensemble) ? kEnsembleMembers : 1;
  // Token by token: where every step's targets were exclusive and some step had several
  // (decisions: a carried load's token is its carrier's).
  const bool loads_carried = !p.step_rules.load_actions.empty();
  const auto decisions = [&](const task::Step& s) {
    return std::count_if(s.tokens.begin(), s.tokens.end(), [&](const task::Token& t) {
      return !loads_carried || train.spec.entities[static_cast<size_t>(t.entity)].kind != task::EntityKind::Object;
    });
  };
  p.token_by_token =
      options.uses(Rule::TokenByToken) && p.step_rules.exclusive_targets &&
      std::any_of(train.demos.begin(), train.demos.end(), [&](const task::Demonstration& d) {
        return std::any_of(d.steps.begin(), d.steps.end(), [&](const task::Step& s) { return decisions(s) >= 2; });
      });
  // Shuffled names: only names to shuffle (the identity embedding) and steps the scene decides.
  const std::vector<std::vector<int>> groups =
      p.fixed_order ? std::vector<std::vector<int>>{} : detail::interchangeableNames(train);
  if (options.uses(Rule::ShuffledNames) && p.identity_embedding) p.name_groups = groups;
  // Names or the scene: a network without the identity embedding tells the entities of a
  // kind apart by the scene alone. It can fit the training demonstrations by coincidences
  // of their scenes where a name decides a role (which of queue's slots is the head), and
  // then fails every fresh scene; so it is tried only where the scene decides the role of
  // every entity of a kind with several (each in a name group).
  std::vector<bool> grouped(static_cast<size_t>(n), false);
  for (const auto& g : groups)
    for (int e : g) grouped[static_cast<size_t>(e)] = true;
  const auto kind = [&](int e) { return train.spec.entities[static_cast<size_t>(e)].kind; };
  p.names_or_scene = p.identity_embedding;
  for (int e = 0; e < n; ++e)
    for (int o = 0; o < n; ++o)
      if (o != e && kind(o) == kind(e) && !grouped[static_cast<size_t>(e)]) p.names_or_scene = false;
  return p;
}

TrainingPlan TrainingPlan::withNamesKept() const {
  TrainingPlan p = *this;
  p.name_groups.clear();
  return p;
}

TrainingPlan TrainingPlan::withoutIdentity() const {
  TrainingPlan p = *this;
  p.identity_embedding = false;
  p.names_or_scene = false;
  p.name_groups.clear();  // no names to shuffle
  return p;
}

}  // namespace ddace::tgn
