// The precedence between tokens: the rule documented in include/ddace/graph/dependencies.h.
#include <gtest/gtest.h>

#include <yaml-cpp/yaml.h>

#include "ddace/common/error.h"
#include "ddace/graph/dependencies.h"
#include "ddace/tasks/generators.h"

using namespace ddace;

namespace {

/// A labelled interval of a hand-made demonstration: `key`'s label holds over [first, last].
struct Held {
  std::string key;
  int first = 0, last = 0;
};

/// A demonstration of `spec` at 20 Hz where each token's label holds over its rows (the
/// positions stay put: the rule reads only when labels begin and end).
task::Demonstration handMoved(const task::TaskSpec& spec, const std::vector<Held>& tokens) {
  const size_t n = spec.entities.size();
  int rows = 0;
  for (const Held& h : tokens) rows = std::max(rows, h.last + 3);
  task::Demonstration d;
  d.source = "hand_moved.csv";
  d.has_label_columns.assign(n, true);
  for (int r = 0; r < rows; ++r) {
    d.t.push_back(r * 0.05);
    std::vector<Eigen::Vector2d> at;
    for (size_t e = 0; e < n; ++e) at.emplace_back(0.1 + 0.08 * static_cast<double>(e), 0.5);
    d.positions.push_back(at);
    d.labels.emplace_back(n);
  }
  for (const Held& h : tokens) {
    const task::Token t = task::parseTokenKey(h.key, spec);
    for (int r = h.first; r <= h.last; ++r)
      d.labels[static_cast<size_t>(r)][static_cast<size_t>(t.entity)] = {t.action, t.target};
  }
  d.analyze();
  return d;
}

task::TaskSpec task4Spec() {
  tasks::GeneratorOptions o;
  o.family = "task4";
  o.demos = 1;
  return tasks::generate(o).spec;
}

std::vector<task::Token> tokens(const task::TaskSpec& spec, const std::vector<std::string>& keys) {
  std::vector<task::Token> out;
  for (const auto& k : keys) out.push_back(task::parseTokenKey(k, spec));
  return out;
}

/// Task 4's steps: [R1:move:R3 R2:move:R4], then [R3:move:G1 R4:move:G1].
struct Task4Steps {
  task::TaskSpec spec = task4Spec();
  std::vector<task::Token> first = tokens(spec, {"R1:move:R3", "R2:move:R4"});
  std::vector<task::Token> second = tokens(spec, {"R3:move:G1", "R4:move:G1"});
  /// Whether second[i] waits for first[j].
  bool waits(const graph::Dependencies& d, size_t i, size_t j) const { return d.waitsFor(spec, second, i, first, j); }
};

}  // namespace

TEST(Dependencies, ATokenWaitsForTheTokensWhoseEntitiesItInvolves) {
  const Task4Steps t;
  graph::Dependencies none;
  none.learned = true;
  EXPECT_TRUE(t.waits(none, 0, 0));   // R3 is R1's target
  EXPECT_FALSE(t.waits(none, 0, 1));  // R3 and R2:move:R4 share nothing
  EXPECT_TRUE(t.waits(none, 1, 1));
  EXPECT_FALSE(t.waits(none, 1, 0));
  // A carrier involves its load: R1 carrying B1 waits for whoever moved B1.
  task::TaskSpec spec = t.spec;
  spec.entities.push_back({"B1", task::EntityKind::Object, "box"});
  spec.actions.push_back("carry");
  const auto carry = tokens(spec, {"R1:carry:G1", "B1:carry:G1"});
  const auto before = tokens(spec, {"R2:move:B1"});
  EXPECT_TRUE(none.waitsFor(spec, carry, 0, before, 0));
  EXPECT_EQ(graph::involvedEntities(spec, carry, 0).size(), 3u);
}

TEST(Dependencies, AModelWithoutThemWaitsForEveryEarlierToken) {
  const Task4Steps t;
  const graph::Dependencies old;  // a manifest without `dependencies`
  EXPECT_TRUE(t.waits(old, 0, 1));
  EXPECT_TRUE(t.waits(old, 1, 0));
}

