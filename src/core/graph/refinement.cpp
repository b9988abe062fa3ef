#include "ddace/graph/refinement.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include <Eigen/Eigenvalues>

#include "ddace/common/error.h"
#include "ddace/common/random.h"

namespace ddace::graph {

namespace {

/// k-means on the rows of `points` with k-means++ seeding; returns labels and inertia.
std::pair<std::vector<int>, double> kmeans(const Eigen::MatrixXd& points, int k, SplitMix64& rng) {
  const int n = static_cast<int>(points.rows());
  Eigen::MatrixXd centres(k, points.cols());
  centres.row(0) = points.row(static_cast<int>(rng.next() % static_cast<uint64_t>(n)));
  Eigen::VectorXd d2(n);
  for (int c = 1; c < k; ++c) {
    for (int i = 0; i < n; ++i) {
      double best = std::numeric_limits<double>::infinity();
      for (int j = 0; j < c; ++j) best = std::min(best, (points.row(i) - centres.row(j)).squaredNorm());
      d2(i) = best;
    }
    const double total = d2.sum();
    int chosen = n - 1;
    if (total > 0) {
      double r = rng.uniform() * total;
      for (int i = 0; i < n; ++i) {
        r -= d2(i);
        if (r <= 0) {
          chosen = i;
          break;
        }
      }
    } else {
      chosen = static_cast<int>(rng.next() % static_cast<uint64_t>(n));
    }
    centres.row(c) = points.row(chosen);
  }
  std::vector<int> label(n, -1);
  for (int iter = 0; iter < 100; ++iter) {
    bool changed = false;
    for (int i = 0; i < n; ++i) {
      int best = 0;
      double bd = std::numeric_limits<double>::infinity();
      for (int c = 0; c < k; ++c) {
        const double d = (points.row(i) - centres.row(c)).squaredNorm();
        if (d < bd - 1e-12) {
          bd = d;
          best = c;
        }
      }
      if (label[i] != best) changed = true;
      label[i] = best;
    }
    if (!changed) break;
    for (int c = 0; c < k; ++c) {
      Eigen::RowVectorXd sum = Eigen::RowVectorXd::Zero(points.cols());
      int count = 0;
      for (int i = 0; i < n; ++i)
        if (label[i] == c) {
          sum += points.row(i);
          ++count;
        }
      if (count > 0) centres.row(c) = sum / count;
    }
  }
  double inertia = 0;
  for (int i = 0; i < n; ++i) inertia += (points.row(i) - centres.row(label[i])).squaredNorm();
  return {label, inertia};
}

}  // namespace

const char* toString(Decision decision) {
  switch (decision) {
    case Decision::KeptRecurrent:
      return "kept: recurs";
    case Decision::KeptSameCluster:
      return "kept: same cluster";
    case Decision::DroppedRare:
      return "dropped: rare";
    case Decision::DroppedCrossCluster:
      return "dropped: crosses clusters";
  }
  return "?";
}

bool isKept(Decision decision) {
  return decision == Decision::KeptRecurrent || decision == Decision::KeptSameCluster;
}

bool RefinedGraph::contains(const Edge& e) const {
  return std::binary_search(kept.begin(), kept.end(), e);
}

std::vector<Edge> tokenEdges(const task::Demonstration& demo) {
  std::vector<Edge> edges;
  for (const auto& step : demo.steps)
    for (const auto& token : step.tokens)
      if (token.isMotion()) edges.push_back({token.entity, token.target});
  return edges;
}

RefinedGraph permuted(const RefinedGraph& g, const std::vector<int>& new_index) {
  const int n = g.nodes;
  if (static_cast<int>(new_index.size()) != n) throw Error("graph refinement: the permutation has the wrong size");
  std::vector<bool> seen(static_cast<size_t>(n), false);
  for (int v : new_index) {
    if (v < 0 || v >= n || seen[static_cast<size_t>(v)]) throw Error("graph refinement: not a permutation");
    seen[static_cast<size_t>(v)] = true;
  }
  const auto map = [&](Edge e) {
    return Edge{new_index[static_cast<size_t>(e.source)], new_index[static_cast<size_t>(e.target)]};
  };
  RefinedGraph out = g;
  for (auto& s : out.edges) s.edge = map(s.edge);
  std::sort(out.edges.begin(), out.edges.end(), [](const EdgeStats& a, const EdgeStats& b) { return a.edge < b.edge; });
  for (auto& e : out.kept) e = map(e);
  std::sort(out.kept.begin(), out.kept.end());
  Eigen::MatrixXd p = Eigen::MatrixXd::Zero(n, n);  // p(new, old) = 1
  for (int k = 0; k < n; ++k) p(new_index[static_cast<size_t>(k)], k) = 1;
  if (g.adjacency.rows() == n) out.adjacency = p * g.adjacency * p.transpose();
  if (g.laplacian.rows() == n) out.laplacian = p * g.laplacian * p.transpose();
  for (int k = 0; k < n && static_cast<int>(g.cluster.size()) == n; ++k)
    out.cluster[static_cast<size_t>(new_index[static_cast<size_t>(k)])] = g.cluster[static_cast<size_t>(k)];
  return out;
}

std::vector<Edge> fullyConnected(int nodes) {
  std::vector<Edge> edges;
  for (int i = 0; i < nodes; ++i)
    for (int j = 0; j < nodes; ++j)
      if (i != j) edges.push_back({i, j});
  return edges;
}

RefinedGraph refine(const std::vector<task::Demonstration>& demos, int nodes, const RefinementOptions& options) {
  if (demos.empty()) throw Error("graph refinement: no demonstrations");
  if (nodes <= 0) throw Error("graph refinement: the task has no entities");
  if (!(options.drop_support >= 0 && options.drop_support <= options.keep_support && options.keep_support <= 1))
    throw Error("graph refinement: support thresholds must satisfy 0 <= drop_support (" +
                std::to_string(options.drop_support) + ") <= keep_support (" + std::to_string(options.keep_support) +
                ") <= 1");

  RefinedGraph g;
  g.nodes = nodes;
  g.demonstrations = static_cast<int>(demos.size());
  std::map<Edge, EdgeStats> stats;
  for (const auto& demo : demos) {
    std::set<Edge> seen;
    for (const Edge& e : tokenEdges(demo)) {
      if (e.source < 0 || e.source >= nodes || e.target < 0 || e.target >= nodes)
        throw Error("graph refinement: " + demo.source + ": a token names entity " +
                    std::to_string(std::max(e.source, e.target)) + " of a task with " + std::to_string(nodes) +
                    " entities");
      auto& s = stats[e];
      s.edge = e;
      ++s.frequency;
      if (seen.insert(e).second) ++s.demos;
    }
  }

  g.adjacency = Eigen::MatrixXd::Zero(nodes, nodes);
  for (const auto& [e, s] : stats) {
    if (e.source == e.target) continue;
    g.adjacency(e.source, e.target) += s.frequency;
    g.adjacency(e.target, e.source) += s.frequency;
  }
  const Eigen::VectorXd degree = g.adjacency.rowwise().sum();
  g.laplacian = Eigen::MatrixXd(degree.asDiagonal()) - g.adjacency;

  // Normalised Laplacian; an isolated node has D^-1/2 = 0 and L_ii = 1.
  Eigen::VectorXd inv_sqrt(nodes);
  for (int i = 0; i < nodes; ++i) inv_sqrt(i) = degree(i) > 0 ? 1.0 / std::sqrt(degree(i)) : 0.0;
  const Eigen::MatrixXd lnorm =
      Eigen::MatrixXd::Identity(nodes, nodes) - inv_sqrt.asDiagonal() * g.adjacency * inv_sqrt.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(lnorm);
  g.eigenvalues = solver.eigenvalues();

  // Eigengap: k = argmax_{i in 1..max(1, n/2)} (lambda_i - lambda_{i-1}).
  g.clusters = 1;
  if (nodes > 1) {
    double best_gap = -1;
    for (int i = 1; i <= std::max(1, nodes / 2); ++i) {
      const double gap = g.eigenvalues(i) - g.eigenvalues(i - 1);
      if (gap > best_gap + 1e-9) {
        best_gap = gap;
        g.clusters = i;
      }
    }
  }
  g.cluster.assign(nodes, 0);
  if (g.clusters > 1) {
    Eigen::MatrixXd embed = solver.eigenvectors().leftCols(g.clusters);
    for (int i = 0; i < nodes; ++i) {
      const double norm = embed.row(i).norm();
      if (norm > 1e-12) embed.row(i) /= norm;
    }
    SplitMix64 rng(options.seed * 0x9E3779B97F4A7C15ULL + 0x2545F4914F6CDD1DULL);
    std::vector<int> best;
    double best_inertia = std::numeric_limits<double>::infinity();
    for (int restart = 0; restart < 8; ++restart) {
      auto [labels, inertia] = kmeans(embed, g.clusters, rng);
      if (inertia < best_inertia - 1e-12) {
        best_inertia = inertia;
        best = labels;
      }
    }
    // Renumber clusters by their first node so the numbering does not depend on seeding.
    std::map<int, int> renumber;
    for (int i = 0; i < nodes; ++i) {
      if (!renumber.count(best[i])) renumber[best[i]] = static_cast<int>(renumber.size());
      g.cluster[i] = renumber[best[i]];
    }
    g.clusters = static_cast<int>(renumber.size());
  }

  const int d = g.demonstrations;
  const int min_demos = std::min(2, d);
  for (auto& [e, s] : stats) {
    s.support = static_cast<double>(s.demos) / d;
    if (s.demos < min_demos || s.support < options.drop_support) {
      s.decision = Decision::DroppedRare;
    } else if (s.support >= options.keep_support) {
      s.decision = Decision::KeptRecurrent;
    } else {
      s.decision =
          g.cluster[e.source] == g.cluster[e.target] ? Decision::KeptSameCluster : Decision::DroppedCrossCluster;
    }
    g.edges.push_back(s);
    if (isKept(s.decision)) g.kept.push_back(e);
  }
  return g;
}

}  // namespace ddace::graph
