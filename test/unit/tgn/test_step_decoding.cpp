// The step decoder: each entity's argmax unless that breaks the step rules the training
// demonstrations kept; then the best joint assignment. And the decision handed on: END or
// a step in which some entity acts, never an empty step.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numeric>
#include <random>

#include "ddace/common/error.h"
#include "ddace/tgn/detail.h"
#include "ddace/tgn/sequence_model.h"

using namespace ddace;
using tgn::StepRules;
using tgn::detail::decideStep;
using tgn::detail::DecodedToken;
using tgn::detail::decodeStep;
using tgn::detail::stepLogProbability;

namespace {

/// Rows of probabilities to log-probabilities, row-major.
std::vector<double> logOf(const std::vector<std::vector<double>>& rows) {
  std::vector<double> out;
  for (const auto& r : rows)
    for (double p : r) out.push_back(std::log(p));
  return out;
}

StepRules exclusive(int step_size = 0) {
  StepRules r;
  r.exclusive_targets = true;
  r.step_size = step_size;
  return r;
}

// Three robots (entities 0..2), three goals (entities 3..5): target slot k = entity k-1.
// Every robot acts; robots 0 and 1 both prefer goal slot 4; robot 0 is more certain.
const std::vector<double> kMove =
    logOf({{0.05, 0.95}, {0.05, 0.95}, {0.05, 0.95}, {0.99, 0.01}, {0.99, 0.01}, {0.99, 0.01}});
const std::vector<double> kGoals = logOf({
    {0.01, 0.01, 0.01, 0.01, 0.85, 0.10, 0.01},
    {0.01, 0.01, 0.01, 0.01, 0.55, 0.40, 0.01},
    {0.01, 0.01, 0.01, 0.01, 0.02, 0.02, 0.92},
    {0.94, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01},
    {0.94, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01},
    {0.94, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01},
});

}  // namespace

TEST(StepDecoding, WithoutRulesEachEntityTakesItsOwnArgmax) {
  const auto d = decodeStep(kMove, 2, kGoals, 7, StepRules{});
  const std::vector<DecodedToken> expected = {{1, 4}, {1, 4}, {1, 6}, {0, 0}, {0, 0}, {0, 0}};
  EXPECT_EQ(d, expected);
}

TEST(StepDecoding, ExclusiveTargetsResolveACollisionByTheBestJointAssignment) {
  const auto d = decodeStep(kMove, 2, kGoals, 7, exclusive());
  // Robot 1 gives way (0.85 * 0.40 > 0.10 * 0.55) and takes its second choice.
  const std::vector<DecodedToken> expected = {{1, 4}, {1, 5}, {1, 6}, {0, 0}, {0, 0}, {0, 0}};
  EXPECT_EQ(d, expected);
  // When robot 1 is the more certain of the two, robot 0 gives way instead.
  std::vector<double> goals = kGoals;
  goals[7 + 4] = std::log(0.97);
  goals[7 + 5] = std::log(0.001);
  const auto swapped = decodeStep(kMove, 2, goals, 7, exclusive());
  EXPECT_EQ(swapped[0], (DecodedToken{1, 5}));
  EXPECT_EQ(swapped[1], (DecodedToken{1, 4}));
}

TEST(StepDecoding, RulesTheArgmaxKeepsChangeNothing) {
  std::vector<double> goals = kGoals;
  goals[7 + 4] = std::log(0.30);  // robot 1 now prefers slot 5 itself
  const auto independent = decodeStep(kMove, 2, goals, 7, StepRules{});
  EXPECT_EQ(decodeStep(kMove, 2, goals, 7, exclusive()), independent);
  EXPECT_EQ(decodeStep(kMove, 2, goals, 7, exclusive(3)), independent);
}