TEST(Dependencies, StepsThatEndTogetherShowNoWaitBeyondTheEntities) {
  // The generators' demonstrations: the tokens of a step start and end together, so R3
  // leaving after R2 ended is explained by R1 (which met R3) ending on the same row.
  tasks::GeneratorOptions o;
  o.family = "task4";
  o.demos = 5;
  const task::TaskDir dir = tasks::generate(o);
  const graph::Dependencies d = graph::learnDependencies(dir.spec, dir.demos);
  const Task4Steps t;
  EXPECT_TRUE(d.learned);
  EXPECT_EQ(d.demonstrations, 5);
  EXPECT_TRUE(d.evidence.empty());
  EXPECT_TRUE(t.waits(d, 0, 0));
  EXPECT_FALSE(t.waits(d, 0, 1));
  EXPECT_FALSE(t.waits(d, 1, 0));
}

TEST(Dependencies, APersonWhoHoldsATokenUntilAnotherEndedShowsItWaiting) {
  // One robot at a time: R1 reaches R3 (row 20), R2 reaches R4 later (row 40), and only
  // then do R3 and R4 leave, although R3 was free at row 20.
  const Task4Steps t;
  std::vector<task::Demonstration> demos;
  for (int k = 0; k < 3; ++k)
    demos.push_back(handMoved(
        t.spec, {{"R1:move:R3", 5, 20 + k}, {"R2:move:R4", 6, 40}, {"R3:move:G1", 42, 70}, {"R4:move:G1", 43, 75}}));
  ASSERT_EQ(demos[0].steps.size(), 2u);
  const graph::Dependencies d = graph::learnDependencies(t.spec, demos);
  const graph::WaitEvidence* e = d.find("R3:move:G1", "R2:move:R4");
  ASSERT_NE(e, nullptr);
  EXPECT_EQ(e->shown_waiting, 3);
  EXPECT_EQ(e->started_early, 0);
  EXPECT_TRUE(t.waits(d, 0, 1));
  // R4 was free only when R2 ended, after R1: nothing shows it waiting for R1.
  EXPECT_EQ(d.find("R4:move:G1", "R1:move:R3"), nullptr);
  EXPECT_FALSE(t.waits(d, 1, 0));
}

TEST(Dependencies, ATokenThatStartsBeforeAnotherEndedDoesNotWaitForIt) {
  // The effect test: robots moved so that R3 leaves for G1 as soon as R1 has reached it,
  // while R2 still drives to R4 -- in most demonstrations; once the person held R3 back.
  const Task4Steps t;
  std::vector<task::Demonstration> demos;
  for (int k = 0; k < 4; ++k)
    demos.push_back(handMoved(
        t.spec, {{"R1:move:R3", 5, 20}, {"R2:move:R4", 6, 40}, {"R3:move:G1", 22 + k, 60}, {"R4:move:G1", 42, 70}}));
  demos.push_back(handMoved(
      t.spec, {{"R1:move:R3", 5, 20}, {"R2:move:R4", 6, 40}, {"R3:move:G1", 42, 60}, {"R4:move:G1", 43, 70}}));
  for (const auto& demo : demos) ASSERT_EQ(demo.steps.size(), 2u);
  const graph::Dependencies d = graph::learnDependencies(t.spec, demos);
  const graph::WaitEvidence* e = d.find("R3:move:G1", "R2:move:R4");
  ASSERT_NE(e, nullptr);
  EXPECT_EQ(e->started_early, 4);
  EXPECT_EQ(e->shown_waiting, 1);
  EXPECT_FALSE(t.waits(d, 0, 1));
  EXPECT_TRUE(t.waits(d, 0, 0));  // its entities still bind it to R1
  // Held back as often as it started early: a tie waits.
  const graph::Dependencies tie = graph::learnDependencies(t.spec, {demos[0], demos[4]});
  EXPECT_TRUE(t.waits(tie, 0, 1));
}

