// detail::interchangeableNames: the entities whose identity embeddings training shuffles
// ("Shuffled names", docs/tgn.md), read from the demonstrations' tokens and scenes.
#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "ddace/tgn/detail.h"

namespace ddace::tgn::detail {

namespace {

// "The rule refers to this entity by name": how unlikely, were the names interchangeable,
// its relation holding in every demonstration while its group mates' holds as rarely as
// it does. A rule holds the relation in every demonstration, chance at the mates' rate;
// 1e-3 keeps the false alarms of the rule zoo's 100 training sets (50 rules, 10 and 20
// demonstrations, some 50 relations each) to two, at 10 demonstrations (docs/tgn-log.md).
constexpr double kReferredNameSignificance = 1e-3;

/// P(X >= k) for X ~ Binomial(n, p).
double binomialTail(int n, int k, double p) {
  if (p <= 0) return k <= 0 ? 1.0 : 0.0;
  if (p >= 1) return 1.0;
  double tail = 0;
  for (int i = std::max(k, 0); i <= n; ++i)
    tail += std::exp(std::lgamma(n + 1.0) - std::lgamma(i + 1.0) - std::lgamma(n - i + 1.0) + i * std::log(p) +
                     (n - i) * std::log1p(-p));
  return tail;
}

/// A relation of entity e to a token's participant X, without its value: the token's
/// action, X's part in it (0 actor, 1 target), X's kind, e's part (0 none, 1 actor, 2
/// target), and which rank of X among its kind seen from e (0 nearness, 1 farness).
using Relation = std::tuple<std::string, int, int, int, int>;

/// The members of `group` (entities of one kind the tokens do not tell apart) that the
/// rule refers to by name: "the robot 2nd farthest from G1", "the goals in turn, G1 first,
/// each taking the free box nearest to it". Such a member has a relation to the tokens'
/// participants, a nearness or farness rank (1 = the nearest of the participant's kind
/// seen from it, others of that kind counted, itself not), with one value in every
/// demonstration but labelling slips, and its group mates, where they have that relation
/// at all, have that value so much more rarely that the names are not interchangeable
/// (binomial tail at the mates' pooled rate < kReferredNameSignificance). Ranks are read
/// in the snapshot the step was decided in.
std::set<int> referredByName(const task::TaskDir& train, const std::vector<int>& group, size_t slips) {
  std::set<int> referred;
  if (group.size() < 2 || train.demos.empty()) return referred;
  const std::vector<task::Entity>& entities = train.spec.entities;
  const auto kind = [&](int i) { return static_cast<int>(entities[static_cast<size_t>(i)].kind); };
  // Per member: the demonstrations with the relation, and those in which it had one value.
  std::map<int, std::map<Relation, int>> testable;
  std::map<int, std::map<std::pair<Relation, int>, int>> holds;
  for (const auto& d : train.demos)
    for (int e : group) {
      std::map<Relation, std::set<int>> values;
      for (size_t k = 0; k < d.steps.size() && k < d.snapshots.size(); ++k) {
        const std::vector<Eigen::Vector2d>& pos = d.snapshots[k].positions;
        const auto distance = [&](int a) { return (pos[static_cast<size_t>(a)] - pos[static_cast<size_t>(e)]).norm(); };
        for (const task::Token& t : d.steps[k].tokens) {
          const int part = t.entity == e ? 1 : t.target == e ? 2 : 0;
          for (int role = 0; role < 2; ++role) {
            const int x = role == 0 ? t.entity : t.target;
            if (x < 0 || x == e) continue;
            int nearer = 0, farther = 0;
            for (int o = 0; o < static_cast<int>(entities.size()); ++o) {
              if (o == e || o == x || kind(o) != kind(x)) continue;
              nearer += distance(o) < distance(x);
              farther += distance(o) > distance(x);
            }
            values[{t.action, role, kind(x), part, 0}].insert(1 + nearer);
            values[{t.action, role, kind(x), part, 1}].insert(1 + farther);
          }
        }
      }
      for (const auto& [relation, seen] : values) {
        ++testable[e][relation];
        if (seen.size() == 1) ++holds[e][{relation, *seen.begin()}];
      }
    }
  const int demos = static_cast<int>(train.demos.size());
  for (int e : group)
    for (const auto& [relation_value, count] : holds[e]) {
      if (count + static_cast<int>(slips) < demos) continue;  // not in every demonstration
      int mates_hold = 0, mates_testable = 0;
      for (int m : group) {
        if (m == e) continue;
        mates_testable += testable[m][relation_value.first];
        mates_hold += holds[m][relation_value];
      }
      if (mates_testable == 0) continue;  // the tokens tell them apart, or nothing does
      const double rate = (mates_hold + 0.5) / (mates_testable + 1.0);
      if (binomialTail(testable[e][relation_value.first], count, rate) < kReferredNameSignificance) referred.insert(e);
    }
  return referred;
}

}  // namespace

std::vector<std::vector<int>> interchangeableNames(const task::TaskDir& train) {
  const std::vector<task::Entity>& entities = train.spec.entities;
  const size_t n = entities.size();
  const auto kind = [&](int i) { return std::string(task::toString(entities[static_cast<size_t>(i)].kind)); };
  // roles[e][d]: entity e's tokens in demonstration d, names of the others replaced by kinds.
  std::vector<std::vector<std::vector<std::string>>> roles(n);
  for (const auto& d : train.demos) {
    std::vector<std::vector<std::string>> role(n);
    for (size_t k = 0; k < d.steps.size(); ++k)
      for (const auto& t : d.steps[k].tokens) {
        const std::string step = std::to_string(k) + ":" + t.action;
        role[static_cast<size_t>(t.entity)].push_back(step + ":acts:" + (t.target >= 0 ? kind(t.target) : "-"));
        if (t.target >= 0) role[static_cast<size_t>(t.target)].push_back(step + ":target of:" + kind(t.entity));
      }
    for (size_t e = 0; e < n; ++e) {
      std::sort(role[e].begin(), role[e].end());
      roles[e].push_back(role[e]);
    }
  }
  // An entity's role is fixed when it is the same in every demonstration but labelling
  // slips: at most one in ten of them (rounded down), as task::commonSteps allows.
  const size_t slips = train.demos.size() / 10;
  std::vector<std::vector<std::string>> modal(n);
  std::vector<bool> fixed(n, false);
  for (size_t e = 0; e < n && !train.demos.empty(); ++e) {
    size_t best = 0;
    for (const auto& r : roles[e]) {
      const size_t count = static_cast<size_t>(std::count(roles[e].begin(), roles[e].end(), r));
      if (count > best) best = count, modal[e] = r;
    }
    fixed[e] = best + slips >= roles[e].size();
  }
  std::vector<std::vector<int>> groups;
  for (task::EntityKind k : {task::EntityKind::Robot, task::EntityKind::Object, task::EntityKind::Goal}) {
    std::vector<int> group;
    for (size_t e = 0; e < n; ++e) {
      if (entities[e].kind != k) continue;
      bool named = fixed[e];
      for (size_t o = 0; o < n && named; ++o)
        if (o != e && entities[o].kind == k && fixed[o] && modal[o] == modal[e]) named = false;
      if (!named) group.push_back(static_cast<int>(e));
    }
    const std::set<int> referred = referredByName(train, group, slips);
    group.erase(std::remove_if(group.begin(), group.end(), [&](int e) { return referred.count(e) > 0; }), group.end());
    if (group.size() >= 2) groups.push_back(group);
  }
  std::sort(groups.begin(), groups.end());
  return groups;
}

}  // namespace ddace::tgn::detail
