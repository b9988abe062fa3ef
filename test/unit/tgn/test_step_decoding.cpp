// The step decoder: each entity's argmax unless that breaks the step rules the training
// demonstrations kept; then the best joint assignment.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "ddace/common/error.h"
#include "ddace/tgn/detail.h"
#include "ddace/tgn/sequence_model.h"

using namespace ddace;
using tgn::StepRules;
using tgn::detail::DecodedToken;
using tgn::detail::decodeStep;

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
