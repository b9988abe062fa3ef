// TrainingPlan::inconsistency: planTraining()'s enabling conditions (plan.cpp) read
// backwards, for the manifest reader; and what a plan lets the model transfer (transferOf).
// Without libtorch, so the manifest fuzz target links it.
#include <algorithm>
#include <set>
#include <string>
#include <vector>

#include "ddace/tgn/sequence_model.h"

namespace ddace::tgn {

std::string TrainingPlan::inconsistency(const TrainOptions& options) const {
  // The enabling conditions of planTraining() above, read backwards.
  if (slips > 0 && !fixed_order) return "slips without a fixed order";
  if (identity_embedding && !options.identity_embedding) return "identity_embedding where the options have none";
  if (options.variant != Variant::Scene &&
      (relative_features || step_rules.any() || !end_scene.counts.empty() || !step_rules.load_actions.empty() ||
       token_by_token || parked_out_of_ranks || names_or_scene || !name_groups.empty()))
    return std::string("rules of the scene network for the ") + toString(options.variant) + " variant";
  if (relative_features && !options.uses(Rule::Relative)) return "relative_features, switched off by the options";
  if (relative_features && fixed_order && options.uses(Rule::FixedOrder)) return "relative_features on a fixed order";
  if (!relative_features && (token_by_token || parked_out_of_ranks || names_or_scene || !name_groups.empty()))
    return "token_by_token, parked_out_of_ranks, names_or_scene or name_groups without the relative features";
  if (token_by_token && !(options.uses(Rule::TokenByToken) && step_rules.exclusive_targets))
    return "token_by_token without exclusive targets";
  if (parked_out_of_ranks && !options.uses(Rule::Parked)) return "parked_out_of_ranks, switched off by the options";
  if (!end_scene.counts.empty() && !(relative_features && options.uses(Rule::EndScene)))
    return "an end scene without the relative features, or switched off by the options";
  if (end_scene.telling && end_scene.counts.empty()) return "a telling end scene without counts";
  if (!next_targets.empty() && !(relative_features && options.uses(Rule::NextTargets)))
    return "next targets without the relative features, or switched off by the options";
  if (!std::is_sorted(next_targets.begin(), next_targets.end()) ||
      std::adjacent_find(next_targets.begin(), next_targets.end()) != next_targets.end())
    return "next targets not sorted, or repeated";
  for (const EndCount& c : end_scene.counts)
    if (c.count < 1) return "an end scene count below 1";
  // Exactly what planTraining() makes: a manifest edited to fewer networks than weights.pt
  // holds would decide with some of them silently.
  const int ensemble_made = relative_features && options.uses(Rule::Ensemble) ? kEnsembleMembers : 1;
  if (ensemble != ensemble_made)
    return "an ensemble of " + std::to_string(ensemble) + " networks (training makes " + std::to_string(ensemble_made) +
           " for this plan and options)";
  if ((names_or_scene || !name_groups.empty()) && !identity_embedding)
    return "names_or_scene or name_groups without the identity embedding";
  if (!name_groups.empty() && !options.uses(Rule::ShuffledNames)) return "name_groups, switched off by the options";
  for (const auto& g : name_groups)
    for (size_t i = 1; i < g.size(); ++i)
      if (g[i] <= g[i - 1]) return "a name group not in ascending order of distinct entities";
  return "";
}

}  // namespace ddace::tgn

namespace ddace::tgn {

std::string kindKey(const task::Entity& e) {
  return std::string(task::toString(e.kind)) + (e.type.empty() ? "" : ":" + e.type);
}

Transfer transferOf(const ModelInfo& info, const task::TaskSpec& spec) {
  Transfer t;
  const TrainingPlan& p = info.plan;
  if (info.variant != Variant::Scene)
    t.refusal = std::string("the ") + toString(info.variant) + " network has one output slot per entity of its task";
  else if (!p.relative_features)
    t.refusal = p.fixed_order ? "every training demonstration had the same steps (a fixed order): the model learned "
                                "the order of the names, not a rule of the scene"
                              : "trained without the relative features: its decisions depend on the names alone";
  if (!t.refusal.empty()) return t;
  // Without the identity embedding no entity has a name the network sees.
  std::vector<bool> interchangeable(spec.entities.size(), !p.identity_embedding);
  for (const auto& g : p.name_groups)
    for (int e : g)
      if (e >= 0 && static_cast<size_t>(e) < interchangeable.size()) interchangeable[static_cast<size_t>(e)] = true;
  std::set<std::string> kinds;
  for (size_t e = 0; e < spec.entities.size(); ++e) {
    if (interchangeable[e]) kinds.insert(kindKey(spec.entities[e]));
    else t.named.push_back(spec.entities[e].name);
  }
  t.any_number.assign(kinds.begin(), kinds.end());
  if (t.any_number.empty())
    t.refusal = "training kept every entity's name (a name alone decides a role, or shuffling the names cost the fit)";
  return t;
}

std::string Transfer::text() const {
  const auto join = [](const std::vector<std::string>& v) {
    std::string s;
    for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
    return s;
  };
  if (!refusal.empty()) return "its own task's entities only: " + refusal;
  return "any number of " + join(any_number) + (named.empty() ? "" : "; by name: " + join(named));
}

}  // namespace ddace::tgn