TEST(Dependencies, ATokenWithNothingInCommonWaitsForThePersonsOrder) {
  // [R1:move:G1] then [R2:move:R4]: nothing shared, so the order is the person's; shown
  // waiting when R2 left after R1 arrived, free when it left before.
  const Task4Steps t;
  const auto after = tokens(t.spec, {"R2:move:R4"});
  const auto before = tokens(t.spec, {"R1:move:G1"});
  const auto waited =
      graph::learnDependencies(t.spec, {handMoved(t.spec, {{"R1:move:G1", 5, 20}, {"R2:move:R4", 23, 40}})});
  EXPECT_TRUE(waited.waitsFor(t.spec, after, 0, before, 0));
  // Left while R3 (of R1's step) had ended and R1 still ran: a step of its own, started early.
  const task::Demonstration early_demo =
      handMoved(t.spec, {{"R1:move:G1", 5, 30}, {"R3:move:G1", 6, 20}, {"R2:move:R4", 25, 40}});
  ASSERT_EQ(early_demo.steps.size(), 2u);
  const auto early = graph::learnDependencies(t.spec, {early_demo});
  ASSERT_NE(early.find("R2:move:R4", "R1:move:G1"), nullptr);
  EXPECT_EQ(early.find("R2:move:R4", "R1:move:G1")->started_early, 1);
  EXPECT_FALSE(early.waitsFor(t.spec, after, 0, before, 0));
  // Left while every token of R1's step still ran: one step with it (step grouping), and
  // tokens of one step wait for none of each other.
  const task::Demonstration together = handMoved(t.spec, {{"R1:move:G1", 5, 30}, {"R2:move:R4", 25, 40}});
  ASSERT_EQ(together.steps.size(), 1u);
  EXPECT_FALSE(graph::learnDependencies(t.spec, {together}).waitsFor(t.spec, after, 0, before, 0));
}

TEST(Dependencies, RoundTripThroughTheManifestAndRefuseAnEditedOne) {
  const Task4Steps t;
  std::vector<task::Demonstration> demos{
      handMoved(t.spec, {{"R1:move:R3", 5, 20}, {"R2:move:R4", 6, 40}, {"R3:move:G1", 25, 60}, {"R4:move:G1", 42, 70}}),
      handMoved(t.spec,
                {{"R1:move:R3", 5, 20}, {"R2:move:R4", 6, 40}, {"R3:move:G1", 42, 60}, {"R4:move:G1", 43, 70}})};
  const graph::Dependencies d = graph::learnDependencies(t.spec, demos);
  ASSERT_FALSE(d.evidence.empty());
  YAML::Emitter y;
  graph::emitDependencies(y, d);
  const graph::Dependencies back = graph::parseDependencies(YAML::Load(y.c_str()), "manifest.yaml", t.spec);
  ASSERT_EQ(back.evidence.size(), d.evidence.size());
  for (size_t i = 0; i < d.evidence.size(); ++i) {
    EXPECT_EQ(back.evidence[i].token, d.evidence[i].token);
    EXPECT_EQ(back.evidence[i].after, d.evidence[i].after);
    EXPECT_EQ(back.evidence[i].shown_waiting, d.evidence[i].shown_waiting);
    EXPECT_EQ(back.evidence[i].started_early, d.evidence[i].started_early);
  }
  const auto refused = [&](const std::string& text, const std::string& what) {
    try {
      graph::parseDependencies(YAML::Load(text), "manifest.yaml", t.spec);
      ADD_FAILURE() << "accepted: " << text;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("manifest.yaml:"), std::string::npos) << e.what();
    }
  };
  refused(
      "demonstrations: 2\npairs:\n  - {token: R9:move:G1, after: R2:move:R4, shown_waiting: 1, started_early: 0, "
      "waits: true}\n",
      "unknown entity 'R9'");
  refused(
      "demonstrations: 2\npairs:\n  - {token: R3:move:G1, after: R2:move:R4, shown_waiting: 0, started_early: 2, "
      "waits: true}\n",
      "contradicts");
  refused(
      "demonstrations: 2\npairs:\n  - {token: R3:move:G1, after: R2:move:R4, shown_waiting: 3, started_early: 0, "
      "waits: true}\n",
      "shown_waiting");
}
