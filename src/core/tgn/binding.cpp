// SequenceModel::transfer and boundTo: a model on the entities of another task of the same
// kinds, in other numbers (docs/tgn.md, "Other team sizes").
#include <torch/torch.h>

#include <algorithm>
#include <map>
#include <set>

#include "ddace/common/error.h"
#include "ddace/tgn/detail.h"
#include "model_impl.h"

namespace ddace::tgn {

namespace {

/// Per entity of `other` (task order), the entity of the model's task (task order) whose
/// identity embedding it reads: the one of its name, else one of its kind's interchangeable
/// ones (those no name took first, then again in order). Throws ddace::Error naming what
/// keeps an entity from having one.
std::vector<int> identitySources(const task::TaskSpec& trained, const Transfer& transfer, const task::TaskSpec& other) {
  const std::set<std::string> named(transfer.named.begin(), transfer.named.end());
  const auto kindsOf = [](const task::TaskSpec& s) {
    std::set<std::string> k;
    for (const auto& e : s.entities) k.insert(kindKey(e));
    return k;
  };
  const std::set<std::string> model_kinds = kindsOf(trained), task_kinds = kindsOf(other);
  for (const auto& k : model_kinds)
    if (!task_kinds.count(k)) throw Error("the task has no entity of kind " + k + ", which the model was trained with");
  for (const auto& k : task_kinds)
    if (!model_kinds.count(k)) throw Error("the model was trained with no entity of kind " + k);
  for (const auto& name : transfer.named)
    if (other.entityIndex(name) < 0)
      throw Error("the model knows " + name +
                  " by name (it has a role of its own, or the rule refers to it), and the " + "task has no " + name);
  // The interchangeable entities of each kind (task order): a name group, or every one of
  // the kind without the identity embedding.
  std::map<std::string, std::vector<int>> pool;
  for (size_t e = 0; e < trained.entities.size(); ++e)
    if (!named.count(trained.entities[e].name)) pool[kindKey(trained.entities[e])].push_back(static_cast<int>(e));
  std::vector<int> source(other.entities.size(), -1);
  std::map<std::string, std::set<int>> taken;
  for (size_t e = 0; e < other.entities.size(); ++e) {
    const int same = trained.entityIndex(other.entities[e].name);
    if (same < 0) continue;
    if (kindKey(trained.entities[static_cast<size_t>(same)]) != kindKey(other.entities[e]))
      throw Error(other.entities[e].name + " is a " + kindKey(other.entities[e]) + " in the task, a " +
                  kindKey(trained.entities[static_cast<size_t>(same)]) + " in the model's");
    source[e] = same;
    taken[kindKey(other.entities[e])].insert(same);
  }
  std::map<std::string, size_t> next;
  for (size_t e = 0; e < other.entities.size(); ++e) {
    if (source[e] >= 0) continue;
    const std::string kind = kindKey(other.entities[e]);
    const std::vector<int>& candidates = pool[kind];
    if (candidates.empty())
      throw Error(other.entities[e].name + ": the model knows every " + kind + " of its task by name and has no role " +
                  "for another");
    std::vector<int> order;
    for (int c : candidates)
      if (!taken[kind].count(c)) order.push_back(c);
    for (int c : candidates)
      if (taken[kind].count(c)) order.push_back(c);
    source[e] = order[next[kind]++ % order.size()];
  }
  return source;
}

/// The step size under `other`. It follows the counts it was all of in training: every
/// possible actor (all at once), and, targets exclusive, every entity of a kind the tokens
/// point at (each box fetched at once): under `other` it is the least of those counts
/// there. 3 robots fetching 3 boxes run with 5 robots and 3 boxes fetch 3, not 5. A step
/// size that was all of none stays, and is no rule where other has fewer actors.
int stepSizeFor(int step_size, const ModelInfo& info, const task::TaskSpec& trained, const task::TaskSpec& other) {
  if (step_size == 0) return 0;
  std::set<std::string> actor_kinds, target_kinds;  // token_types: "ACTORKIND:ACTION[:TARGETKIND]"
  for (const auto& type : info.fingerprint.token_types) {
    actor_kinds.insert(type.substr(0, type.find(':')));
    const size_t second = type.find(':', type.find(':') + 1);
    if (second != std::string::npos) target_kinds.insert(type.substr(second + 1));
  }
  const bool loads_carried = !info.plan.step_rules.load_actions.empty();
  const auto actors = [&](const task::TaskSpec& s) {
    return static_cast<int>(std::count_if(s.entities.begin(), s.entities.end(), [&](const task::Entity& e) {
      return actor_kinds.count(task::toString(e.kind)) && !(loads_carried && e.kind == task::EntityKind::Object);
    }));
  };
  const auto ofKind = [](const task::TaskSpec& s, const std::string& kind) {
    return static_cast<int>(std::count_if(s.entities.begin(), s.entities.end(),
                                          [&](const task::Entity& e) { return task::toString(e.kind) == kind; }));
  };
  std::vector<std::pair<int, int>> counts{{actors(trained), actors(other)}};
  if (info.plan.step_rules.exclusive_targets)
    for (const auto& kind : target_kinds) counts.push_back({ofKind(trained, kind), ofKind(other, kind)});
  if (const int followed = detail::followedCount(step_size, counts); followed >= 0) return followed;
  return step_size > actors(other) ? 0 : step_size;
}

}  // namespace

Transfer SequenceModel::transfer() const {
  return transferOf(impl_->info, impl_->spec);
}

SequenceModel SequenceModel::boundTo(const task::TaskSpec& other) const {
  const Impl& from = *impl_;
  const Transfer t = transferOf(from.info, from.spec);
  if (!t.refusal.empty()) throw Error("the model runs only on the entities of its own task: " + t.refusal);
  const std::vector<int> source = identitySources(from.spec, t, other);
  auto impl = std::make_shared<Impl>();
  impl->spec = other;
  impl->info = from.info;
  impl->bound = true;
  TrainingPlan& plan = impl->info.plan;
  plan.attention_edges = detail::liftedToKinds(from.info.plan.attention_edges, from.spec, other);
  plan.step_rules.step_size = stepSizeFor(plan.step_rules.step_size, from.info, from.spec, other);
  plan.end_scene = detail::endSceneFor(from.info.plan.end_scene, from.spec, other, impl->end_waits);
  // The name groups are training's; the bound model is not trained.
  std::map<int, std::vector<int>> groups;
  for (size_t g = 0; g < from.info.plan.name_groups.size(); ++g)
    for (int e : from.info.plan.name_groups[g])
      for (size_t o = 0; o < source.size(); ++o)
        if (source[o] == e) groups[static_cast<int>(g)].push_back(static_cast<int>(o));
  plan.name_groups.clear();
  for (auto& [g, members] : groups) {
    std::sort(members.begin(), members.end());
    if (members.size() >= 2) plan.name_groups.push_back(members);
  }
  impl->build(plan.ensemble);
  torch::NoGradGuard no_grad;
  const std::vector<SceneNetwork> before = from.members(), after = impl->members();
  for (size_t m = 0; m < before.size(); ++m) {
    const auto old_params = before[m]->named_parameters();
    for (auto& p : after[m]->named_parameters()) {
      if (p.key() == "identity.weight") continue;
      p.value().copy_(old_params[p.key()]);
    }
    if (!after[m]->identity) continue;
    // Row k (other's canonical order) from the model's row of its source entity.
    std::vector<int64_t> rows;
    for (int k = 0; k < impl->order.size(); ++k)
      rows.push_back(from.order.canonical_of[static_cast<size_t>(source[static_cast<size_t>(impl->order.task_of[k])])]);
    after[m]->identity->weight.copy_(before[m]->identity->weight.index_select(0, torch::tensor(rows, torch::kLong)));
  }
  // Built modules are in training mode: a bound model's decisions would run with dropout.
  for (SceneNetwork m : after) m->eval();
  return SequenceModel(impl);
}

}  // namespace ddace::tgn