TEST(StepDecoding, ALoserWithNoGoodOtherTargetStaysIdle) {
  // Queue-like (target slot k = entity k-1): robots 0 and 1 both step to slot 3, robot 1
  // barely acting; its other targets are unlikely, so under exclusive targets it stays idle.
  const std::vector<double> move = logOf({{0.1, 0.9}, {0.4, 0.6}, {0.9, 0.1}});
  const std::vector<double> where =
      logOf({{0.02, 0.02, 0.06, 0.90}, {0.02, 0.04, 0.06, 0.88}, {0.02, 0.02, 0.06, 0.90}});
  EXPECT_EQ(decodeStep(move, 2, where, 4, StepRules{}), (std::vector<DecodedToken>{{1, 3}, {1, 3}, {0, 0}}));
  EXPECT_EQ(decodeStep(move, 2, where, 4, exclusive()), (std::vector<DecodedToken>{{1, 3}, {0, 0}, {0, 0}}));
}

TEST(StepDecoding, AFixedStepSizeMakesTheLikeliestEntityActWhenNoneWould) {
  // Nobody's own argmax acts; the training steps always had one acting entity.
  const std::vector<double> move = logOf({{0.7, 0.3}, {0.6, 0.4}, {0.9, 0.1}});
  const std::vector<double> where = logOf({{0.1, 0.1, 0.1, 0.7}, {0.1, 0.1, 0.1, 0.7}, {0.1, 0.1, 0.1, 0.7}});
  EXPECT_EQ(decodeStep(move, 2, where, 4, StepRules{}), (std::vector<DecodedToken>(3)));
  StepRules one;
  one.step_size = 1;
  const auto d = decodeStep(move, 2, where, 4, one);
  EXPECT_EQ(d, (std::vector<DecodedToken>{{0, 0}, {1, 3}, {0, 0}}));
  // And too many acting entities are cut to the step size (the most probable stay).
  const std::vector<double> all = logOf({{0.2, 0.8}, {0.3, 0.7}, {0.1, 0.9}});
  const std::vector<double> spread = logOf({{0.1, 0.7, 0.1, 0.1}, {0.1, 0.1, 0.7, 0.1}, {0.1, 0.1, 0.1, 0.7}});
  EXPECT_EQ(decodeStep(all, 2, spread, 4, one), (std::vector<DecodedToken>{{0, 0}, {0, 0}, {1, 3}}));
}

TEST(StepDecoding, PermutingTheEntitiesPermutesTheDecision) {
  // Relabel entity i as perm[i] (rows and the target slots that point at entities).
  const int n = 6, targets = 7;
  std::vector<int> perm = {4, 2, 0, 5, 1, 3};
  std::vector<double> move(kMove.size()), goals(kGoals.size());
  for (int i = 0; i < n; ++i) {
    std::copy(kMove.begin() + i * 2, kMove.begin() + i * 2 + 2, move.begin() + perm[i] * 2);
    goals[static_cast<size_t>(perm[i] * targets)] = kGoals[static_cast<size_t>(i * targets)];
    for (int k = 0; k < n; ++k)
      goals[static_cast<size_t>(perm[i] * targets + 1 + perm[k])] = kGoals[static_cast<size_t>(i * targets + 1 + k)];
  }
  const auto original = decodeStep(kMove, 2, kGoals, targets, exclusive(3));
  const auto permuted = decodeStep(move, 2, goals, targets, exclusive(3));
  for (int i = 0; i < n; ++i) {
    const DecodedToken o = original[static_cast<size_t>(i)], p = permuted[static_cast<size_t>(perm[i])];
    EXPECT_EQ(p.action, o.action) << i;
    EXPECT_EQ(p.target, o.target == 0 ? 0 : 1 + perm[static_cast<size_t>(o.target - 1)]) << i;
  }
}

TEST(StepDecoding, RefusesArraysOfTheWrongShape) {
  EXPECT_THROW(decodeStep({0.0, 0.0, 0.0}, 2, {0.0}, 1, StepRules{}), Error);
  EXPECT_THROW(decodeStep(kMove, 2, kGoals, 6, StepRules{}), Error);
  EXPECT_THROW(decodeStep(kMove, 2, kGoals, 7, exclusive(7)), Error);
}

