// Decoding one step from the per-entity heads: each entity's argmax, or, when that breaks
// the step rules the training demonstrations kept (StepRules), the best joint assignment.
#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "ddace/common/error.h"
#include "ddace/tgn/detail.h"

namespace ddace::tgn::detail {

namespace {

/// Log-probabilities below this are the same "impossible" (the pointer's self-mask is a
/// -1e9 logit): keeps the assignment's costs finite and well-conditioned.
constexpr double kLogFloor = -1e3;
/// Added to the idle columns when the step size is fixed, so that the optimum uses every
/// one of them (exactly n - step_size idle entities): larger than any sum of floored scores.
constexpr double kIdleBonus = 1e7;

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

}  // namespace

std::vector<DecodedToken> decodeStep(const std::vector<double>& log_action, int actions,
                                     const std::vector<double>& log_target, int targets, const StepRules& rules) {
  if (actions < 2 || targets < 1 || log_action.size() % static_cast<size_t>(actions) != 0)
    throw Error("decodeStep: log_action is not [n][actions] with at least one action besides idle");
  const int n = static_cast<int>(log_action.size() / static_cast<size_t>(actions));
  if (log_target.size() != static_cast<size_t>(n) * static_cast<size_t>(targets))
    throw Error("decodeStep: log_target is not [n][targets]");
  if (rules.step_size > n) throw Error("decodeStep: step_size is larger than the number of entities");
  const auto la = [&](int i, int c) { return std::max(kLogFloor, log_action[static_cast<size_t>(i * actions + c)]); };
  const auto lt = [&](int i, int c) { return std::max(kLogFloor, log_target[static_cast<size_t>(i * targets + c)]); };
  std::vector<DecodedToken> independent(static_cast<size_t>(n));
  std::vector<int> best_action(static_cast<size_t>(n)), best_target(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    const size_t a0 = static_cast<size_t>(i * actions), t0 = static_cast<size_t>(i * targets);
    best_action[static_cast<size_t>(i)] = 1 + argmax(log_action, a0 + 1, a0 + static_cast<size_t>(actions));
    best_target[static_cast<size_t>(i)] = argmax(log_target, t0, t0 + static_cast<size_t>(targets));
    const int a = argmax(log_action, a0, a0 + static_cast<size_t>(actions));
    if (a != 0) independent[static_cast<size_t>(i)] = {a, best_target[static_cast<size_t>(i)]};
  }
  if (!rules.any() || keepsRules(independent, rules)) return independent;

  // Columns an entity can be assigned to, each once: acting with target slot t (one column
  // per target entity when targets are exclusive, else acting with its own best target),
  // acting without a target, idle (its target is free: the target head's best).
  struct Column {
    int target;  // slot, or -1 for idle
    bool own_best;
  };
  std::vector<Column> columns;
  if (rules.exclusive_targets) {
    for (int t = 1; t < targets; ++t) columns.push_back({t, false});
    for (int i = 0; i < n; ++i) columns.push_back({0, false});
  } else {
    for (int i = 0; i < n; ++i) columns.push_back({0, true});
  }
  const int idle_columns = rules.step_size > 0 ? n - rules.step_size : n;
  for (int i = 0; i < idle_columns; ++i) columns.push_back({-1, false});
  const int m = static_cast<int>(columns.size());
  std::vector<double> cost(static_cast<size_t>(n) * static_cast<size_t>(m));
  for (int i = 0; i < n; ++i) {
    const int a = best_action[static_cast<size_t>(i)], bt = best_target[static_cast<size_t>(i)];
    for (int j = 0; j < m; ++j) {
      const Column& c = columns[static_cast<size_t>(j)];
      double score;
      if (c.target < 0) score = la(i, 0) + lt(i, bt) + (rules.step_size > 0 ? kIdleBonus : 0);
      else score = la(i, a) + lt(i, c.own_best ? bt : c.target);
      cost[static_cast<size_t>(i * m + j)] = -score;
    }
  }
  const std::vector<int> column = minCostAssignment(cost, n, m);
  std::vector<DecodedToken> joint(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    const Column& c = columns[static_cast<size_t>(column[static_cast<size_t>(i)])];
    if (c.target >= 0)
      joint[static_cast<size_t>(i)] = {best_action[static_cast<size_t>(i)],
                                       c.own_best ? best_target[static_cast<size_t>(i)] : c.target};
  }
  return joint;
}

}  // namespace ddace::tgn::detail
