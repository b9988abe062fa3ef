// Interaction graph of a task and its spectral refinement (DDACE, Sec. IV-A).
//
// Owns: the directed interaction edges (entity -> target) observed in the
// demonstrations, their frequencies F(e), the weighted adjacency and Laplacian,
// spectral clustering of the entities, and the refined edge set E' that the
// temporal graph network attends over. Plain Eigen; no torch, no ROS.
//
// Nodes are entity indices in task.yaml order. An edge (s, t) comes from a token
// "s does an action directed at t"; in-place tokens (no target) give no edge.
//
// THE REFINEMENT RULE (the paper only says "retain structurally consistent
// relational patterns"; this is ours):
//   support(e) = fraction of the demonstrations in which edge e occurs at least once.
//   1. support(e) >= keep_support (default 0.5) and e occurs in at least two
//      demonstrations (one when there is only one): kept — the edge recurs
//      across demonstrations, whatever the clustering says.
//   2. support(e) < drop_support (default 0.1), or e occurs in a single
//      demonstration when there are several: dropped — a spurious interaction
//      (a mislabelled or accidental token), whatever the clustering says.
//   3. otherwise: kept exactly when both end points lie in the same spectral
//      cluster, i.e. the edge is consistent with the dominant interaction
//      structure; an occasional edge that bridges two clusters is dropped.
// The clustering: symmetric weighted adjacency A_ij = F(i->j) + F(j->i), where
// F(e) is the number of tokens with edge e summed over all demonstrations;
// normalised Laplacian L = I - D^-1/2 A D^-1/2 (an isolated node keeps L_ii = 1);
// number of clusters k = position of the largest gap among the ascending
// eigenvalues, k in 1..max(1, n/2) (a cluster of one or two entities on average
// says nothing about structure); rows of the first k eigenvectors, normalised to unit
// length, clustered by k-means (k-means++ seeding with our own SplitMix64 RNG
// from `seed`, 8 restarts, best inertia). Everything is deterministic: the same
// demonstrations and options give the same E'.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ddace/task/demonstration.h"

namespace ddace::graph {

/// A directed interaction edge source -> target (entity indices).
struct Edge {
  int source = -1;
  int target = -1;
  bool operator==(const Edge& o) const { return source == o.source && target == o.target; }
  bool operator<(const Edge& o) const { return source != o.source ? source < o.source : target < o.target; }
};

/// Why an observed edge is in E' or not (see the rule above).
enum class Decision { KeptRecurrent, KeptSameCluster, DroppedRare, DroppedCrossCluster };
/// "kept: recurs", "kept: same cluster", "dropped: rare", "dropped: crosses clusters".
const char* toString(Decision decision);
bool isKept(Decision decision);

/// One observed edge with its statistics.
struct EdgeStats {
  Edge edge;
  int frequency = 0;   ///< F(e): tokens with this edge, summed over demonstrations
  int demos = 0;       ///< demonstrations in which the edge occurs
  double support = 0;  ///< demos / number of demonstrations, in [0, 1]
  Decision decision = Decision::DroppedRare;
};

struct RefinementOptions {
  double keep_support = 0.5;  ///< support at or above which an edge is always kept
  double drop_support = 0.1;  ///< support below which an edge is always dropped
  uint64_t seed = 1;          ///< k-means seeding
};

/// Everything the refinement computed; `kept` is E'.
struct RefinedGraph {
  int nodes = 0;
  int demonstrations = 0;
  std::vector<EdgeStats> edges;  ///< every observed edge, sorted by (source, target)
  Eigen::MatrixXd adjacency;     ///< [nodes x nodes] symmetric weights A
  Eigen::MatrixXd laplacian;     ///< L = D - A (unnormalised; the clustering uses the normalised one)
  Eigen::VectorXd eigenvalues;   ///< of the normalised Laplacian, ascending
  int clusters = 1;              ///< k chosen by the eigengap
  std::vector<int> cluster;      ///< [node] cluster index in 0..k-1 (numbered by first node)
  std::vector<Edge> kept;        ///< E', sorted

  bool contains(const Edge& e) const;
};

/// The directed edges of one demonstration's tokens (with repetitions: one per token).
std::vector<Edge> tokenEdges(const task::Demonstration& demo);

/// Applies the rule above to the demonstrations of one task with `nodes` entities.
/// Throws ddace::Error when there are no demonstrations, a token names an entity
/// outside 0..nodes-1, or the support thresholds are not 0 <= drop <= keep <= 1.
RefinedGraph refine(const std::vector<task::Demonstration>& demos, int nodes, const RefinementOptions& options = {});

/// The same graph with node k renamed to new_index[k] (a permutation of 0..nodes-1):
/// edges and E' re-sorted, clusters, adjacency and Laplacian permuted; the eigenvalues
/// stay. The sequence model refines in the canonical (name-sorted) entity order, where
/// the k-means seeding visits the nodes, and maps the result back to the task's order.
RefinedGraph permuted(const RefinedGraph& g, const std::vector<int>& new_index);

/// Every ordered pair (i, j), i != j: the edge set of the `full-graph` ablation.
std::vector<Edge> fullyConnected(int nodes);

}  // namespace ddace::graph