TEST(StepDecision, AnAllIdleStepBecomesTheLikeliestActingEntityWhenEndIsUnlikely) {
  // Nobody's argmax acts (robot 1 comes closest, 0.4), no rule forces a step: END has
  // p = 0.01, far below P(robot 1 acts alone) = 0.4 * 0.7 * 0.7 * 0.9.
  const std::vector<double> move = logOf({{0.7, 0.3}, {0.6, 0.4}, {0.9, 0.1}});
  const std::vector<double> where = logOf({{0.1, 0.1, 0.1, 0.7}, {0.1, 0.1, 0.1, 0.7}, {0.1, 0.1, 0.1, 0.7}});
  ASSERT_EQ(decodeStep(move, 2, where, 4, StepRules{}), (std::vector<DecodedToken>(3)));
  for (const StepRules& rules : {StepRules{}, exclusive()}) {
    const auto d = decideStep(0.01, move, 2, where, 4, rules);
    EXPECT_FALSE(d.end);
    EXPECT_EQ(d.tokens, (std::vector<DecodedToken>{{0, 0}, {1, 3}, {0, 0}}));
  }
}

TEST(StepDecision, AnAllIdleStepBecomesEndWhenEndIsTheMoreProbable) {
  // Every entity is almost surely idle: P(best acting step) = 0.05 * 0.7 * 0.98 * 0.98 is
  // below p(END) / (1 - p(END)) = 0.3 / 0.7.
  const std::vector<double> move = logOf({{0.98, 0.02}, {0.95, 0.05}, {0.98, 0.02}});
  const std::vector<double> where = logOf({{0.1, 0.1, 0.1, 0.7}, {0.1, 0.1, 0.1, 0.7}, {0.1, 0.1, 0.1, 0.7}});
  const auto d = decideStep(0.3, move, 2, where, 4, StepRules{});
  EXPECT_TRUE(d.end);
  EXPECT_EQ(d.tokens, (std::vector<DecodedToken>(3)));
  // Far less likely END: the step.
  const auto s = decideStep(0.001, move, 2, where, 4, StepRules{});
  EXPECT_FALSE(s.end);
  EXPECT_EQ(s.tokens, (std::vector<DecodedToken>{{0, 0}, {1, 3}, {0, 0}}));
}

TEST(StepDecision, EndAboveTheThresholdAndANonEmptyStepAreAsDecodedBefore) {
  EXPECT_TRUE(decideStep(0.51, kMove, 2, kGoals, 7, exclusive()).end);
  const auto d = decideStep(0.49, kMove, 2, kGoals, 7, exclusive());
  EXPECT_FALSE(d.end);
  EXPECT_EQ(d.tokens, decodeStep(kMove, 2, kGoals, 7, exclusive()));
}

TEST(StepDecision, RefusesAnEndProbabilityThatIsNotAProbability) {
  for (double p : {std::nan(""), -0.1, 1.5, HUGE_VAL}) EXPECT_THROW(decideStep(p, kMove, 2, kGoals, 7, {}), Error) << p;
}

namespace {

bool keeps(const std::vector<DecodedToken>& step, const StepRules& rules) {
  std::vector<int> targets;
  int acting = 0;
  for (const auto& t : step) {
    if (t.action == 0) continue;
    ++acting;
    if (rules.exclusive_targets && t.target > 0) {
      if (std::find(targets.begin(), targets.end(), t.target) != targets.end()) return false;
      targets.push_back(t.target);
    }
  }
  return rules.step_size <= 0 || acting == rules.step_size;
}

/// The joint decoder's objective: acting tokens log p(action) + log p(target), idle ones
/// log p(idle) + their best log p(target) (an idle entity's target is free).
double objective(const std::vector<DecodedToken>& step, const std::vector<double>& la, int actions,
                 const std::vector<double>& lt, int targets) {
  double sum = 0;
  for (size_t i = 0; i < step.size(); ++i) {
    const auto row = lt.begin() + static_cast<long>(i) * targets;
    sum += la[i * static_cast<size_t>(actions) + static_cast<size_t>(step[i].action)] +
           (step[i].action == 0 ? *std::max_element(row, row + targets) : row[step[i].target]);
  }
  return sum;
}

}  // namespace

