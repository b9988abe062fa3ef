// The training plan (tgn::TrainingPlan): what the demonstrations decide about training,
// computed once (tgn::planTraining), and what each of its rules does to what the network
// sees and decides. The step decoder: one, for predictNext and the accuracy check.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "ddace/common/error.h"
#include "ddace/common/sha256.h"
#include "ddace/task/end_point.h"
#include "ddace/tasks/generators.h"
#include "ddace/tasks/rule_zoo.h"
#include "ddace/tgn/detail.h"
#include "ddace/tgn/sequence_model.h"
#include "model_impl.h"

#include "../common/file_tree.h"
#include "../common/role_tasks.h"

using namespace ddace;
namespace fs = std::filesystem;

namespace {

task::TaskDir generate(const std::string& family, int demos, uint64_t seed = 1) {
  uint64_t rule = 0;
  if (tasks::parseZooFamily(family, rule)) return tasks::generateZoo(rule, demos, seed);
  tasks::GeneratorOptions o;
  o.family = family;
  o.demos = demos;
  o.seed = seed;
  return tasks::generate(o);
}

tgn::TrainingPlan planOf(const task::TaskDir& train, const tgn::TrainOptions& o = {}) {
  return tgn::planTraining(train, o, graph::refine(train.demos, static_cast<int>(train.spec.entities.size())));
}

std::vector<std::vector<std::string>> names(const task::TaskDir& dir, const std::vector<std::vector<int>>& groups) {
  std::vector<std::vector<std::string>> out;
  for (const auto& g : groups) {
    out.emplace_back();
    for (int e : g) out.back().push_back(dir.spec.entities[static_cast<size_t>(e)].name);
  }
  return out;
}

using Groups = std::vector<std::vector<std::string>>;

}  // namespace

// Each family's plan, from its demonstrations alone (no training): the paper's fixed order
// (Task 4), the scene's choices (fetch: a carried box; nearest_goal: one step of exclusive
// targets; queue: one robot per step to named slots), and the paper's network.
TEST(TrainingPlan, IsWhatTheDemonstrationsDecide) {
  const task::TaskDir task4 = generate("task4", 4), fetch = generate("fetch", 6), goals = generate("nearest_goal", 10),
                      queue = generate("queue", 6);
  const tgn::TrainingPlan fixed = planOf(task4);
  EXPECT_TRUE(fixed.fixed_order);
  EXPECT_FALSE(fixed.relative_features);
  EXPECT_TRUE(fixed.identity_embedding);
  EXPECT_TRUE(fixed.name_groups.empty());
  EXPECT_FALSE(fixed.token_by_token || fixed.parked_out_of_ranks);
  EXPECT_EQ(fixed.step_rules.step_size, 2);
  EXPECT_EQ(fixed.ensemble, 1) << "a fixed order is the steps', which any seed learns";

  const tgn::TrainingPlan f = planOf(fetch);
  EXPECT_FALSE(f.fixed_order);
  EXPECT_TRUE(f.relative_features && f.parked_out_of_ranks);
  EXPECT_FALSE(f.token_by_token) << "the fetcher and its box share a target";
  EXPECT_EQ(names(fetch, f.name_groups), (Groups{{"R1", "R2"}}));
  EXPECT_EQ(f.step_rules.load_actions, std::vector<std::string>{"carry"});
  EXPECT_EQ(f.step_rules.step_size, 1) << "a carrier and its load are one decision, not two actors";
  EXPECT_TRUE(f.step_rules.exclusive_targets) << "the load's target is its carrier's";
  // Several loads at once (zoo: each box fetched by its nearest free robot, then carried to
  // the goals): three decisions a step, each target once, decided token by token.
  const tgn::TrainingPlan boxes = planOf(generate("zoo:50", 6));
  EXPECT_EQ(boxes.step_rules.load_actions, std::vector<std::string>{"carry"});
  EXPECT_EQ(boxes.step_rules.step_size, 3);
  EXPECT_TRUE(boxes.step_rules.exclusive_targets && boxes.token_by_token);

  const tgn::TrainingPlan g = planOf(goals);
  EXPECT_TRUE(g.names_or_scene) << "every robot's and goal's role is the scene's";
  EXPECT_TRUE(g.token_by_token);
  EXPECT_TRUE(g.step_rules.exclusive_targets);
  EXPECT_EQ(g.step_rules.step_size, 3);
  EXPECT_EQ(g.ensemble, tgn::kEnsembleMembers);

  const tgn::TrainingPlan q = planOf(queue);
  EXPECT_FALSE(q.token_by_token) << "one token per step";
  EXPECT_EQ(names(queue, q.name_groups), (Groups{{"R1", "R2", "R3"}})) << "the slots keep their names";
  EXPECT_FALSE(q.names_or_scene) << "only its name says which slot is the head of the line";
  EXPECT_FALSE(fixed.names_or_scene);
  EXPECT_FALSE(planOf(generate("zoo:5", 10)).names_or_scene) << "a queue by left-to-right order";

  // The user's --without turns each rule off, and only that one.
  for (tgn::Rule rule : tgn::allRules()) {
    tgn::TrainOptions o;
    o.without = {rule};
    const tgn::TrainingPlan off = planOf(goals, o);
    EXPECT_EQ(off.relative_features, rule != tgn::Rule::Relative) << tgn::toString(rule);
    EXPECT_EQ(off.token_by_token, rule != tgn::Rule::Relative && rule != tgn::Rule::TokenByToken)
        << tgn::toString(rule);
    EXPECT_EQ(off.parked_out_of_ranks, rule != tgn::Rule::Relative && rule != tgn::Rule::Parked) << tgn::toString(rule);
    EXPECT_EQ(off.name_groups.empty(), rule == tgn::Rule::Relative || rule == tgn::Rule::ShuffledNames)
        << tgn::toString(rule);
    EXPECT_EQ(off.ensemble == 1, rule == tgn::Rule::Relative || rule == tgn::Rule::Ensemble) << tgn::toString(rule);
  }
  tgn::TrainOptions keep;
  keep.without = {tgn::Rule::FixedOrder};
  EXPECT_TRUE(planOf(task4, keep).relative_features);
  EXPECT_TRUE(planOf(task4, keep).name_groups.empty()) << "a fixed order's names are what its steps follow";

  tgn::TrainOptions paper;
  paper.variant = tgn::Variant::Paper;
  const tgn::TrainingPlan p = planOf(goals, paper);
  EXPECT_FALSE(p.relative_features || p.token_by_token || p.parked_out_of_ranks || !p.name_groups.empty());
  EXPECT_FALSE(p.step_rules.any()) << "the paper's network decodes each entity on its own";
  EXPECT_EQ(p.attention_edges, graph::refine(goals.demos, 7).kept);
}

