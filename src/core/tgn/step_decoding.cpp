// Decoding one step from the per-entity heads: each entity's argmax, or, when that breaks
// the step rules the training demonstrations kept (StepRules), the best joint assignment.
#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <utility>

#include "ddace/common/error.h"
#include "ddace/task/body_geometry.h"
#include "ddace/tgn/detail.h"

namespace ddace::tgn::detail {

namespace {

/// Log-probabilities below this are the same "impossible" (the pointer's self-mask is a
/// -1e9 logit): keeps the assignment's costs finite and well-conditioned.
constexpr double kLogFloor = -1e3;
/// Added to the idle columns when the step size is fixed, so that the optimum uses every
/// one of them (exactly n - step_size idle entities): larger than any sum of floored scores.
constexpr double kIdleBonus = 1e7;
/// The score of a column an entity may not take: below any sum of bonuses and floors.
constexpr double kForbidden = 1e9;

/// Rows to distinct columns minimising the summed cost (Hungarian method, O(n^2 m),
/// n <= m); returns the column of every row. Ties resolve by row and column order.
std::vector<int> minCostAssignment(const std::vector<double>& cost, int n, int m) {
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> u(static_cast<size_t>(n) + 1, 0), v(static_cast<size_t>(m) + 1, 0);
  std::vector<int> row_of(static_cast<size_t>(m) + 1, 0), way(static_cast<size_t>(m) + 1, 0);
  for (int i = 1; i <= n; ++i) {
    row_of[0] = i;
    int j0 = 0;
    std::vector<double> minv(static_cast<size_t>(m) + 1, inf);
    std::vector<bool> used(static_cast<size_t>(m) + 1, false);
    do {
      used[static_cast<size_t>(j0)] = true;
      const int i0 = row_of[static_cast<size_t>(j0)];
      double delta = inf;
      int j1 = 0;
      for (int j = 1; j <= m; ++j) {
        if (used[static_cast<size_t>(j)]) continue;
        const double cur =
            cost[static_cast<size_t>((i0 - 1) * m + (j - 1))] - u[static_cast<size_t>(i0)] - v[static_cast<size_t>(j)];
        if (cur < minv[static_cast<size_t>(j)]) {
          minv[static_cast<size_t>(j)] = cur;
          way[static_cast<size_t>(j)] = j0;
        }
        if (minv[static_cast<size_t>(j)] < delta) {
          delta = minv[static_cast<size_t>(j)];
          j1 = j;
        }
      }
      for (int j = 0; j <= m; ++j) {
        if (used[static_cast<size_t>(j)]) {
          u[static_cast<size_t>(row_of[static_cast<size_t>(j)])] += delta;
          v[static_cast<size_t>(j)] -= delta;
        } else {
          minv[static_cast<size_t>(j)] -= delta;
        }
      }
      j0 = j1;
    } while (row_of[static_cast<size_t>(j0)] != 0);
    do {
      const int j1 = way[static_cast<size_t>(j0)];
      row_of[static_cast<size_t>(j0)] = row_of[static_cast<size_t>(j1)];
      j0 = j1;
    } while (j0 != 0);
  }
  std::vector<int> column(static_cast<size_t>(n), -1);
  for (int j = 1; j <= m; ++j)
    if (row_of[static_cast<size_t>(j)] > 0) column[static_cast<size_t>(row_of[static_cast<size_t>(j)] - 1)] = j - 1;
  return column;
}

/// Index of the largest of v[begin, end) (the first on ties, as the independent decode).
int argmax(const std::vector<double>& v, size_t begin, size_t end) {
  size_t best = begin;
  for (size_t k = begin + 1; k < end; ++k)
    if (v[k] > v[best]) best = k;
  return static_cast<int>(best - begin);
}

bool keepsRules(const std::vector<DecodedToken>& step, const StepRules& rules) {
  std::set<int> targets;
  int acting = 0;
  for (const auto& t : step) {
    if (t.action == 0) continue;
    ++acting;
    if (rules.exclusive_targets && t.target > 0 && !targets.insert(t.target).second) return false;
  }
  return rules.step_size <= 0 || acting == rules.step_size;
}

/// An entity's head outputs, floored, and its best acting class and best target.
struct Heads {
  int n = 0, actions = 0, targets = 0;
  const std::vector<double>* log_action = nullptr;
  const std::vector<double>* log_target = nullptr;
  std::vector<int> best_action, best_target;
  double la(int i, int c) const { return std::max(kLogFloor, (*log_action)[static_cast<size_t>(i * actions + c)]); }
  double lt(int i, int c) const { return std::max(kLogFloor, (*log_target)[static_cast<size_t>(i * targets + c)]); }
};

Heads headsOf(const std::vector<double>& log_action, int actions, const std::vector<double>& log_target, int targets,
              const StepRules& rules) {
  if (actions < 2 || targets < 1 || log_action.size() % static_cast<size_t>(actions) != 0)
    throw Error("decodeStep: log_action is not [n][actions] with at least one action besides idle");
  Heads h;
  h.n = static_cast<int>(log_action.size() / static_cast<size_t>(actions));
  h.actions = actions;
  h.targets = targets;
  if (log_target.size() != static_cast<size_t>(h.n) * static_cast<size_t>(targets))
    throw Error("decodeStep: log_target is not [n][targets]");
  if (rules.step_size > h.n) throw Error("decodeStep: step_size is larger than the number of entities");
  h.log_action = &log_action;
  h.log_target = &log_target;
  for (int i = 0; i < h.n; ++i) {
    const size_t a0 = static_cast<size_t>(i * actions), t0 = static_cast<size_t>(i * targets);
    h.best_action.push_back(1 + argmax(log_action, a0 + 1, a0 + static_cast<size_t>(actions)));
    h.best_target.push_back(argmax(log_target, t0, t0 + static_cast<size_t>(targets)));
  }
  return h;
}

/// The best joint assignment under `rules` (see StepRules); with `must_act` >= 0 that
/// entity may not be idle. Returns the tokens and the assignment's summed score.
std::pair<std::vector<DecodedToken>, double> jointAssignment(const Heads& h, const StepRules& rules, int must_act) {
  const int n = h.n;
  // Columns an entity can be assigned to, each once: acting with target slot t (one column
  // per target entity when targets are exclusive, else acting with its own best target),
  // acting without a target, idle (its target is free: the target head's best).
  struct Column {
    int target;  // slot, or -1 for idle
    bool own_best;
  };
  std::vector<Column> columns;
  if (rules.exclusive_targets) {
    for (int t = 1; t < h.targets; ++t) columns.push_back({t, false});
    for (int i = 0; i < n; ++i) columns.push_back({0, false});
  } else {
    for (int i = 0; i < n; ++i) columns.push_back({0, true});
  }
  const int idle_columns = rules.step_size > 0 ? n - rules.step_size : n;
  for (int i = 0; i < idle_columns; ++i) columns.push_back({-1, false});
  const int m = static_cast<int>(columns.size());
  std::vector<double> cost(static_cast<size_t>(n) * static_cast<size_t>(m));
  for (int i = 0; i < n; ++i) {
    const int a = h.best_action[static_cast<size_t>(i)], bt = h.best_target[static_cast<size_t>(i)];
    for (int j = 0; j < m; ++j) {
      const Column& c = columns[static_cast<size_t>(j)];
      double score;
      if (c.target < 0)
        score = i == must_act ? -kForbidden : h.la(i, 0) + h.lt(i, bt) + (rules.step_size > 0 ? kIdleBonus : 0);
      else score = h.la(i, a) + h.lt(i, c.own_best ? bt : c.target);
      cost[static_cast<size_t>(i * m + j)] = -score;
    }
  }
  const std::vector<int> column = minCostAssignment(cost, n, m);
  std::vector<DecodedToken> joint(static_cast<size_t>(n));
  double total = 0;
  for (int i = 0; i < n; ++i) {
    const int j = column[static_cast<size_t>(i)];
    const Column& c = columns[static_cast<size_t>(j)];
    total -= cost[static_cast<size_t>(i * m + j)];
    if (c.target >= 0)
      joint[static_cast<size_t>(i)] = {h.best_action[static_cast<size_t>(i)],
                                       c.own_best ? h.best_target[static_cast<size_t>(i)] : c.target};
  }
  return {joint, total};
}

bool isEmpty(const std::vector<DecodedToken>& step) {
  return std::all_of(step.begin(), step.end(), [](const DecodedToken& t) { return t.action == 0; });
}

}  // namespace

std::vector<DecodedToken> decodeStep(const std::vector<double>& log_action, int actions,
                                     const std::vector<double>& log_target, int targets, const StepRules& rules) {
  const Heads h = headsOf(log_action, actions, log_target, targets, rules);
  std::vector<DecodedToken> independent(static_cast<size_t>(h.n));
  for (int i = 0; i < h.n; ++i) {
    const size_t a0 = static_cast<size_t>(i * actions);
    const int a = argmax(log_action, a0, a0 + static_cast<size_t>(actions));
    if (a != 0) independent[static_cast<size_t>(i)] = {a, h.best_target[static_cast<size_t>(i)]};
  }
  if (!rules.any() || keepsRules(independent, rules)) return independent;
  return jointAssignment(h, rules, -1).first;
}

double stepLogProbability(const std::vector<DecodedToken>& step, const std::vector<double>& log_action, int actions,
                          const std::vector<double>& log_target, int targets) {
  const Heads h = headsOf(log_action, actions, log_target, targets, StepRules{});
  if (step.size() != static_cast<size_t>(h.n)) throw Error("stepLogProbability: the step is not one token per entity");
  double sum = 0;
  for (int i = 0; i < h.n; ++i) {
    const DecodedToken& t = step[static_cast<size_t>(i)];
    sum += h.la(i, t.action) + (t.action == 0 ? 0 : h.lt(i, t.target));
  }
  return sum;
}

bool sameDecision(const StepDecision& a, const StepDecision& b) {
  return a.end == b.end && (a.end || a.tokens == b.tokens);
}

size_t majorityDecision(const std::vector<StepDecision>& decisions) {
  if (decisions.empty()) throw Error("majorityDecision: no decisions");
  size_t best = 0, best_votes = 0;
  for (size_t i = 0; i < decisions.size(); ++i) {
    const size_t votes = static_cast<size_t>(std::count_if(
        decisions.begin(), decisions.end(), [&](const StepDecision& d) { return sameDecision(d, decisions[i]); }));
    if (votes > best_votes) best = i, best_votes = votes;  // the first of the most voted
  }
  return best;
}

StepDecision decideStep(double end_probability, const std::vector<double>& log_action, int actions,
                        const std::vector<double>& log_target, int targets, const StepRules& rules) {
  if (!std::isfinite(end_probability) || end_probability < 0 || end_probability > 1)
    throw Error("decideStep: p(END) = " + std::to_string(end_probability) + " is not a probability");
  StepDecision d;
  if (end_probability > kEndThreshold) {
    d.end = true;
    return d;
  }
  d.tokens = decodeStep(log_action, actions, log_target, targets, rules);
  if (!isEmpty(d.tokens)) return d;
  // Every entity would stay idle, which is no step: the most probable step in which some
  // entity acts (the joint decoder's best with entity k forced to act, best k, the first
  // on ties), unless END is at least as probable as it.
  const Heads h = headsOf(log_action, actions, log_target, targets, rules);
  double best = -std::numeric_limits<double>::infinity();
  for (int k = 0; k < h.n; ++k) {
    auto [step, score] = jointAssignment(h, rules, k);
    if (score > best) {
      best = score;
      d.tokens = std::move(step);
    }
  }
  const double log_step = stepLogProbability(d.tokens, log_action, actions, log_target, targets);
  if (std::log(end_probability) >= std::log1p(-end_probability) + log_step) {
    d.end = true;
    d.tokens.assign(static_cast<size_t>(h.n), DecodedToken{});
  }
  return d;
}

std::vector<Load> loadsAt(const task::TaskSpec& spec, const std::vector<int>& entity_of,
                          const std::vector<Eigen::Vector2d>& pos) {
  const int n = static_cast<int>(entity_of.size());
  if (pos.size() != entity_of.size()) throw Error("loadsAt: not one position per entity");
  const auto isObject = [&](int i) {
    return spec.entities.at(static_cast<size_t>(entity_of[static_cast<size_t>(i)])).kind == task::EntityKind::Object;
  };
  const auto at = [&](int c, int o) {
    return task::together(spec, entity_of[static_cast<size_t>(c)], pos[static_cast<size_t>(c)],
                          entity_of[static_cast<size_t>(o)], pos[static_cast<size_t>(o)]);
  };
  std::vector<Load> loads;
  std::vector<int> load_of(static_cast<size_t>(n), -1);  // node -> index into loads
  for (int o = 0; o < n; ++o)
    if (isObject(o)) load_of[static_cast<size_t>(o)] = static_cast<int>(loads.size()), loads.push_back({o, {}});
  for (int c = 0; c < n; ++c) {
    if (isObject(c)) continue;
    int nearest = -1;
    for (int o = 0; o < n; ++o)
      if (isObject(o) && at(c, o) &&
          (nearest < 0 || (pos[static_cast<size_t>(o)] - pos[static_cast<size_t>(c)]).norm() <
                              (pos[static_cast<size_t>(nearest)] - pos[static_cast<size_t>(c)]).norm()))
        nearest = o;
    if (nearest >= 0) loads[static_cast<size_t>(load_of[static_cast<size_t>(nearest)])].carriers.push_back(c);
  }
  return loads;
}

void coupleLoads(std::vector<DecodedToken>& step, const std::vector<double>& log_action, int actions,
                 const std::vector<double>& log_target, int targets, const std::vector<Load>& loads,
                 const std::vector<bool>& load_action) {
  const Heads h = headsOf(log_action, actions, log_target, targets, StepRules{});
  if (step.size() != static_cast<size_t>(h.n)) throw Error("coupleLoads: the step is not one token per entity");
  if (load_action.size() != static_cast<size_t>(actions)) throw Error("coupleLoads: load_action is not one per class");
  const auto isLoad = [&](int a) { return a > 0 && load_action[static_cast<size_t>(a)]; };
  const auto score = [&](int i, const DecodedToken& t) {
    return h.la(i, t.action) + (t.action == 0 ? 0 : h.lt(i, t.target));
  };
  // An entity's best token without a load action (idle, or another action with its best target).
  const auto unloaded = [&](int i) {
    DecodedToken best{};
    double s = h.la(i, 0);
    for (int a = 1; a < actions; ++a)
      if (!isLoad(a) && h.la(i, a) + h.lt(i, h.best_target[static_cast<size_t>(i)]) > s)
        s = h.la(i, a) + h.lt(i, h.best_target[static_cast<size_t>(i)]),
        best = {a, h.best_target[static_cast<size_t>(i)]};
    return best;
  };
  for (const Load& load : loads) {
    const int o = load.object;
    const DecodedToken mine = step[static_cast<size_t>(o)];
    bool kept = !isLoad(mine.action) || std::any_of(load.carriers.begin(), load.carriers.end(),
                                                    [&](int c) { return step[static_cast<size_t>(c)] == mine; });
    for (int c : load.carriers)
      if (isLoad(step[static_cast<size_t>(c)].action) && !(step[static_cast<size_t>(c)] == mine)) kept = false;
    if (kept) continue;
    // One decision for the load and the entities at its place: the load idle and none of them
    // with a load action, or the load and one of them with the same load action and target;
    // the most probable of these (the first on ties: idle, then carriers and tokens in order).
    std::vector<DecodedToken> base(load.carriers.size());
    double base_score = 0;
    for (size_t k = 0; k < load.carriers.size(); ++k) {
      const int c = load.carriers[k];
      base[k] = isLoad(step[static_cast<size_t>(c)].action) ? unloaded(c) : step[static_cast<size_t>(c)];
      base_score += score(c, base[k]);
    }
    double best = base_score + h.la(o, 0);
    int best_k = -1;
    DecodedToken best_token{};
    for (size_t k = 0; k < load.carriers.size(); ++k) {
      const int c = load.carriers[k];
      for (int a = 1; a < actions; ++a) {
        if (!isLoad(a)) continue;
        for (int t = 0; t < targets; ++t) {
          const DecodedToken tok{a, t};
          const double v = base_score - score(c, base[k]) + score(c, tok) + score(o, tok);
          if (v > best) best = v, best_k = static_cast<int>(k), best_token = tok;
        }
      }
    }
    for (size_t k = 0; k < load.carriers.size(); ++k) step[static_cast<size_t>(load.carriers[k])] = base[k];
    step[static_cast<size_t>(o)] = DecodedToken{};
    if (best_k >= 0) {
      step[static_cast<size_t>(load.carriers[static_cast<size_t>(best_k)])] = best_token;
      step[static_cast<size_t>(o)] = best_token;
    }
  }
}

}  // namespace ddace::tgn::detail