TEST(StepDecision, NeverAnEmptyStepAndTheMostProbableAlternative) {
  // Random heads, mostly idle so that the all-idle case is common. For each, every step the
  // entities could take is enumerated: the decision is END or keeps the rules and is not
  // empty, and an all-idle decode is replaced by the best non-empty step (or by END when
  // that is the more probable).
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> u(0, 1);
  int replaced = 0, ended = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const int n = 1 + trial % 4, actions = 2 + trial % 2, targets = n + 1;
    std::vector<double> la, lt;
    for (int i = 0; i < n; ++i) {
      std::vector<double> a(static_cast<size_t>(actions)), t(static_cast<size_t>(targets));
      a[0] = 2 + 6 * u(rng);
      for (int c = 1; c < actions; ++c) a[static_cast<size_t>(c)] = u(rng);
      for (auto& v : t) v = 0.05 + u(rng);
      const double sa = std::accumulate(a.begin(), a.end(), 0.0), st = std::accumulate(t.begin(), t.end(), 0.0);
      for (double v : a) la.push_back(std::log(v / sa));
      for (double v : t) lt.push_back(std::log(v / st));
      lt[static_cast<size_t>(i * targets + i + 1)] = -1e9;  // the pointer never targets the entity itself
    }
    StepRules rules;
    rules.exclusive_targets = trial % 3 == 1;
    const double p_end = std::pow(u(rng), 3) * 0.5;
    const auto d = decideStep(p_end, la, actions, lt, targets, rules);
    ASSERT_EQ(d.tokens.size(), static_cast<size_t>(n));
    const bool empty =
        std::all_of(d.tokens.begin(), d.tokens.end(), [](const DecodedToken& t) { return t.action == 0; });
    ASSERT_TRUE(d.end || !empty) << trial;
    if (d.end) {
      EXPECT_TRUE(empty) << trial;
    } else {
      EXPECT_TRUE(keeps(d.tokens, rules)) << trial;
    }
    const auto decoded = decodeStep(la, actions, lt, targets, rules);
    if (std::any_of(decoded.begin(), decoded.end(), [](const DecodedToken& t) { return t.action != 0; })) {
      EXPECT_FALSE(d.end) << trial;
      EXPECT_EQ(d.tokens, decoded) << trial;
      continue;
    }
    // Every non-empty step keeping the rules, the best by the decoder's objective.
    std::vector<DecodedToken> best, cur(static_cast<size_t>(n));
    double best_score = -HUGE_VAL;
    const std::function<void(int)> visit = [&](int i) {
      if (i == n) {
        const bool none = std::all_of(cur.begin(), cur.end(), [](const DecodedToken& t) { return t.action == 0; });
        if (none || !keeps(cur, rules)) return;
        const double s = objective(cur, la, actions, lt, targets);
        if (s > best_score + 1e-9) {
          best_score = s;
          best = cur;
        }
        return;
      }
      cur[static_cast<size_t>(i)] = {};
      visit(i + 1);
      for (int a = 1; a < actions; ++a)
        for (int t = 0; t < targets; ++t) {
          if (t == i + 1) continue;
          cur[static_cast<size_t>(i)] = {a, t};
          visit(i + 1);
        }
      cur[static_cast<size_t>(i)] = {};
    };
    visit(0);
    ASSERT_FALSE(best.empty());
    const double log_step = stepLogProbability(best, la, actions, lt, targets);
    const bool end_wins = std::log(p_end) >= std::log1p(-p_end) + log_step;
    EXPECT_EQ(d.end, end_wins) << trial;
    if (!end_wins) {
      EXPECT_NEAR(objective(d.tokens, la, actions, lt, targets), best_score, 1e-9) << trial;
      ++replaced;
    } else {
      ++ended;
    }
  }
  // Both outcomes of the all-idle case were exercised.
  EXPECT_GT(replaced, 20);
  EXPECT_GT(ended, 20);
}