TEST(TrainingPlan, RuleNamesAreTheCommandLineOnes) {
  EXPECT_EQ(tgn::rulesFromList("fixed-order,parked"), (std::set<tgn::Rule>{tgn::Rule::FixedOrder, tgn::Rule::Parked}));
  EXPECT_TRUE(tgn::rulesFromList("").empty());
  for (tgn::Rule r : tgn::allRules()) EXPECT_EQ(tgn::ruleFromString(tgn::toString(r)), r);
  try {
    tgn::rulesFromList("parked,nearest");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'nearest' is not a learning rule (relative, fixed-order"), std::string::npos)
        << e.what();
  }
}

// Parked entities: after R? parked on Q1 in queue, the nearest free robot to Q1 is again
// the nearest (rank 1, as at the first step) for the network; without the rule it is the
// 2nd, the parked one counted in.
TEST(ParkedEntities, AParkedRobotIsNoRivalOfTheFreeOnes) {
  const task::TaskDir queue = generate("queue", 4);
  auto impl = tgn::prepare(queue, tgn::TrainOptions{});
  ASSERT_TRUE(impl->info.plan.parked_out_of_ranks);
  impl->build();
  const task::Demonstration d = impl->order.toCanonical(queue.demos.front());
  ASSERT_GE(d.snapshots.size(), 3u);
  const int n = impl->cfg.nodes;
  const int parked = d.steps[0].tokens.at(0).entity, q1 = d.steps[0].tokens.at(0).target;
  const auto& pos = d.snapshots[1].positions;
  int free = -1;
  for (int e = 0; e < n; ++e)
    if (e != parked &&
        queue.spec.entities[static_cast<size_t>(impl->order.task_of[static_cast<size_t>(e)])].kind ==
            task::EntityKind::Robot &&
        (free < 0 || (pos[static_cast<size_t>(e)] - pos[static_cast<size_t>(q1)]).norm() <
                         (pos[static_cast<size_t>(free)] - pos[static_cast<size_t>(q1)]).norm()))
      free = e;
  ASSERT_GE(free, 0);
  const auto rank = [&](bool rule) {
    impl->info.plan.parked_out_of_ranks = rule;
    std::vector<float> rel(static_cast<size_t>(n * n * tgn::kRelativeFeatures));
    const std::vector<std::vector<Eigen::Vector2d>> history = {d.snapshots[0].positions, pos};
    impl->relative(history.data(), history.size(), rel.data());
    return rel[static_cast<size_t>((q1 * n + free) * tgn::kRelativeFeatures + tgn::basis::kNearJ)];
  };
  EXPECT_FLOAT_EQ(rank(true), 1.f);
  EXPECT_FLOAT_EQ(rank(false), 0.5f);
}

// ... but a parked one is ranked among every one of its kind: "each box fetched by its
// nearest free robot, then carried to the goals in back-to-front order" (zoo:50). As the
// carrying step begins every box is parked with its carrier; ranked among the free boxes
// only (none), each was the backmost, and the network could not tell which box goes to
// which goal (OSR 0.47 / 0.53 at 20 demonstrations, data seeds 1-2; 0.97 / 1.00 now).
// The k-th box from the back (i's order from the back) goes to the k-th goal from the back
// (j's).
TEST(ParkedEntities, AParkedOneIsRankedAmongEveryOneOfItsKind) {
  const task::TaskDir boxes = generate("zoo:50", 10);
  auto impl = tgn::prepare(boxes, tgn::TrainOptions{});
  ASSERT_TRUE(impl->info.plan.parked_out_of_ranks);
  impl->build();
  const int n = impl->cfg.nodes;
  const auto kind = [&](int c) {
    return boxes.spec.entities[static_cast<size_t>(impl->order.task_of[static_cast<size_t>(c)])].kind;
  };
  int carried = 0;
  for (const auto& demo : boxes.demos) {
    const task::Demonstration d = impl->order.toCanonical(demo);
    ASSERT_EQ(d.steps.size(), 2u);
    const std::vector<std::vector<Eigen::Vector2d>> history = {d.snapshots[0].positions, d.snapshots[1].positions};
    std::vector<float> rel(static_cast<size_t>(n * n * tgn::kRelativeFeatures));
    impl->relative(history.data(), history.size(), rel.data());
    for (const auto& t : d.steps[1].tokens) {
      if (kind(t.entity) != task::EntityKind::Object) continue;
      ++carried;
      for (int j = 0; j < n; ++j)
        if (kind(j) == task::EntityKind::Goal) {
          const float* r = &rel[static_cast<size_t>((t.entity * n + j) * tgn::kRelativeFeatures)];
          EXPECT_EQ(r[tgn::basis::kAxisI + 3] == r[tgn::basis::kAxisJ + 3], j == t.target)
              << "box " << t.entity << ", goal " << j;
        }
    }
  }
  EXPECT_EQ(carried, 30) << "three boxes carried in each of 10 demonstrations";
}

// Each one's last move: in a relay ("... hands it to the teammate nearest to it, who carries
// it to the goal ..., then the giver follows the receiver"), as the last step begins the
// giver's last move (the handover, two steps back) went to the receiver, which the last
// step's relation (the receiver carried the box on) no longer says.
TEST(RelationalBasis, RemembersEachOnesLastMove) {
  const task::TaskDir relay = generate("zoo:16", 2);
  auto impl = tgn::prepare(relay, tgn::TrainOptions{});
  impl->build();
  const task::Demonstration d = impl->order.toCanonical(relay.demos.front());
  ASSERT_EQ(d.steps.size(), 4u);
  // Step 2: the giver carries the box to the receiver; step 4: the giver moves to it.
  const task::Token* handover = nullptr;
  for (const auto& t : d.steps[1].tokens)
    if (relay.spec.entities[static_cast<size_t>(impl->order.task_of[static_cast<size_t>(t.entity)])].kind ==
        task::EntityKind::Robot)
      handover = &t;
  ASSERT_NE(handover, nullptr);
  const int giver = handover->entity, receiver = handover->target, n = impl->cfg.nodes;
  ASSERT_EQ(d.steps[3].tokens, (std::vector<task::Token>{{giver, "move", receiver}}));
  std::vector<std::vector<Eigen::Vector2d>> history;
  for (size_t k = 0; k <= 3; ++k) history.push_back(d.snapshots[k].positions);
  std::vector<float> rel(static_cast<size_t>(n * n * tgn::kRelativeFeatures));
  impl->relative(history.data(), history.size(), rel.data());
  const auto feature = [&](int i, int j, int f) {
    return rel[static_cast<size_t>((i * n + j) * tgn::kRelativeFeatures + f)];
  };
  EXPECT_FLOAT_EQ(feature(giver, receiver, tgn::basis::kWentTo), 0.f) << "the giver did not move in the last step";
  EXPECT_FLOAT_EQ(feature(giver, receiver, tgn::basis::kLastMoveTo), 1.f) << "its last move went to the receiver";
  EXPECT_FLOAT_EQ(feature(receiver, giver, tgn::basis::kLastMoveFrom), 1.f) << "seen from the receiver";
  for (int j = 0; j < n; ++j)
    if (j != receiver) {
      EXPECT_FLOAT_EQ(feature(giver, j, tgn::basis::kLastMoveTo), 0.f) << "one entity per last move";
    }
}

// A move went to the entity it stopped where a motion toward it ends (at contact with a
// robot, on a goal), not the nearest: in a line-up the second robot joins the head, which
// stands on G1, and stops a contact from both; by nearness its move "went to" G1 in some
// scenes (a millimetre's coincidence), as the head's had, and a model trained with three
// robots then sent a fourth to the head.
TEST(RelationalBasis, AMoveWentToWhatItStoppedAtNotTheNearest) {
  const task::TaskDir line = test::lineUp(10, 1, 4);
  auto impl = tgn::prepare(line, tgn::TrainOptions{});
  impl->build();
  const int n = impl->cfg.nodes;
  for (const task::Demonstration& demo : line.demos) {
    const task::Demonstration d = impl->order.toCanonical(demo);
    ASSERT_EQ(d.steps.size(), 4u) << demo.source;
    std::vector<std::vector<Eigen::Vector2d>> history;
    for (size_t k = 0; k < d.snapshots.size(); ++k) history.push_back(d.snapshots[k].positions);
    // After step k (k = 1..3) its mover joined the robot of step k - 1: the last step's, and
    // each one's last move, went to the robot it joined, the head's to G1.
    for (size_t k = 1; k < 4; ++k) {
      std::vector<float> rel(static_cast<size_t>(n * n * tgn::kRelativeFeatures));
      impl->relative(history.data(), k + 2, rel.data());
      const auto feature = [&](int i, int j, int f) {
        return rel[static_cast<size_t>((i * n + j) * tgn::kRelativeFeatures + f)];
      };
      for (size_t s = 0; s <= k; ++s) {
        const task::Token& t = d.steps[s].tokens.at(0);
        for (int j = 0; j < n; ++j) {
          const float expected = j == t.target ? 1.f : 0.f;
          EXPECT_EQ(feature(t.entity, j, tgn::basis::kLastMoveTo), expected)
              << demo.source << " after step " << k + 1 << ": the last move of step " << s + 1;
          if (s == k) {
            EXPECT_EQ(feature(t.entity, j, tgn::basis::kWentTo), expected)
                << demo.source << " step " << k + 1 << ": went to the one it joined only";
          }
        }
      }
    }
  }
}

// Entities at one place are seen from one place: "the robot nearest B1 fetches it and
// hands it to the teammate nearest to it" (zoo:87). At the handover the giver stands a
// contact (4.2 cm) behind the box; in this scene (a fresh one the relay failed on) R3 is the
// giver's nearest teammate by 6.7 cm, but from the box's own place R1 is 4 mm nearer. Seen
// from their one place, R3 is the nearest robot to both, and every distance is the same
// (the distance, and j's nearness rank among its kind seen from i).
TEST(RelationalBasis, SeesEntitiesAtOnePlaceFromOnePlace) {
  const task::TaskDir relay = generate("zoo:87", 10);
  auto impl = tgn::prepare(relay, tgn::TrainOptions{});
  impl->build();
  const int n = impl->cfg.nodes;
  const auto at = [&](const std::map<std::string, Eigen::Vector2d>& where) {
    std::vector<Eigen::Vector2d> pos(static_cast<size_t>(n));
    for (int c = 0; c < n; ++c)
      pos[static_cast<size_t>(c)] =
          where.at(relay.spec.entities[static_cast<size_t>(impl->order.task_of[static_cast<size_t>(c)])].name);
    return pos;
  };
  const std::vector<std::vector<Eigen::Vector2d>> history = {at({{"R1", {0.11, 0.14}},
                                                                 {"R2", {0.52, 0.42}},
                                                                 {"R3", {0.75, 0.32}},
                                                                 {"R4", {0.89, 0.65}},
                                                                 {"B1", {0.41, 0.30}},
                                                                 {"G1", {0.84, 0.08}}}),
                                                             at({{"R1", {0.11, 0.14}},
                                                                 {"R2", {0.44, 0.33}},
                                                                 {"R3", {0.75, 0.32}},
                                                                 {"R4", {0.89, 0.65}},
                                                                 {"B1", {0.41, 0.30}},
                                                                 {"G1", {0.84, 0.08}}})};
  std::vector<float> rel(static_cast<size_t>(n * n * tgn::kRelativeFeatures));
  impl->relative(history.data(), history.size(), rel.data());
  const auto canonical = [&](const std::string& name) {
    for (int c = 0; c < n; ++c)
      if (relay.spec.entities[static_cast<size_t>(impl->order.task_of[static_cast<size_t>(c)])].name == name) return c;
    return -1;
  };
  const int giver = canonical("R2"), box = canonical("B1"), receiver = canonical("R3");
  const auto feature = [&](int i, int j, int f) {
    return rel[static_cast<size_t>((i * n + j) * tgn::kRelativeFeatures + f)];
  };
  EXPECT_FLOAT_EQ(feature(giver, receiver, tgn::basis::kNearJ), 1.f) << "the receiver, seen from the giver";
  EXPECT_FLOAT_EQ(feature(box, receiver, tgn::basis::kNearJ), 1.f) << "the receiver, seen from the box";
  for (int j = 0; j < n; ++j)
    if (j != giver && j != box) {
      EXPECT_FLOAT_EQ(feature(giver, j, tgn::basis::kDistance), feature(box, j, tgn::basis::kDistance))
          << "distance to " << j;
    }
}

// Orders along the table's axes are strict but for entities at one place: "robots take
// goals in left-to-right order" pairs the k-th robot from the left (i's order from the
// left) with the k-th goal from the left (j's), also where two robots or two
// goals are nearer in x than contact plus the arrival radius (the end-point rule's distance
// of "at one place"), which the basis once counted as tied.
TEST(RelationalBasis, OrdersAlongTheAxesTellApartEntitiesSideBySide) {
  const task::TaskDir l2r = generate("zoo:left-to-right", 20);
  auto impl = tgn::prepare(l2r, tgn::TrainOptions{});
  impl->build();
  const int n = impl->cfg.nodes;
  const auto kind = [&](int c) {
    return l2r.spec.entities[static_cast<size_t>(impl->order.task_of[static_cast<size_t>(c)])].kind;
  };
  int side_by_side = 0;
  for (const auto& demo : l2r.demos) {
    const task::Demonstration d = impl->order.toCanonical(demo);
    ASSERT_EQ(d.steps.size(), 1u);
    const auto& pos = d.snapshots[0].positions;
    for (int a = 0; a < n; ++a)
      for (int b = a + 1; b < n; ++b)
        side_by_side +=
            kind(a) == kind(b) && std::abs(pos[static_cast<size_t>(a)].x() - pos[static_cast<size_t>(b)].x()) <
                                      task::togetherDistance(l2r.spec, impl->order.task_of[static_cast<size_t>(a)],
                                                             impl->order.task_of[static_cast<size_t>(b)]);
    std::vector<float> rel(static_cast<size_t>(n * n * tgn::kRelativeFeatures));
    impl->relative(&d.snapshots[0].positions, 1, rel.data());
    for (const auto& t : d.steps[0].tokens)
      for (int j = 0; j < n; ++j)
        if (kind(j) == task::EntityKind::Goal) {
          const float* r = &rel[static_cast<size_t>((t.entity * n + j) * tgn::kRelativeFeatures)];
          EXPECT_EQ(r[tgn::basis::kAxisI] == r[tgn::basis::kAxisJ], j == t.target)
              << "robot " << t.entity << ", goal " << j;
        }
  }
  EXPECT_GT(side_by_side, 0) << "no scene puts two of a kind side by side: the test would not tell";
}

// The nearness ranks are counts of rivals (docs/tgn.md, "Relational basis"): for the pair
// (i, j), how many of j's rivals lie nearer to i than j (farther), and of i's nearer to j
// than i; a rival of e is of e's kind, competing (token by token: not given its part yet)
// and free unless e is parked. Counted here one entity at a time for every pair, in
// scenes with parked boxes and with some entities given their part, against the features
// token by token computes from one sort per entity (and for some rows only).
TEST(RelationalBasis, NearnessRanksCountTheRivalsOfEachPair) {
  const task::TaskDir boxes = generate("zoo:50", 6);
  auto impl = tgn::prepare(boxes, tgn::TrainOptions{});
  ASSERT_TRUE(impl->info.plan.parked_out_of_ranks);
  impl->build();
  const int n = impl->cfg.nodes, f = tgn::kRelativeFeatures;
  const auto kind = [&](int c) {
    return boxes.spec.entities[static_cast<size_t>(impl->order.task_of[static_cast<size_t>(c)])].kind;
  };
  int parked_seen = 0, checked = 0;
  for (const auto& demo : boxes.demos) {
    const task::Demonstration d = impl->order.toCanonical(demo);
    for (size_t s = 0; s < d.snapshots.size(); ++s) {
      std::vector<std::vector<Eigen::Vector2d>> history;
      for (size_t k = 0; k <= s; ++k) history.push_back(d.snapshots[k].positions);
      const tgn::PairRelations relations(*impl, history.data(), history.size());
      for (int out_every = 0; out_every < 3; ++out_every) {  // none out, then every 2nd or 3rd entity given
        std::vector<bool> competing(static_cast<size_t>(n), true);
        for (int e = 0; out_every > 0 && e < n; e += out_every + 1) competing[static_cast<size_t>(e)] = false;
        std::vector<float> rel(static_cast<size_t>(n * n * f));
        relations.write(rel.data(), &competing);
        const auto at = [&](int i, int j, int feature) { return rel[static_cast<size_t>((i * n + j) * f + feature)]; };
        std::vector<bool> parked(static_cast<size_t>(n), false);
        for (int e = 0; e < n; ++e)
          for (int m = 0; m < n; ++m)
            if (m != e && at(e, m, tgn::basis::kDistance) == 0.f) parked[static_cast<size_t>(e)] = true;
        parked_seen += static_cast<int>(std::count(parked.begin(), parked.end(), true));
        const auto rival = [&](int k, int e) {
          return competing[static_cast<size_t>(k)] && kind(k) == kind(e) &&
                 (parked[static_cast<size_t>(e)] || !parked[static_cast<size_t>(k)]);
        };
        for (int i = 0; i < n; ++i)
          for (int j = 0; j < n; ++j) {
            if (i == j) continue;
            const float dij = at(i, j, tgn::basis::kDistance);
            int near_j = 0, far_j = 0, near_i = 0, far_i = 0;
            for (int k = 0; k < n; ++k) {
              if (k == i || k == j) continue;
              near_j += rival(k, j) && at(i, k, tgn::basis::kDistance) < dij;
              far_j += rival(k, j) && at(i, k, tgn::basis::kDistance) > dij;
              near_i += rival(k, i) && at(j, k, tgn::basis::kDistance) < dij;
              far_i += rival(k, i) && at(j, k, tgn::basis::kDistance) > dij;
            }
            EXPECT_FLOAT_EQ(at(i, j, tgn::basis::kNearJ), 1.f / static_cast<float>(1 + near_j)) << i << ", " << j;
            EXPECT_FLOAT_EQ(at(i, j, tgn::basis::kFarJ), 1.f / static_cast<float>(1 + far_j)) << i << ", " << j;
            EXPECT_FLOAT_EQ(at(i, j, tgn::basis::kNearI), 1.f / static_cast<float>(1 + near_i)) << i << ", " << j;
            EXPECT_FLOAT_EQ(at(i, j, tgn::basis::kFarI), 1.f / static_cast<float>(1 + far_i)) << i << ", " << j;
            ++checked;
          }
        // Some rows only: the same features, those rows' alone.
        const std::vector<int64_t> rows = {1, 3, static_cast<int64_t>(n - 1)};
        std::vector<float> some(rows.size() * static_cast<size_t>(n * f));
        relations.write(some.data(), &competing, &rows);
        for (size_t q = 0; q < rows.size(); ++q)
          EXPECT_TRUE(std::equal(some.begin() + static_cast<std::ptrdiff_t>(q * n * f),
                                 some.begin() + static_cast<std::ptrdiff_t>((q + 1) * n * f),
                                 rel.begin() + static_cast<std::ptrdiff_t>(rows[q] * n * f)))
              << "row " << rows[q];
      }
    }
  }
  EXPECT_GT(parked_seen, 0) << "no parked entity: the test would not tell";
  EXPECT_GT(checked, 1000);
}

// Token by token asks the pointer again after every token for the rows still to be
// decided only: their logits are those of the whole heads.
TEST(TokenByToken, ThePointersRowsAreThoseOfTheWholeHeads) {
  const task::TaskDir goals = generate("zoo:nearest-goals", 2);
  auto impl = tgn::prepare(goals, tgn::TrainOptions{});
  impl->build();
  torch::NoGradGuard no_grad;
  tgn::SceneNetwork net = impl->members().front();
  net->eval();
  const int64_t n = impl->cfg.nodes;
  torch::manual_seed(5);
  const torch::Tensor nodes = torch::randn({n, net->act_h->weight.size(1)});
  const torch::Tensor z = torch::randn({net->ptr_z->weight.size(1)});
  const torch::Tensor rel = torch::rand({n, n, tgn::kRelativeFeatures});
  const auto parts = net->pointerParts(nodes, z, net->hiddenOf(nodes, z));
  const torch::Tensor whole = net->pointerLogits(parts, rel);
  const torch::Tensor rows = torch::tensor(std::vector<int64_t>{0, 2, n - 1}, torch::kLong);
  const torch::Tensor some = net->pointerLogits(parts, rel.index_select(0, rows), rows);
  ASSERT_EQ(some.sizes(), torch::IntArrayRef({3, n + 1}));
  EXPECT_LT((some - whole.index_select(0, rows)).abs().max().item<double>(), 1e-5);
  EXPECT_THROW(net->pointerLogits(parts, rel, rows), Error) << "the features of every row for three rows";
}

// Demonstrated tokens: whatever the heads say, in a decided step an entity takes only
// actions its kind took in the training demonstrations and points only at kinds of
// target its kind pointed at. A network stopped after one epoch decides nearly at random;
// the decoder still never lets a goal act nor a box act on its own, a box move, or a robot
// point at a robot.
TEST(DemonstratedTokens, AreTheOnlyTokensADecidedStepHolds) {
  tgn::TrainOptions o;
  o.max_epochs = 1;
  o.without = {tgn::Rule::Ensemble};
  const task::TaskDir train = generate("zoo:two-boxes", 6);
  const tgn::SequenceModel m = tgn::SequenceModel::train(train, o, nullptr);
  ASSERT_EQ(m.info().fingerprint.token_types,
            (std::vector<std::string>{"object:carry:goal", "robot:carry:goal", "robot:move:object"}));
  const std::set<std::string> actions = {"object:carry", "robot:carry", "robot:move"};
  const std::set<std::string> targets = {"object:goal", "robot:goal", "robot:object"};
  const task::TaskDir test = generate("zoo:two-boxes", 12, 5);
  const auto kind = [&](int e) {
    return std::string(task::toString(test.spec.entities.at(static_cast<size_t>(e)).kind));
  };
  int tokens = 0;
  for (const auto& d : test.demos)
    for (size_t k = 1; k <= d.snapshots.size(); ++k) {
      const auto p = m.predictNext({d.snapshots.begin(), d.snapshots.begin() + static_cast<long>(k)});
      for (const auto& t : p.tokens) {
        ++tokens;
        EXPECT_TRUE(actions.count(kind(t.entity) + ":" + t.action)) << kind(t.entity) << " " << t.action;
        ASSERT_TRUE(t.isMotion());
        EXPECT_TRUE(targets.count(kind(t.entity) + ":" + kind(t.target))) << kind(t.entity) << " to " << kind(t.target);
        if (kind(t.entity) != "object") continue;
        // never on its own: a robot takes the same token (its carrier)
        const bool carried = std::any_of(p.tokens.begin(), p.tokens.end(), [&](const task::Token& c) {
          return kind(c.entity) == "robot" && c.action == t.action && c.target == t.target;
        });
        EXPECT_TRUE(carried) << "box " << t.entity << " " << t.action << " alone";
      }
    }
  EXPECT_GT(tokens, 20);
}

// One decoder: the step accuracy training prints and stepAccuracy returns is the fraction of
// steps (and END) predictNext decides exactly from the true history, on rules where the
// decoder does more than each entity's argmax: token by token (nearest_goal), carried
// loads (fetch), a fixed step size (queue).
TEST(OneDecoder, StepAccuracyIsThatOfPredictNext) {
  for (const char* family : {"nearest_goal", "fetch", "queue"}) {
    tgn::TrainOptions o;
    o.max_epochs = 12;  // short of the demonstrations: some steps wrong
    const task::TaskDir train = generate(family, 6);
    const tgn::SequenceModel m = tgn::SequenceModel::train(train, o, nullptr);
    const task::TaskDir test = generate(family, 6, 9);
    int right = 0, steps = 0;
    for (const auto& d : test.demos)
      for (size_t k = 1; k <= d.snapshots.size(); ++k) {
        const auto p = m.predictNext({d.snapshots.begin(), d.snapshots.begin() + static_cast<long>(k)});
        const bool end = k == d.snapshots.size();
        right += p.end == end && (end || p.tokens == d.steps[k - 1].tokens);
        ++steps;
      }
    EXPECT_DOUBLE_EQ(m.stepAccuracy(test.demos), static_cast<double>(right) / steps) << family;
  }
}

namespace {

/// Replaces `from` by `to` in the saved model's manifest and seals it again (as an edit by
/// hand whose author recomputed the hash). False when `from` is not there.
bool editManifest(const std::string& dir, const std::string& from, const std::string& to) {
  std::string s = test::fileBytes(fs::path(dir) / "manifest.yaml");
  const size_t at = s.find(from);
  if (at == std::string::npos) return false;
  s.replace(at, from.size(), to);
  s = s.substr(0, s.rfind("\nmanifest_sha256: ") + 1);
  s += "manifest_sha256: " + sha256Hex(s) + "\n";
  test::writeBytes(fs::path(dir) / "manifest.yaml", s);
  return true;
}

}  // namespace

// Token by token is the plan's: the same weights loaded with the rule recorded off decide
// a step's targets all at once, and a token's probability is then its pointer's, not the
// one of the target chosen after the others.
TEST(TokenByToken, IsHowThePlanSaysAStepIsDecoded) {
  tgn::TrainOptions o;
  o.max_epochs = 8;
  const task::TaskDir goals = generate("nearest_goal", 4);
  const tgn::SequenceModel m = tgn::SequenceModel::train(goals, o, nullptr);
  ASSERT_TRUE(m.info().plan.token_by_token);
  const std::string dir = (fs::temp_directory_path() / ("ddace_test_plan_" + std::to_string(::getpid()))).string();
  m.save(dir);
  ASSERT_TRUE(editManifest(dir, "token_by_token: true", "token_by_token: false"));
  const tgn::SequenceModel at_once = tgn::SequenceModel::load(dir);
  fs::remove_all(dir);
  ASSERT_FALSE(at_once.info().plan.token_by_token);
  const std::vector<task::Snapshot> first(goals.demos.front().snapshots.begin(),
                                          goals.demos.front().snapshots.begin() + 1);
  const tgn::Prediction p = m.predictNext(first), q = at_once.predictNext(first);
  ASSERT_GE(p.tokens.size(), 2u);
  ASSERT_EQ(p.tokens.size(), q.tokens.size());
  EXPECT_NE(p.token_probabilities, q.token_probabilities);
}

// A manifest is another process's file: a plan no training makes (the scene network's
// token-by-token decoding on the paper's network, which has no scene to decode with) is
// refused by name when the model is loaded, never run.
TEST(TrainingPlan, AManifestWithAPlanNoTrainingMakesIsRefused) {
  tgn::TrainOptions o;
  o.variant = tgn::Variant::Paper;
  o.max_epochs = 2;
  const tgn::SequenceModel m = tgn::SequenceModel::train(generate("nearest_goal", 3), o, nullptr);
  ASSERT_FALSE(m.info().plan.token_by_token);
  const std::string dir = (fs::temp_directory_path() / ("ddace_test_plan_bad_" + std::to_string(::getpid()))).string();
  m.save(dir);
  ASSERT_TRUE(editManifest(dir, "token_by_token: false", "token_by_token: true"));
  try {
    tgn::SequenceModel::load(dir);
    ADD_FAILURE() << "loaded a paper model that decodes token by token";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("plan: rules of the scene network for the paper variant"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("manifest.yaml"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

// Names or the scene, gated: a queue filled in left-to-right order (zoo:5) from 20
// demonstrations. Only a slot's name says which slot is the head; the network without the
// identity embedding fitted the training scenes by their coincidences and was kept, and
// sent the leftmost robot to Q2 or Q3 in every fresh scene (OSR 0.00). The plan keeps the
// names: every step of at least 8 of 10 fresh scenes decided as the rule says.
TEST(NamesOrTheScene, KeepsTheNamesWhereANameAloneTellsARole) {
  const task::TaskDir train = generate("zoo:5", 20), test = generate("zoo:5", 10, 77);
  const tgn::SequenceModel m = tgn::SequenceModel::train(train, tgn::TrainOptions{}, nullptr);
  EXPECT_FALSE(m.info().plan.names_or_scene);
  EXPECT_TRUE(m.info().plan.identity_embedding);
  int right = 0;
  for (const auto& d : test.demos) {
    bool all = true;
    for (size_t k = 1; k <= d.snapshots.size() && all; ++k) {
      const auto p = m.predictNext({d.snapshots.begin(), d.snapshots.begin() + static_cast<long>(k)});
      all = p.end == (k == d.snapshots.size()) && (p.end || p.tokens == d.steps[k - 1].tokens);
    }
    right += all;
  }
  EXPECT_GE(right, 8);
}

// Labelling slips: Task 4 with one of ten demonstrations mislabelled is still a fixed order,
// and the network decides the common steps in fresh scenes (it used to be trained as a
// scene-dependent task and fall to OSR 0).
TEST(LabellingSlips, LeaveTheCommonStepsDecided) {
  tasks::GeneratorOptions g;
  g.family = "task4";
  g.demos = 10;
  g.mislabel_fraction = 0.1;
  const task::TaskDir train = tasks::generate(g);
  const tgn::SequenceModel m = tgn::SequenceModel::train(train, tgn::TrainOptions{}, nullptr);
  ASSERT_TRUE(m.info().plan.fixed_order);
  ASSERT_GT(m.info().plan.slips, 0);
  const task::TaskDir test = generate("task4", 5, 7);
  for (const auto& d : test.demos)
    for (size_t k = 1; k <= d.snapshots.size(); ++k) {
      const auto p = m.predictNext({d.snapshots.begin(), d.snapshots.begin() + static_cast<long>(k)});
      EXPECT_EQ(p.end, k == d.snapshots.size()) << d.source << " step " << k;
      if (!p.end && k <= d.steps.size()) {
        EXPECT_EQ(p.tokens, d.steps[k - 1].tokens) << d.source << " step " << k;
      }
    }
}

// Together is the end-point rule's (task::togetherDistance): a fetcher that stopped where
// the path follower stops (the stop radius short of contact with its box, 6.6 cm from the
// box's centre where the demonstrations show 4.2 cm) is at the box, so the next step is
// still the carrier and its load together. With "together" at two arrival radii (6 cm) the
// network saw a robot apart from the box and sent it to the box again (closed-loop OSR 0).
TEST(CarriedLoads, ACarrierStoppedWhereTheFollowerStopsStillCarries) {
  const task::TaskDir train = generate("fetch", 10), test = generate("fetch", 5, 9);
  const tgn::SequenceModel m = tgn::SequenceModel::train(train, tgn::TrainOptions{}, nullptr);
  const double stop = task::stopRadius(train.spec.arrival_radius, 3 * 0.002);
  int checked = 0;
  for (const auto& d : test.demos) {
    ASSERT_GE(d.steps.size(), 2u);
    const task::Token fetcher = d.steps[0].tokens.at(0);  // R?:move:B1
    std::vector<task::Snapshot> history(d.snapshots.begin(), d.snapshots.begin() + 2);
    auto& at = history[1].positions;
    const Eigen::Vector2d box = at[static_cast<size_t>(fetcher.target)];
    Eigen::Vector2d& robot = at[static_cast<size_t>(fetcher.entity)];
    ASSERT_LT((robot - box).norm(), 0.05) << d.source << ": the demonstration stops at contact";
    robot = box + (robot - box).normalized() * ((robot - box).norm() + stop);
    const auto p = m.predictNext(history);
    EXPECT_EQ(p.tokens, d.steps[1].tokens) << d.source << ": the carrier " << (robot - box).norm() << " m from its box";
    ++checked;
  }
  EXPECT_EQ(checked, 5);
}

// Two pairs fetched side by side: a carrier standing beside the other pair's box (within
// "together" of it, nearer its own) carries only its own. Before a robot stood at the place
// of every box within reach, so the demonstrations seemed to show a carrier taking a load
// action without the box at its place (no carried loads: decoded entity by entity, the
// lab's two pairs of 4 robots at OSR 0.37), and a decoded box took the first carrier's
// token at its place, going where the other pair went.
namespace {

/// Moves the pair of the higher-indexed carrier of `step` (tokens of two carriers with their
/// loads) behind the other carrier, its box 1.5 cm from that carrier's body: within
/// "together" of both carriers, nearer its own. Returns {first carrier, its load, second
/// carrier, its load}.
std::array<int, 4> pairsSideBySide(const task::TaskSpec& spec, const task::Step& step,
                                   std::vector<Eigen::Vector2d>& at) {
  std::map<int, int> load_of;  // carrier -> load (same action and target)
  for (const task::Token& c : step.tokens)
    for (const task::Token& o : step.tokens)
      if (spec.entities[static_cast<size_t>(o.entity)].kind == task::EntityKind::Object &&
          spec.entities[static_cast<size_t>(c.entity)].kind != task::EntityKind::Object && c.action == o.action &&
          c.target == o.target)
        load_of[c.entity] = o.entity;
  EXPECT_EQ(load_of.size(), 2u);
  const int c1 = load_of.begin()->first, o1 = load_of.begin()->second;
  const int c2 = std::next(load_of.begin())->first, o2 = std::next(load_of.begin())->second;
  const double contact = spec.contactDistance(c1, o1);
  const Eigen::Vector2d away = (at[static_cast<size_t>(c1)] - at[static_cast<size_t>(o1)]).normalized();
  at[static_cast<size_t>(o2)] = at[static_cast<size_t>(c1)] + away * (contact + 0.015);
  at[static_cast<size_t>(c2)] = at[static_cast<size_t>(o2)] + away * contact;
  return {c1, o1, c2, o2};
}

}  // namespace

TEST(CarriedLoads, ACarrierBesideAnotherPairsBoxCarriesOnlyItsOwn) {
  // The rule: each robot is a carrier of the nearest object at its place only.
  task::TaskDir train = generate("zoo:two-pairs", 20);
  const task::TaskSpec& spec = train.spec;
  ASSERT_FALSE(planOf(train).step_rules.load_actions.empty()) << "the zoo's pairs stand apart";
  for (size_t d = 0; d < train.demos.size(); d += 4) {
    task::Demonstration& demo = train.demos[d];
    ASSERT_EQ(demo.steps.size(), 2u) << demo.source;
    const auto [c1, o1, c2, o2] = pairsSideBySide(spec, demo.steps[1], demo.snapshots[1].positions);
    const std::vector<int> identity = {0, 1, 2, 3, 4, 5};
    ASSERT_EQ(spec.entities.size(), identity.size());
    for (const tgn::detail::Load& load : tgn::detail::loadsAt(spec, identity, demo.snapshots[1].positions)) {
      std::vector<int> robots;
      for (int c : load.carriers)
        if (spec.entities[static_cast<size_t>(c)].kind == task::EntityKind::Robot) robots.push_back(c);
      EXPECT_EQ(robots, std::vector<int>{load.object == o1 ? c1 : c2}) << demo.source;
    }
  }
  // The demonstrations still show every load carried: one decision each.
  EXPECT_EQ(planOf(train).step_rules.load_actions, std::vector<std::string>{"carry"});

  // Decided: each box goes where its own carrier goes.
  const task::TaskDir fresh = generate("zoo:two-pairs", 20), test = generate("zoo:two-pairs", 10, 5);
  const tgn::SequenceModel m = tgn::SequenceModel::train(fresh, tgn::TrainOptions{}, nullptr);
  int carried = 0;
  for (const task::Demonstration& d : test.demos) {
    std::vector<task::Snapshot> history(d.snapshots.begin(), d.snapshots.begin() + 2);
    const auto [c1, o1, c2, o2] = pairsSideBySide(spec, d.steps[1], history[1].positions);
    const tgn::Prediction p = m.predictNext(history);
    ASSERT_FALSE(p.end) << d.source;
    const auto tokenOf = [&](int e) {
      for (const task::Token& t : p.tokens)
        if (t.entity == e) return t;
      return task::Token{e, "", -1};
    };
    for (const auto& [c, o] : {std::pair{c1, o1}, std::pair{c2, o2}}) {
      if (tokenOf(o).action.empty()) continue;
      EXPECT_EQ(tokenOf(o).target, tokenOf(c).target) << d.source << ": " << spec.entities[static_cast<size_t>(o)].name;
      EXPECT_EQ(tokenOf(o).action, tokenOf(c).action) << d.source << ": " << spec.entities[static_cast<size_t>(o)].name;
      ++carried;
    }
  }
  EXPECT_GE(carried, 10);
}

// Ensemble: three networks trained alike from three seeds (the first the model's own,
// trained to the bit as alone) each decode a step, and the majority decides. On fresh
// scenes of queue from 4 demonstrations (networks that fit their demonstrations exactly
// and still generalise differently), every step the ensemble takes is the majority of the
// three networks trained alone, and somewhere the first network is outvoted. Which steps
// the networks disagree on depends on the CPU's floating-point kernels, so the data sets
// are searched (data seeds 4..11) until the first network is outvoted (on the first, on
// each kind of CPU tried).
TEST(Ensemble, TheMajorityOfSeedsDecides) {
  const auto same = [](const tgn::Prediction& a, const tgn::Prediction& b) {
    return a.end == b.end && a.tokens == b.tokens;
  };
  bool outvoted = false;
  int decided = 0;
  for (uint64_t data_seed = 4; data_seed < 12 && !outvoted; ++data_seed) {
    const task::TaskDir train = generate("queue", 4, data_seed),
                        test = generate("queue", 15, data_seed * 2654435761ULL + 0x7e57);
    const tgn::SequenceModel three = tgn::SequenceModel::train(train, tgn::TrainOptions{}, nullptr);
    ASSERT_EQ(three.info().plan.ensemble, tgn::kEnsembleMembers);
    std::vector<tgn::SequenceModel> alone;
    for (int k = 0; k < tgn::kEnsembleMembers; ++k) {
      tgn::TrainOptions o;
      o.without = {tgn::Rule::Ensemble};
      o.seed = tgn::memberSeed(1, k);
      alone.push_back(tgn::SequenceModel::train(train, o, nullptr));
      ASSERT_EQ(alone.back().info().plan.ensemble, 1);
      // The member trained as the ensemble's (the same plan: no fit guard chose otherwise).
      ASSERT_EQ(alone.back().info().plan.identity_embedding, three.info().plan.identity_embedding);
      ASSERT_EQ(alone.back().info().plan.name_groups, three.info().plan.name_groups);
    }
    EXPECT_EQ(alone[0].info().history.size(), three.info().history.size()) << "the first network is the one alone";
    for (const task::Demonstration& d : test.demos)
      for (size_t k = 1; k < d.snapshots.size(); ++k) {
        const std::vector<task::Snapshot> history(d.snapshots.begin(), d.snapshots.begin() + static_cast<long>(k));
        std::vector<tgn::Prediction> votes;
        for (const tgn::SequenceModel& m : alone) votes.push_back(m.predictNext(history));
        // The majority: a decision more than half the networks took; else the first's.
        tgn::Prediction majority = votes[0];
        for (const tgn::Prediction& v : votes)
          if (2 * std::count_if(votes.begin(), votes.end(), [&](const tgn::Prediction& o) { return same(o, v); }) >
              static_cast<long>(votes.size()))
            majority = v;
        const tgn::Prediction p = three.predictNext(history);
        EXPECT_TRUE(same(p, majority)) << d.source << " snapshot " << k;
        outvoted = outvoted || !same(p, votes[0]);
        ++decided;
      }
    if (outvoted) {
      // Saved and loaded: every network, the same decisions.
      const std::string dir =
          (fs::temp_directory_path() / ("ddace_test_ensemble_" + std::to_string(::getpid()))).string();
      three.save(dir);
      const tgn::SequenceModel loaded = tgn::SequenceModel::load(dir);
      fs::remove_all(dir);
      EXPECT_EQ(loaded.info().plan.ensemble, tgn::kEnsembleMembers);
      EXPECT_DOUBLE_EQ(loaded.stepAccuracy(test.demos), three.stepAccuracy(test.demos));
    }
  }
  EXPECT_TRUE(outvoted) << "in " << decided << " steps of queue's fresh scenes (data seeds 4..11) the first network "
                        << "was never outvoted";
}

// A manifest edited to another number of networks than training made (and weights.pt
// holds) is refused by name, never decided with some of the networks silently.
TEST(Ensemble, AManifestWithAnotherNumberOfNetworksIsRefused) {
  tgn::TrainOptions o;
  o.max_epochs = 3;
  const tgn::SequenceModel m = tgn::SequenceModel::train(generate("nearest_goal", 4), o, nullptr);
  ASSERT_EQ(m.info().plan.ensemble, tgn::kEnsembleMembers);
  const std::string dir =
      (fs::temp_directory_path() / ("ddace_test_ensemble_count_" + std::to_string(::getpid()))).string();
  for (const int edited : {1, 2, tgn::kEnsembleMembers + 1}) {
    fs::remove_all(dir);
    m.save(dir);
    ASSERT_TRUE(
        editManifest(dir, "ensemble: " + std::to_string(tgn::kEnsembleMembers), "ensemble: " + std::to_string(edited)));
    try {
      tgn::SequenceModel::load(dir);
      ADD_FAILURE() << "loaded a model of " << tgn::kEnsembleMembers << " networks as " << edited;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("an ensemble of " + std::to_string(edited) + " networks"), std::string::npos)
          << e.what();
    }
  }
  fs::remove_all(dir);
}

// The majority of an ensemble's decoded steps: the most voted, the first network's on a tie.
TEST(Ensemble, MajorityDecision) {
  const auto step = [](int target) {
    tgn::detail::StepDecision d;
    d.tokens = {{1, target}, {0, 0}};
    return d;
  };
  tgn::detail::StepDecision end;
  end.end = true;
  EXPECT_EQ(tgn::detail::majorityDecision({step(1), step(2), step(2)}), 1u);
  EXPECT_EQ(tgn::detail::majorityDecision({step(1), step(2), step(3)}), 0u);
  EXPECT_EQ(tgn::detail::majorityDecision({step(1), end, end}), 1u);
  EXPECT_EQ(tgn::detail::majorityDecision({step(1)}), 0u);
  EXPECT_THROW(tgn::detail::majorityDecision({}), Error);
}

// Shuffled names, unless they cost the fit: where the network with the names shuffled fits
// its demonstrations short of every step, one with them kept is trained next, and the
// better fit of the two is the model. zoo:11 at 10 demonstrations ("each box fetched by the
// robots in front-to-back order, then carried to its farthest free goal": the robots' and
// the goals' names shuffled). Trained to the end, its networks fit every step on most
// machines (which seeds fall short depends on the CPU's floating-point kernels), so training
// is cut to 2 epochs: the first network falls short wherever it is tried, and the model kept
// must be the better fit, the names kept exactly when they fit better.
TEST(ShuffledNames, AreKeptWhereShufflingThemCostsTheFit) {
  const task::TaskDir train = generate("zoo:11", 10);
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    tgn::TrainOptions o;
    o.without = {tgn::Rule::Ensemble};  // the rule is the first network's; one is enough here
    o.seed = seed;
    o.max_epochs = 2;
    ASSERT_FALSE(planOf(train, o).name_groups.empty());
    std::ostringstream progress;
    const tgn::SequenceModel m = tgn::SequenceModel::train(train, o, &progress);
    const std::string log = progress.str();
    // "step accuracy F: training with the names kept", then "step accuracy G with the
    // names kept: keeping it|the first".
    const size_t tried = log.find("training with the names kept");
    ASSERT_NE(tried, std::string::npos) << log;
    const double shuffled_fit = std::stod(log.substr(log.rfind("step accuracy ", tried) + 14));
    const size_t verdict = log.find("with the names kept: keeping", tried);
    ASSERT_NE(verdict, std::string::npos) << log;
    const double kept_fit = std::stod(log.substr(log.rfind("step accuracy ", verdict) + 14));
    EXPECT_LT(shuffled_fit, 1.0) << log;
    EXPECT_EQ(m.info().plan.name_groups.empty(), kept_fit > shuffled_fit) << log;
    if (kept_fit > shuffled_fit) {
      EXPECT_TRUE(m.info().plan.identity_embedding) << log;
    }
    EXPECT_NEAR(m.stepAccuracy(train.demos), std::max(shuffled_fit, kept_fit), 1e-5) << log;  // printed to 6 digits
  }
}

// Every message of TrainingPlan::inconsistency (plan_check.cpp): what the manifest reader
// refuses, each from the plan of a valid scene model changed in one place.
TEST(PlanCheck, NamesEachPlanNoTrainingMakes) {
  tgn::TrainOptions o;
  tgn::TrainingPlan valid;  // a scene model of a task the scene decides
  valid.relative_features = true;
  valid.identity_embedding = true;
  valid.names_or_scene = true;
  valid.name_groups = {{0, 1}};
  valid.token_by_token = true;
  valid.step_rules.exclusive_targets = true;
  valid.parked_out_of_ranks = true;
  valid.ensemble = tgn::kEnsembleMembers;
  valid.end_scene = {{{"robot:hamster", "goal", 2}}, true};
  ASSERT_EQ(valid.inconsistency(o), "");
  const auto why = [&](const std::function<void(tgn::TrainingPlan&, tgn::TrainOptions&)>& change) {
    tgn::TrainingPlan p = valid;
    tgn::TrainOptions options = o;
    change(p, options);
    return p.inconsistency(options);
  };
  using P = tgn::TrainingPlan;
  using O = tgn::TrainOptions;
  EXPECT_EQ(why([](P& p, O&) { p.slips = 1; }), "slips without a fixed order");
  EXPECT_EQ(why([](P&, O& x) { x.identity_embedding = false; }), "identity_embedding where the options have none");
  EXPECT_EQ(why([](P&, O& x) { x.variant = tgn::Variant::Paper; }), "rules of the scene network for the paper variant");
  EXPECT_EQ(why([](P&, O& x) { x.without = {tgn::Rule::Relative}; }), "relative_features, switched off by the options");
  EXPECT_EQ(why([](P& p, O&) { p.fixed_order = true; }), "relative_features on a fixed order");
  EXPECT_EQ(why([](P& p, O&) { p.relative_features = false; }),
            "token_by_token, parked_out_of_ranks, names_or_scene or name_groups without the relative features");
  EXPECT_EQ(why([](P& p, O&) { p.step_rules.exclusive_targets = false; }), "token_by_token without exclusive targets");
  EXPECT_EQ(why([](P&, O& x) { x.without = {tgn::Rule::Parked}; }), "parked_out_of_ranks, switched off by the options");
  EXPECT_EQ(why([](P&, O& x) { x.without = {tgn::Rule::EndScene}; }),
            "an end scene without the relative features, or switched off by the options");
  EXPECT_EQ(why([](P& p, O&) { p.end_scene.counts.clear(); }), "a telling end scene without counts");
  EXPECT_EQ(why([](P& p, O&) { p.end_scene.counts[0].count = 0; }), "an end scene count below 1");
  EXPECT_EQ(why([](P& p, O&) { p.ensemble = 1; }),
            "an ensemble of 1 networks (training makes 3 for this plan and options)");
  EXPECT_EQ(why([](P& p, O&) { p.identity_embedding = false; }),
            "names_or_scene or name_groups without the identity embedding");
  EXPECT_EQ(why([](P&, O& x) { x.without = {tgn::Rule::ShuffledNames}; }), "name_groups, switched off by the options");
  EXPECT_EQ(why([](P& p, O&) {
              p.name_groups = {{1, 0}};
            }),
            "a name group not in ascending order of distinct entities");
  EXPECT_EQ(why([](P& p, O&) {
              p.name_groups = {{1, 1}};
            }),
            "a name group not in ascending order of distinct entities");
}

// Every refusal of transferOf (plan_check.cpp), and what a model that transfers says, each
// from the model info of a scene model that transfers changed in one place.
TEST(PlanCheck, TransferNamesWhyAModelRunsOnlyOnItsOwnEntities) {
  task::TaskSpec spec;
  spec.entities = {{"R1", task::EntityKind::Robot, "hamster"},
                   {"R2", task::EntityKind::Robot, "hamster"},
                   {"G1", task::EntityKind::Goal, ""},
                   {"G2", task::EntityKind::Goal, ""}};
  tgn::ModelInfo valid;
  valid.variant = tgn::Variant::Scene;
  valid.plan.relative_features = true;
  valid.plan.identity_embedding = true;
  valid.plan.name_groups = {{0, 1}};
  const tgn::Transfer t = tgn::transferOf(valid, spec);
  EXPECT_EQ(t.refusal, "");
  EXPECT_EQ(t.any_number, (std::vector<std::string>{"robot:hamster"}));
  EXPECT_EQ(t.named, (std::vector<std::string>{"G1", "G2"}));
  EXPECT_EQ(t.text(), "any number of robot:hamster; by name: G1, G2");
  const auto why = [&](const std::function<void(tgn::ModelInfo&)>& change) {
    tgn::ModelInfo info = valid;
    change(info);
    return tgn::transferOf(info, spec).text();
  };
  EXPECT_EQ(why([](tgn::ModelInfo& i) { i.variant = tgn::Variant::Paper; }),
            "its own task's entities only: the paper network has one output slot per entity of its task");
  EXPECT_EQ(why([](tgn::ModelInfo& i) { i.variant = tgn::Variant::Gnn; }),
            "its own task's entities only: the gnn network has one output slot per entity of its task");
  EXPECT_EQ(why([](tgn::ModelInfo& i) {
              i.plan.relative_features = false;
              i.plan.fixed_order = true;
            }),
            "its own task's entities only: every training demonstration had the same steps (a fixed order): the model "
            "learned the order of the names, not a rule of the scene");
  EXPECT_EQ(why([](tgn::ModelInfo& i) { i.plan.relative_features = false; }),
            "its own task's entities only: trained without the relative features: its decisions depend on the names "
            "alone");
  EXPECT_EQ(why([](tgn::ModelInfo& i) { i.plan.name_groups.clear(); }),
            "its own task's entities only: training kept every entity's name (a name alone decides a role, or "
            "shuffling the names cost the fit)");
  EXPECT_EQ(why([](tgn::ModelInfo& i) { i.plan.identity_embedding = false; }), "any number of goal, robot:hamster");
}
