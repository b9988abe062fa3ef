// "Next targets" (docs/tgn.md): which kinds of target an entity takes next, from what its own
// last move went to, as the training tokens show it; per entity, so that it holds for other
// team sizes. No torch.
#include <algorithm>
#include <set>

#include "ddace/tgn/detail.h"

namespace ddace::tgn::detail {

namespace {

/// The kind an entity's last move went to (lastMoves' node `went`), "none" for none.
std::string afterOf(const task::TaskSpec& spec, const std::vector<int>& entity_of, int went) {
  return went < 0 ? "none" : kindKey(spec.entities[static_cast<size_t>(entity_of[static_cast<size_t>(went)])]);
}

}  // namespace

std::vector<NextTarget> nextTargetsOf(const task::TaskDir& train) {
  const task::TaskSpec& spec = train.spec;
  std::vector<int> identity(spec.entities.size());
  for (size_t i = 0; i < identity.size(); ++i) identity[i] = static_cast<int>(i);
  std::set<NextTarget> seen;
  for (const auto& d : train.demos) {
    std::vector<std::vector<Eigen::Vector2d>> history;
    for (size_t k = 0; k < d.steps.size() && k < d.snapshots.size(); ++k) {
      history.push_back(d.snapshots[k].positions);
      const std::vector<int> last = lastMoves(spec, identity, history.data(), history.size());
      for (const task::Token& t : d.steps[k].tokens)
        seen.insert({kindKey(spec.entities[static_cast<size_t>(t.entity)]),
                     afterOf(spec, identity, last[static_cast<size_t>(t.entity)]),
                     t.target < 0 ? "none" : kindKey(spec.entities[static_cast<size_t>(t.target)])});
    }
  }
  return {seen.begin(), seen.end()};
}

std::vector<bool> nextTargetsAllowed(const std::vector<NextTarget>& rule, const task::TaskSpec& spec,
                                     const std::vector<int>& entity_of, const std::vector<Eigen::Vector2d>* history,
                                     size_t count) {
  const size_t n = entity_of.size(), targets = n + 1;
  std::vector<bool> allowed(n * targets, true);
  if (rule.empty()) return allowed;
  const std::vector<int> last = lastMoves(spec, entity_of, history, count);
  const auto kindOf = [&](size_t i) { return kindKey(spec.entities[static_cast<size_t>(entity_of[i])]); };
  for (size_t i = 0; i < n; ++i) {
    const std::string kind = kindOf(i), after = afterOf(spec, entity_of, last[i]);
    std::set<std::string> next;
    for (const NextTarget& t : rule)
      if (t.kind == kind && t.after == after) next.insert(t.target);
    if (next.empty()) continue;  // nothing shown after such a move: the heads decide
    allowed[i * targets] = next.count("none") > 0;
    for (size_t j = 0; j < n; ++j) allowed[i * targets + j + 1] = j != i && next.count(kindOf(j)) > 0;
  }
  return allowed;
}

}  // namespace ddace::tgn::detail