// Carried loads: entity 0 a robot, entity 1 the box at its place, entities 2 and 3 goals
// (target slots 3 and 4); actions: idle, move, carry (the load action).
namespace {
struct LoadScene {
  std::vector<double> la, lt;
  std::vector<tgn::detail::Load> loads = {{1, {0}}};
  std::vector<bool> load_action = {false, false, true};
  std::vector<DecodedToken> couple(std::vector<DecodedToken> step) const {
    tgn::detail::coupleLoads(step, la, 3, lt, 5, loads, load_action);
    return step;
  }
};
}  // namespace

TEST(CarriedLoads, TheLoadGoesWhereItsCarrierGoesAsOneDecision) {
  LoadScene s;
  // The robot: carry to G1 (slot 3) 0.6, to G2 0.4; the box: carry, to G2 0.7, to G1 0.3.
  s.la = logOf({{0.1, 0.1, 0.8}, {0.1, 0.1, 0.8}, {1, 1e-9, 1e-9}, {1, 1e-9, 1e-9}});
  s.lt = logOf({{0.0, 0.0, 0.0, 0.6, 0.4}, {0.0, 0.0, 0.0, 0.3, 0.7}, {1, 0, 0, 0, 0}, {1, 0, 0, 0, 0}});
  for (auto& v : s.lt) v = std::max(v, -1e3);
  // Each on its own would split them (R1 to G1, its box to G2); one decision: both to G2
  // (0.4 * 0.7 > 0.6 * 0.3).
  const auto step = s.couple({{2, 3}, {2, 4}, {}, {}});
  EXPECT_EQ(step[0], (DecodedToken{2, 4}));
  EXPECT_EQ(step[1], (DecodedToken{2, 4}));
}

TEST(CarriedLoads, NeverOneWithoutTheOther) {
  LoadScene s;
  s.lt = logOf({{0.05, 0.05, 0.05, 0.8, 0.05}, {0.05, 0.05, 0.05, 0.8, 0.05}, {1, 0, 0, 0, 0}, {1, 0, 0, 0, 0}});
  for (auto& v : s.lt) v = std::max(v, -1e3);
  // The box would be carried while its robot stays: the robot is sure it stays, so the box stays too.
  s.la = logOf({{0.9, 0.05, 0.05}, {0.4, 0.1, 0.5}, {1, 1e-9, 1e-9}, {1, 1e-9, 1e-9}});
  auto step = s.couple({{}, {2, 3}, {}, {}});
  EXPECT_EQ(step[0], DecodedToken{});
  EXPECT_EQ(step[1], DecodedToken{});
  // The robot would carry while its box stays: the box is unsure, so it goes along.
  s.la = logOf({{0.05, 0.05, 0.9}, {0.6, 0.1, 0.3}, {1, 1e-9, 1e-9}, {1, 1e-9, 1e-9}});
  step = s.couple({{2, 3}, {}, {}, {}});
  EXPECT_EQ(step[0], (DecodedToken{2, 3}));
  EXPECT_EQ(step[1], (DecodedToken{2, 3}));
  // A step that keeps the rule (the robot moves without a load action) is left as it is.
  s.la = logOf({{0.05, 0.9, 0.05}, {0.9, 0.05, 0.05}, {1, 1e-9, 1e-9}, {1, 1e-9, 1e-9}});
  step = s.couple({{1, 3}, {}, {}, {}});
  EXPECT_EQ(step[0], (DecodedToken{1, 3}));
  EXPECT_EQ(step[1], DecodedToken{});
}
