// Spectral edge refinement: the rule documented in include/ddace/graph/refinement.h.
#include <gtest/gtest.h>

#include "ddace/common/error.h"
#include "ddace/graph/refinement.h"
#include "ddace/tasks/generators.h"

using namespace ddace;
using graph::Edge;

namespace {

/// A demonstration of `nodes` entities whose steps are the given (entity, target) motions;
/// each step lasts two rows followed by one idle row.
task::Demonstration demoOf(int nodes, const std::vector<std::vector<std::pair<int, int>>>& steps) {
  task::Demonstration d;
  d.source = "synthetic.csv";
  d.has_label_columns.assign(nodes, true);
  auto addRow = [&](const std::vector<task::Label>& labels) {
    d.t.push_back(0.1 * static_cast<double>(d.t.size()));
    std::vector<Eigen::Vector2d> pos;
    for (int i = 0; i < nodes; ++i) pos.emplace_back(0.1 * i, 0.05 * static_cast<double>(d.t.size()));
    d.positions.push_back(pos);
    d.labels.push_back(labels);
  };
  addRow(std::vector<task::Label>(nodes));
  for (const auto& step : steps) {
    std::vector<task::Label> labels(nodes);
    for (auto [e, t] : step) labels[e] = {"move", t};
    addRow(labels);
    addRow(labels);
    addRow(std::vector<task::Label>(nodes));
  }
  d.analyze();
  return d;
}

}  // namespace

TEST(Refinement, KeepsEveryRecurringEdgeAndDropsOneSpuriousToken) {
  tasks::GeneratorOptions options;
  options.family = "task2";
  options.demos = 20;
  options.seed = 7;
  task::TaskDir dir = tasks::generate(options);
  const int n = static_cast<int>(dir.spec.entities.size());
  const graph::RefinedGraph clean = graph::refine(dir.demos, n);

  // Inject one spurious token into demonstration 5: R1's first motion goes to G1 instead.
  const int r1 = dir.spec.entityIndex("R1"), g1 = dir.spec.entityIndex("G1");
  task::Demonstration& bad = dir.demos[5];
  const task::Segment seg = bad.segments.front();
  ASSERT_EQ(seg.token.entity, r1);
  ASSERT_NE(seg.token.target, g1);
  for (int row = seg.first_row; row <= seg.last_row; ++row) bad.labels[row][r1].target = g1;
  bad.analyze();
  const Edge spurious{r1, g1};
  const graph::RefinedGraph g = graph::refine(dir.demos, n);

  // The spurious edge was observed (once) but is not in E'.
  bool observed = false;
  for (const auto& s : g.edges)
    if (s.edge == spurious) {
      observed = true;
      EXPECT_EQ(s.demos, 1);
      EXPECT_EQ(s.decision, graph::Decision::DroppedRare);
    }
  EXPECT_TRUE(observed);
  EXPECT_FALSE(g.contains(spurious));
  // Every edge of the clean demonstrations recurs in (at least) 19 of 20 and is kept.
  ASSERT_FALSE(clean.kept.empty());
  for (const Edge& e : clean.kept) EXPECT_TRUE(g.contains(e)) << e.source << "->" << e.target;
  EXPECT_EQ(g.kept, clean.kept);
  // Task 2's edges: 13 distinct motions (R1,R2->R3; R3->R5; R3->R4; ...; R11->G1).
  EXPECT_EQ(clean.kept.size(), 13u);
}

TEST(Refinement, OccasionalEdgesAreDecidedByTheSpectralClusters) {
  // Two communities {0,1,2} and {3,4,5}, linked by an occasional edge 2->3; 0->2 is
  // equally occasional but inside a community.
  std::vector<task::Demonstration> demos;
  for (int i = 0; i < 10; ++i) {
    std::vector<std::vector<std::pair<int, int>>> steps = {{{0, 1}, {3, 4}}, {{1, 2}, {4, 5}}};
    if (i < 3) steps.push_back({{0, 2}});
    if (i >= 7) steps.push_back({{2, 3}});
    demos.push_back(demoOf(6, steps));
  }
  const graph::RefinedGraph g = graph::refine(demos, 6);
  EXPECT_EQ(g.clusters, 2);
  EXPECT_EQ(g.cluster, (std::vector<int>{0, 0, 0, 1, 1, 1}));
  EXPECT_EQ(g.kept, (std::vector<Edge>{{0, 1}, {0, 2}, {1, 2}, {3, 4}, {4, 5}}));
  for (const auto& s : g.edges) {
    if (s.edge == Edge{0, 2}) {
      EXPECT_EQ(s.decision, graph::Decision::KeptSameCluster);
    } else if (s.edge == Edge{2, 3}) {
      EXPECT_EQ(s.decision, graph::Decision::DroppedCrossCluster);
    } else if (s.edge == Edge{0, 1}) {
      EXPECT_EQ(s.decision, graph::Decision::KeptRecurrent);
    }
  }
  // Laplacian L = D - A of the symmetric frequencies.
  EXPECT_DOUBLE_EQ(g.adjacency(0, 1), 10);
  EXPECT_DOUBLE_EQ(g.adjacency(2, 3), 3);
  EXPECT_DOUBLE_EQ(g.laplacian(2, 2), 10 + 3 + 3);
  EXPECT_NEAR(g.laplacian.rowwise().sum().norm(), 0, 1e-12);
}

TEST(Refinement, IsDeterministicAndIndependentOfTheSeedForClearStructure) {
  tasks::GeneratorOptions options;
  options.family = "task1";
  options.demos = 10;
  const task::TaskDir dir = tasks::generate(options);
  const int n = static_cast<int>(dir.spec.entities.size());
  graph::RefinementOptions a, b;
  b.seed = 12345;
  const auto g1 = graph::refine(dir.demos, n, a), g2 = graph::refine(dir.demos, n, a),
             g3 = graph::refine(dir.demos, n, b);
  EXPECT_EQ(g1.kept, g2.kept);
  EXPECT_EQ(g1.cluster, g2.cluster);
  EXPECT_EQ(g1.kept, g3.kept);
  EXPECT_TRUE(g1.eigenvalues.isApprox(g2.eigenvalues));
}

TEST(Refinement, AnEdgeOfASingleDemonstrationOutOfTwoIsNotRecurring) {
  const auto a = demoOf(3, {{{0, 1}}, {{1, 2}}});
  const auto b = demoOf(3, {{{0, 1}}, {{0, 2}}});
  const graph::RefinedGraph g = graph::refine({a, b}, 3);
  EXPECT_EQ(g.kept, (std::vector<Edge>{{0, 1}}));
  // A single demonstration: all its edges are kept.
  EXPECT_EQ(graph::refine({b}, 3).kept, (std::vector<Edge>{{0, 1}, {0, 2}}));
}

TEST(Refinement, RejectsBadInput) {
  EXPECT_THROW(graph::refine({}, 3), Error);
  const auto a = demoOf(3, {{{0, 2}}});
  EXPECT_THROW(graph::refine({a}, 2), Error);
  graph::RefinementOptions bad;
  bad.drop_support = 0.6;
  EXPECT_THROW(graph::refine({a}, 3, bad), Error);
}

TEST(Refinement, FullyConnectedHasEveryOrderedPair) {
  const auto e = graph::fullyConnected(4);
  EXPECT_EQ(e.size(), 12u);
  for (const auto& x : e) EXPECT_NE(x.source, x.target);
}
