// SequenceModel::Impl: the canonical entity order, building the network and turning
// demonstrations into tensors.
#include "model_impl.h"

#include <ATen/CPUGeneratorImpl.h>

#include <algorithm>
#include <array>
#include <map>
#include <cmath>
#include <limits>
#include <mutex>
#include <numeric>
#include <set>

#include "ddace/common/error.h"
#include "ddace/common/random.h"
#include "ddace/task/end_point.h"
#include "loss.h"

namespace ddace::tgn {

using torch::Tensor;

namespace {

/// Seeds torch's process-wide CPU generator for the module constructors' initialisers and
/// puts its previous state back afterwards: building (or loading) a model neither reseeds
/// nor advances the generator other code in the process draws from.
class SeededInit {
 public:
  explicit SeededInit(uint64_t seed) : gen_(at::detail::getDefaultCPUGenerator()) {
    std::lock_guard<std::mutex> lock(gen_.mutex());
    saved_ = gen_.get_state();
    gen_.set_current_seed(seed);
  }
  ~SeededInit() {
    std::lock_guard<std::mutex> lock(gen_.mutex());
    gen_.set_state(saved_);
  }
  SeededInit(const SeededInit&) = delete;
  SeededInit& operator=(const SeededInit&) = delete;

 private:
  at::Generator gen_;
  Tensor saved_;
};

uint64_t fnv1a(const std::string& s) {
  uint64_t h = 0xcbf29ce484222325ULL;
  for (unsigned char c : s) {
    h ^= c;
    h *= 0x100000001b3ULL;
  }
  return h;
}

/// Row k of the identity embedding from the name of canonical entity k and the seed
/// (standard normal, as torch::nn::Embedding's own initialisation).
void initIdentity(torch::nn::Embedding& e, const task::TaskSpec& spec, const EntityOrder& order, uint64_t seed) {
  torch::NoGradGuard no_grad;
  auto w = e->weight.accessor<float, 2>();
  for (int k = 0; k < order.size(); ++k) {
    SplitMix64 rng(fnv1a(spec.entities[static_cast<size_t>(order.task_of[k])].name) ^ (seed * 0x9E3779B97F4A7C15ULL));
    for (int64_t c = 0; c < w.size(1); ++c) w[k][c] = static_cast<float>(rng.normal());
  }
}

}  // namespace

EntityOrder::EntityOrder(const task::TaskSpec& spec) {
  const size_t n = spec.entities.size();
  task_of.resize(n);
  std::iota(task_of.begin(), task_of.end(), 0);
  std::sort(task_of.begin(), task_of.end(), [&](int a, int b) {
    return spec.entities[static_cast<size_t>(a)].name < spec.entities[static_cast<size_t>(b)].name;
  });
  canonical_of.resize(n);
  for (size_t k = 0; k < n; ++k) canonical_of[static_cast<size_t>(task_of[k])] = static_cast<int>(k);
}

task::Demonstration EntityOrder::toCanonical(const task::Demonstration& d) const {
  const size_t n = task_of.size();
  const auto entity = [&](int i) { return i < 0 ? i : canonical_of[static_cast<size_t>(i)]; };
  const auto token = [&](task::Token t) {
    t.entity = entity(t.entity);
    t.target = entity(t.target);
    return t;
  };
  const auto positions = [&](const std::vector<Eigen::Vector2d>& p) {
    std::vector<Eigen::Vector2d> out(n);
    for (size_t k = 0; k < n; ++k) out[k] = p[static_cast<size_t>(task_of[k])];
    return out;
  };
  task::Demonstration c = d;
  for (size_t r = 0; r < d.rows(); ++r) {
    c.positions[r] = positions(d.positions[r]);
    for (size_t k = 0; k < n; ++k) {
      task::Label l = d.labels[r][static_cast<size_t>(task_of[k])];
      l.target = entity(l.target);
      c.labels[r][k] = l;
    }
  }
  for (size_t k = 0; k < n; ++k) c.has_label_columns[k] = d.has_label_columns[static_cast<size_t>(task_of[k])];
  for (auto& step : c.steps) {
    for (auto& t : step.tokens) t = token(t);
    std::sort(step.tokens.begin(), step.tokens.end());
    for (auto& late : step.late) late.token = token(late.token);
  }
  for (auto& seg : c.segments) seg.token = token(seg.token);
  for (auto& s : c.snapshots) s.positions = positions(s.positions);
  return c;
}

task::Demonstration EntityOrder::rowsToTask(const task::Demonstration& c) const {
  const size_t n = task_of.size();
  task::Demonstration d;
  d.source = c.source;
  d.t = c.t;
  d.has_label_columns.resize(n);
  for (size_t k = 0; k < n; ++k) d.has_label_columns[static_cast<size_t>(task_of[k])] = c.has_label_columns[k];
  for (size_t r = 0; r < c.rows(); ++r) {
    std::vector<Eigen::Vector2d> p(n);
    std::vector<task::Label> l(n);
    for (size_t k = 0; k < n; ++k) {
      p[static_cast<size_t>(task_of[k])] = c.positions[r][k];
      task::Label label = c.labels[r][k];
      if (label.target >= 0) label.target = task_of[static_cast<size_t>(label.target)];
      l[static_cast<size_t>(task_of[k])] = label;
    }
    d.positions.push_back(std::move(p));
    d.labels.push_back(std::move(l));
  }
  return d;
}

void requireFinite(const std::vector<Eigen::Vector2d>& pos, const task::TaskSpec& spec, const std::string& source,
                   const char* what, size_t index) {
  for (size_t i = 0; i < pos.size(); ++i)
    if (!pos[i].allFinite())
      throw Error(Diagnostic{source, 0, 0,
                             std::string(what) + " " + std::to_string(index) + ": the position of '" +
                                 (i < spec.entities.size() ? spec.entities[i].name : std::to_string(i)) +
                                 "' is not finite"});
}

torch::nn::Module& SequenceModel::Impl::module() {
  if (scene) return *scene;
  return *net;
}

int SequenceModel::Impl::vocabIndex(const std::string& action) const {
  const auto it = std::find(info.vocabulary.begin(), info.vocabulary.end(), action);
  return it == info.vocabulary.end() ? -1 : static_cast<int>(it - info.vocabulary.begin());
}

uint64_t memberSeed(uint64_t seed, int k) {
  return k == 0 ? seed : SplitMix64(seed ^ (0xE7037ED1A0B428DBULL * static_cast<uint64_t>(k))).next();
}

std::vector<SceneNetwork> SequenceModel::Impl::members() const {
  std::vector<SceneNetwork> all = {scene};
  all.insert(all.end(), others.begin(), others.end());
  return all;
}

void SequenceModel::Impl::build(int members) {
  order = EntityOrder(spec);
  cfg.nodes = static_cast<int>(spec.entities.size());
  cfg.actions = static_cast<int>(info.vocabulary.size()) + 1;
  cfg.targets = cfg.nodes + 1;
  cfg.gnn = info.variant == Variant::Gnn;
  cfg.features = cfg.gnn ? 2 + cfg.actions + cfg.targets : isScene() ? 5 : 2;
  cfg.o = info.options;
  cfg.identity_embedding = info.plan.identity_embedding;
  cfg.relative_features = info.plan.relative_features;
  kinds.assign(static_cast<size_t>(cfg.nodes) * 3, 0.f);
  for (int k = 0; k < cfg.nodes; ++k)
    kinds[static_cast<size_t>(k) * 3 + static_cast<size_t>(spec.entities[static_cast<size_t>(order.task_of[k])].kind)] =
        1.f;
  std::vector<graph::Edge> edges;
  for (const auto& e : info.plan.attention_edges)
    edges.push_back(
        {order.canonical_of[static_cast<size_t>(e.source)], order.canonical_of[static_cast<size_t>(e.target)]});
  const Tensor mask = maskFromEdges(cfg.nodes, edges, true);
  SeededInit seeded(info.options.seed);
  net = nullptr;
  scene = nullptr;
  others.clear();
  if (isScene()) {
    scene = SceneNetwork(cfg, mask);
    if (scene->identity) initIdentity(scene->identity, spec, order, info.options.seed);
    for (int k = 1; k < members; ++k) others.push_back(SceneNetwork(cfg, mask));  // the loaded weights replace these
  } else {
    net = Network(cfg, mask);
    if (net->identity) initIdentity(net->identity, spec, order, info.options.seed);
  }
}

void SequenceModel::Impl::features(const std::vector<Eigen::Vector2d>& pos, const std::vector<task::Label>* labels,
                                   float* out) const {
  const int f = cfg.features;
  for (int i = 0; i < cfg.nodes; ++i) {
    float* row = out + i * f;
    std::fill(row, row + f, 0.f);
    if (!isScene()) {
      row[0] = static_cast<float>((pos[i].x() - info.mean[0]) / info.std[0]);
      row[1] = static_cast<float>((pos[i].y() - info.mean[1]) / info.std[1]);
    }
    if (isScene()) std::copy(kinds.begin() + i * 3, kinds.begin() + i * 3 + 3, row + 2);
    if (labels) {
      const task::Label& l = (*labels)[i];
      const int a = l.isNull() ? 0 : vocabIndex(l.action) + 1;
      row[2 + std::max(a, 0)] = 1;
      row[2 + cfg.actions + (l.isNull() ? 0 : l.target + 1)] = 1;
    }
  }
}

namespace {

/// The pairwise view of one snapshot the relational basis reads (canonical order).
struct PairView {
  int n = 0;
  std::vector<double> together;  ///< [N * N] task::togetherDistance of each pair
  /// The position each entity is seen at from elsewhere: the mean of the entities at one
  /// place with it (itself when alone).
  std::vector<Eigen::Vector2d> seen;
  std::vector<double> d;  ///< [N * N] distance between the seen positions / scale; 0 at one place

  double at(int i, int j) const { return together[static_cast<size_t>(i * n + j)]; }
  double dist(int i, int j) const { return d[static_cast<size_t>(i * n + j)]; }
};

/// Entities at one place (task::togetherDistance, the end-point rule): a motion ends at
/// contact with its target or on it, a closed-loop one within the arrival radius of that
/// (the coordinator's DONE). Nearer than that they count as together (distance 0, tied
/// ranks), as in the demonstrations: otherwise a few millimetres of stopping error reorder
/// the nearness ranks of a cluster and change the decision. And they are seen from
/// elsewhere as one place, their mean: a carrier and its load (or a robot and the goal it
/// stands on) then have the same nearest of every kind, as they have one part in the rule
/// ("the teammate nearest to it"), instead of two views a contact apart (a carrier stops
/// behind its load) that disagree where two teammates are nearly as near.
PairView pairView(const task::TaskSpec& spec, const EntityOrder& order, const std::vector<Eigen::Vector2d>& pos,
                  double scale) {
  PairView v;
  const int n = static_cast<int>(pos.size());
  v.n = n;
  v.together.resize(static_cast<size_t>(n * n));
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      v.together[static_cast<size_t>(i * n + j)] = task::togetherDistance(spec, order.task_of[i], order.task_of[j]);
  const std::vector<int> place_of = detail::placesOf(pos, v.together);
  std::vector<Eigen::Vector2d> sum(static_cast<size_t>(n), Eigen::Vector2d::Zero());
  std::vector<double> members(static_cast<size_t>(n), 0.0);
  for (int i = 0; i < n; ++i) {
    sum[static_cast<size_t>(place_of[static_cast<size_t>(i)])] += pos[static_cast<size_t>(i)];
    members[static_cast<size_t>(place_of[static_cast<size_t>(i)])] += 1;
  }
  v.seen.resize(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    const auto p = static_cast<size_t>(place_of[static_cast<size_t>(i)]);
    v.seen[static_cast<size_t>(i)] = sum[p] / members[p];
  }
  v.d.resize(static_cast<size_t>(n * n));
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      v.d[static_cast<size_t>(i * n + j)] =
          place_of[static_cast<size_t>(i)] == place_of[static_cast<size_t>(j)]
              ? 0.0
              : (v.seen[static_cast<size_t>(j)] - v.seen[static_cast<size_t>(i)]).norm() / scale;
  return v;
}

/// Order along the table's axes: 1 / (1 + the number of e's rivals before e), from the
/// left (x), the right, the front (y) and the back; two at one place are tied, any others
/// ordered however near their coordinates (side by side, 5 cm apart in x, one is still the
/// leftmost). `rivals(k, e)`: k counts in e's order.
template <class Rivals>
std::vector<std::array<float, 4>> axisOrders(const PairView& v, const Rivals& rivals) {
  const int n = v.n;
  std::vector<std::array<float, 4>> axis(static_cast<size_t>(n));
  for (int e = 0; e < n; ++e) {
    int before[4] = {0, 0, 0, 0};
    for (int k = 0; k < n; ++k) {
      if (k == e || !rivals(k, e)) continue;
      if (v.dist(k, e) == 0.0) continue;  // at one place: neither is before the other
      const Eigen::Vector2d delta = v.seen[static_cast<size_t>(k)] - v.seen[static_cast<size_t>(e)];
      before[0] += delta.x() < 0;
      before[1] += delta.x() > 0;
      before[2] += delta.y() < 0;
      before[3] += delta.y() > 0;
    }
    for (int a = 0; a < 4; ++a) axis[static_cast<size_t>(e)][a] = 1.f / static_cast<float>(1 + before[a]);
  }
  return axis;
}

/// The entity e's motion from `was` to `now` went to, or -1 (it moved no more than the
/// arrival radius, or nothing lay ahead): of the entities whose place as the step began lies
/// ahead (beyond the motion's midpoint, along it; what it carried started beside it,
/// behind), the one it stopped where a motion toward it ends by the footprints: at contact
/// with an obstacle, on a goal (task/end_point.h). Not the nearest: a robot that joins one
/// standing on a goal stops a contact from both, and the nearest of the two was a
/// millimetre's coincidence (a line-up's second robot "went to the goal" as the first did,
/// so a fourth joined the head instead of the third). The target is where the motion
/// headed, not where it stopped: a motion ends at contact with an obstacle target (a
/// carrier further back, behind its load), so "within a distance" would depend on bodies.
int wentTo(const task::TaskSpec& spec, const std::vector<int>& entity_of, const std::vector<Eigen::Vector2d>& was,
           const std::vector<Eigen::Vector2d>& now, int e, double arrival_radius) {
  const auto at = [](const std::vector<Eigen::Vector2d>& p, int k) { return p[static_cast<size_t>(k)]; };
  const Eigen::Vector2d step = at(now, e) - at(was, e);
  if (step.norm() <= arrival_radius) return -1;
  int went = -1;
  double best = std::numeric_limits<double>::infinity();
  for (int f = 0; f < static_cast<int>(was.size()); ++f) {
    if (f == e || (at(was, f) - at(was, e)).dot(step) < 0.5 * step.squaredNorm()) continue;
    const double contact = spec.contactDistance(entity_of[static_cast<size_t>(e)], entity_of[static_cast<size_t>(f)]);
    const double off = std::abs((at(now, e) - at(was, f)).norm() - contact);
    if (off < best) best = off, went = f;
  }
  return went;
}

}  // namespace

std::vector<int> detail::lastMoves(const task::TaskSpec& spec, const std::vector<int>& entity_of,
                                   const std::vector<Eigen::Vector2d>* history, size_t count) {
  const int n = static_cast<int>(entity_of.size());
  std::vector<int> last_went(static_cast<size_t>(n), -1);
  for (int e = 0; e < n; ++e)
    for (size_t k = count - 1; k >= 1; --k) {
      if ((history[k][static_cast<size_t>(e)] - history[k - 1][static_cast<size_t>(e)]).norm() <= spec.arrival_radius)
        continue;
      last_went[static_cast<size_t>(e)] = wentTo(spec, entity_of, history[k - 1], history[k], e, spec.arrival_radius);
      break;
    }
  return last_went;
}

/// What the relative features of one history hold whatever the competing entities: the
/// pairs' distances, who is parked, each entity's others in order of nearness (in groups
/// of equal distance), the last step's and each entity's last move.
struct PairRelations::Scene {
  int n = 0;
  bool relative_features = false;
  PairView v;
  std::vector<int> kind_of;  ///< [N] the entity's kind (task::EntityKind)
  std::vector<bool> parked;  ///< [N]
  /// [N][N] row r: the entities by their distance from r; group_end[r][k]: the end of the
  /// group of equal distances position k is in.
  std::vector<int> by_distance, group_end;
  std::vector<bool> went_to;   ///< [N][N] e went to f in the last step
  std::vector<int> last_went;  ///< [N] lastMoves

  size_t at(int r, int k) const { return static_cast<size_t>(r * n + k); }
};

PairRelations::PairRelations(const SequenceModel::Impl& model, const std::vector<Eigen::Vector2d>* history,
                             size_t count)
    : scene_(std::make_unique<Scene>()) {
  Scene& s = *scene_;
  const int n = s.n = model.cfg.nodes;
  if (count == 0) throw Error("relative features: no snapshot");
  s.relative_features = model.info.plan.relative_features;
  if (!s.relative_features) return;  // "Fixed order": the configuration reaches no decision
  const std::vector<Eigen::Vector2d>& pos = history[count - 1];
  const PairView& v = s.v = pairView(model.spec, model.order, pos, model.info.std[0]);  // isotropic for the scene
  s.kind_of.resize(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i)
    s.kind_of[static_cast<size_t>(i)] = static_cast<int>(model.spec.entities[model.order.task_of[i]].kind);
  // Parked entities (docs/tgn.md): one at one place with another has had its part (a robot
  // on the goal it drove to, a box picked up) and is no rival of the free ones in "the
  // nearest of its kind"; the parked ones rank among themselves (the boxes in hand, back
  // to front).
  s.parked.assign(static_cast<size_t>(n), false);
  if (model.info.plan.parked_out_of_ranks)
    for (int k = 0; k < n; ++k)
      for (int m = 0; m < n; ++m)
        if (m != k && v.dist(k, m) == 0.0) s.parked[static_cast<size_t>(k)] = true;
  s.by_distance.resize(static_cast<size_t>(n * n));
  s.group_end.resize(static_cast<size_t>(n * n));
  for (int r = 0; r < n; ++r) {
    const auto row = s.by_distance.begin() + r * n;
    std::iota(row, row + n, 0);
    std::sort(row, row + n, [&](int a, int b) { return v.dist(r, a) < v.dist(r, b); });
    for (int g = 0; g < n;) {
      int end = g;
      while (end < n && v.dist(r, row[end]) == v.dist(r, row[g])) ++end;
      std::fill(s.group_end.begin() + r * n + g, s.group_end.begin() + r * n + end, end);
      g = end;
    }
  }
  // The last step (from the previous snapshot): e went to f when its motion went to f
  // (wentTo) and it now stands where f stood (at one place with f's place as the step began).
  s.went_to.assign(static_cast<size_t>(n * n), false);
  if (count > 1) {
    const auto& was = history[count - 2];
    for (int e = 0; e < n; ++e) {
      const int f = wentTo(model.spec, model.order.task_of, was, pos, e, model.spec.arrival_radius);
      if (f >= 0 && (pos[e] - was[f]).norm() <= v.at(e, f)) s.went_to[s.at(e, f)] = true;
    }
  }
  s.last_went = detail::lastMoves(model.spec, model.order.task_of, history, count);
}

PairRelations::~PairRelations() = default;

void PairRelations::write(float* out, const std::vector<bool>* competing, const std::vector<int64_t>* rows) const {
  const Scene& s = *scene_;
  const int n = s.n;
  const size_t m = rows ? rows->size() : static_cast<size_t>(n);
  std::fill(out, out + m * n * kRelativeFeatures, 0.f);
  if (!s.relative_features || n == 0) return;
  // k is a rival of e: of its kind, not given its part yet, and free unless e is parked.
  // Whose rival k is depends on e's kind and whether e is parked: e's class, 2 kind (+1
  // parked). (Bytes, not vector<bool>: these are read n^2 times a token.)
  std::vector<uint8_t> rival(static_cast<size_t>(n), 1), parked(s.parked.begin(), s.parked.end());
  if (competing) std::copy(competing->begin(), competing->end(), rival.begin());
  const int* kind = s.kind_of.data();
  std::vector<int> class_of(static_cast<size_t>(n));
  for (int e = 0; e < n; ++e) class_of[static_cast<size_t>(e)] = 2 * kind[e] + parked[static_cast<size_t>(e)];
  const auto rivals = [&](int k, int e) {
    return rival[static_cast<size_t>(k)] && kind[k] == kind[e] &&
           (parked[static_cast<size_t>(e)] || !parked[static_cast<size_t>(k)]);
  };
  const int classes = 2 * (1 + *std::max_element(s.kind_of.begin(), s.kind_of.end()));
  std::vector<int> total(static_cast<size_t>(classes), 0), seen(static_cast<size_t>(classes));
  const auto count = [&](int* counts, int k) {  // k in the classes it is a rival in
    counts[2 * kind[k]] += rival[static_cast<size_t>(k)] & !parked[static_cast<size_t>(k)];
    counts[2 * kind[k] + 1] += rival[static_cast<size_t>(k)];  // the parked ones' rivals: all of the kind
  };
  for (int k = 0; k < n; ++k) count(total.data(), k);
  // nearer[r][e] (farther): how many of e's rivals lie nearer to r than e (farther); one
  // sweep of r's others in order of distance, a group of equal distances at a time.
  std::vector<int> nearer(static_cast<size_t>(n * n)), farther(static_cast<size_t>(n * n));
  for (int r = 0; r < n; ++r) {
    const int* row = s.by_distance.data() + r * n;
    std::fill(seen.begin(), seen.end(), 0);
    for (int g = 0; g < n;) {
      const int end = s.group_end[s.at(r, g)];
      for (int k = g; k < end; ++k) nearer[s.at(r, row[k])] = seen[static_cast<size_t>(class_of[row[k]])];
      for (int k = g; k < end; ++k) count(seen.data(), row[k]);
      for (int k = g; k < end; ++k) {
        const auto c = static_cast<size_t>(class_of[row[k]]);
        farther[s.at(r, row[k])] = total[c] - seen[c];
      }
      g = end;
    }
  }
  const std::vector<std::array<float, 4>> axis = axisOrders(s.v, rivals);
  for (size_t q = 0; q < m; ++q)
    for (int j = 0; j < n; ++j) {
      const int i = rows ? static_cast<int>((*rows)[q]) : static_cast<int>(q);
      if (i == j) continue;
      float* r = out + (q * n + j) * kRelativeFeatures;
      const double dij = s.v.dist(i, j);
      // How many entities of j's kind are nearer to i than j (and farther); of i's kind
      // nearer to j than i (and farther). Neither i nor j counts: j lies at dij from i (and
      // i from j), neither nearer nor farther, and each at distance 0 from itself.
      const int near_j = nearer[s.at(i, j)] - (rivals(i, j) && 0.0 < dij);
      const int near_i = nearer[s.at(j, i)] - (rivals(j, i) && 0.0 < dij);
      r[basis::kDistance] = static_cast<float>(dij);
      r[basis::kNearJ] = 1.f / static_cast<float>(1 + near_j);
      r[basis::kNearI] = 1.f / static_cast<float>(1 + near_i);
      r[basis::kFarJ] = 1.f / static_cast<float>(1 + farther[s.at(i, j)]);
      r[basis::kFarI] = 1.f / static_cast<float>(1 + farther[s.at(j, i)]);
      for (int a = 0; a < 4; ++a) {
        r[basis::kAxisJ + a] = axis[static_cast<size_t>(j)][a];
        r[basis::kAxisI + a] = axis[static_cast<size_t>(i)][a];
      }
      r[basis::kWentTo] = s.went_to[s.at(i, j)] ? 1.f : 0.f;
      r[basis::kCameFrom] = s.went_to[s.at(j, i)] ? 1.f : 0.f;
      r[basis::kLastMoveTo] = s.last_went[static_cast<size_t>(i)] == j ? 1.f : 0.f;
      r[basis::kLastMoveFrom] = s.last_went[static_cast<size_t>(j)] == i ? 1.f : 0.f;
    }
}

void SequenceModel::Impl::relative(const std::vector<Eigen::Vector2d>* history, size_t count, float* out,
                                   const std::vector<bool>* competing) const {
  PairRelations(*this, history, count).write(out, competing);
}

Sequence SequenceModel::Impl::keyframeSequence(const task::Demonstration& d) const {
  const int64_t t = static_cast<int64_t>(d.snapshots.size()), n = cfg.nodes;
  Sequence s;
  s.x = torch::zeros({t, n, cfg.features});
  s.action = torch::zeros({t, n}, torch::kLong);
  s.target = torch::zeros({t, n}, torch::kLong);
  s.end = torch::zeros({t}, torch::kLong);
  if (isScene()) {
    s.rel = torch::zeros({t, n, n, kRelativeFeatures});
    for (const auto& snapshot : d.snapshots) s.positions.push_back(snapshot.positions);
  }
  auto act = s.action.accessor<int64_t, 2>();
  auto tgt = s.target.accessor<int64_t, 2>();
  for (int64_t k = 0; k < t; ++k) {
    features(d.snapshots[k].positions, nullptr, s.x[k].data_ptr<float>());
    if (isScene()) relative(s.positions.data(), static_cast<size_t>(k) + 1, s.rel[k].data_ptr<float>());
    if (d.snapshots[k].end) {
      s.end[k] = 1;
      continue;
    }
    for (const auto& tok : d.steps.at(static_cast<size_t>(k)).tokens) {
      act[k][tok.entity] = vocabIndex(tok.action) + 1;
      tgt[k][tok.entity] = tok.target + 1;
    }
  }
  return s;
}

Sequence SequenceModel::Impl::frameSequence(const task::Demonstration& d) const {
  const int64_t t = static_cast<int64_t>(d.rows()) - 1, n = cfg.nodes;
  Sequence s;
  s.x = torch::zeros({t, n, cfg.features});
  s.action = torch::zeros({t, n}, torch::kLong);
  s.target = torch::zeros({t, n}, torch::kLong);
  s.end = torch::zeros({t}, torch::kLong);
  s.delta = torch::zeros({t, n, 2});
  auto act = s.action.accessor<int64_t, 2>();
  auto tgt = s.target.accessor<int64_t, 2>();
  auto del = s.delta.accessor<float, 3>();
  for (int64_t r = 0; r < t; ++r) {
    features(d.positions[r], &d.labels[r], s.x[r].data_ptr<float>());
    for (int64_t i = 0; i < n; ++i) {
      const task::Label& l = d.labels[r + 1][i];
      act[r][i] = l.isNull() ? 0 : vocabIndex(l.action) + 1;
      tgt[r][i] = l.isNull() ? 0 : l.target + 1;
      const Eigen::Vector2d dp = d.positions[r + 1][i] - d.positions[r][i];
      del[r][i][0] = static_cast<float>(dp.x() / info.delta_std[0]);
      del[r][i][1] = static_cast<float>(dp.y() / info.delta_std[1]);
    }
  }
  s.end[t - 1] = 1;
  return s;
}

std::vector<Sequence> SequenceModel::Impl::sequences(const std::vector<task::Demonstration>& demos) const {
  std::vector<Sequence> out;
  for (const auto& d : demos) {
    if (d.entities() != static_cast<size_t>(cfg.nodes))
      throw Error(Diagnostic{
          d.source, 0, 0,
          "has " + std::to_string(d.entities()) + " entities, the model's task has " + std::to_string(cfg.nodes)});
    for (const auto& step : d.steps)
      for (const auto& tok : step.tokens)
        if (vocabIndex(tok.action) < 0)
          throw Error(Diagnostic{d.source, 0, 0, "action '" + tok.action + "' is not in the model's vocabulary"});
    if (cfg.gnn) {
      if (d.rows() < 2) throw Error(Diagnostic{d.source, 0, 0, "needs at least two rows"});
      for (size_t r = 0; r < d.rows(); ++r) requireFinite(d.positions[r], spec, d.source, "row", r);
      out.push_back(frameSequence(order.toCanonical(d)));
    } else {
      for (size_t k = 0; k < d.snapshots.size(); ++k)
        requireFinite(d.snapshots[k].positions, spec, d.source, "snapshot", k);
      out.push_back(keyframeSequence(order.toCanonical(d)));
    }
  }
  return out;
}

Heads SequenceModel::Impl::run(const Batch& batch, Tensor* nodes_out, Tensor* z_out, int member) {
  if (!isScene()) {
    const Tensor emb = net->encode(batch.x);
    Tensor seq = torch::zeros({batch.b * batch.t, emb.size(1)}).index_copy(0, batch.slot, emb);
    return net->heads(fused::gru(net->gru, seq.view({batch.b, batch.t, emb.size(1)})).first);
  }
  SceneNetwork net = members().at(static_cast<size_t>(member));
  const Tensor nodes = net->encode(batch.x, batch.rel, batch.names);  // [S, N, W]
  const int64_t n = nodes.size(1), w = nodes.size(2), bt = batch.b * batch.t;
  const Tensor pooled = torch::zeros({bt, w}).index_copy(0, batch.slot, nodes.mean(1));
  const Tensor z = fused::gru(net->gru, pooled.view({batch.b, batch.t, w})).first;
  const Tensor slots = torch::zeros({bt, n, w}).index_copy(0, batch.slot, nodes).view({batch.b, batch.t, n, w});
  Heads h = net->heads(slots, batch.rel_slots, z);
  if (batch.taken.defined()) h.target = h.target + takenMask(batch.taken);
  if (nodes_out) *nodes_out = slots;
  if (z_out) *z_out = z;
  return h;
}

double SequenceModel::Impl::accuracy(const std::vector<Sequence>& seqs) {
  return accuracy(collateAll(seqs, cfg.gnn));
}

double SequenceModel::Impl::accuracy(const Batch& batch) {
  torch::NoGradGuard no_grad;
  module().eval();
  for (SceneNetwork o : others) o->eval();
  if (cfg.gnn) {
    const Tensor ok = correctOf(run(batch), batch, true).to(torch::kFloat) * batch.valid;
    return (ok.sum() / batch.valid.sum()).item<double>();
  }
  // Every step decoded as predictNext decodes it (decide(), an ensemble's majority): right
  // when END and, for a step, every entity's action and the acting entities' targets are.
  struct Outputs {
    Heads h;
    Tensor nodes, z, la, lt, p_end;
  };
  const bool scene = isScene(), by_token = info.plan.token_by_token;
  const DemonstratedTokens demonstrated = demonstratedTokens();
  std::vector<Outputs> out(scene ? 1 + others.size() : 1);
  for (size_t m = 0; m < out.size(); ++m) {
    Outputs& o = out[m];
    o.h = run(batch, scene ? &o.nodes : nullptr, scene ? &o.z : nullptr, static_cast<int>(m));
    o.la = torch::log_softmax(o.h.action, -1).to(torch::kDouble).contiguous();  // [B, T, N, A]
    o.lt = torch::log_softmax(o.h.target, -1).to(torch::kDouble).contiguous();  // [B, T, N, 1 + N]
    o.p_end = torch::softmax(o.h.end, -1).select(-1, 1).to(torch::kDouble).contiguous();
  }
  const int64_t n = cfg.nodes, actions = cfg.actions, targets = cfg.targets;
  auto valid = batch.valid.accessor<float, 2>();
  auto end = batch.end.accessor<int64_t, 2>();
  auto act = batch.action.accessor<int64_t, 3>();
  auto tgt = batch.target.accessor<int64_t, 3>();
  static const std::vector<Eigen::Vector2d> kNoPositions;
  double right = 0;
  for (int64_t b = 0; b < batch.b; ++b)
    for (int64_t t = 0; t < batch.t; ++t) {
      if (valid[b][t] == 0) continue;
      const int64_t slot = b * batch.t + t;
      std::vector<detail::StepDecision> decisions;
      for (size_t m = 0; m < out.size(); ++m) {
        const Outputs& o = out[m];
        const double* la0 = o.la.data_ptr<double>() + slot * n * actions;
        const double* lt0 = o.lt.data_ptr<double>() + slot * n * targets;
        const std::vector<double> la(la0, la0 + n * actions);
        std::vector<double> lt(lt0, lt0 + n * targets);
        decisions.push_back(decide(o.p_end.data_ptr<double>()[slot], la, lt, by_token ? o.h.target[b][t] : Tensor(),
                                   by_token ? o.nodes[b][t] : Tensor(), by_token ? o.z[b][t] : Tensor(),
                                   scene ? &batch.positions[static_cast<size_t>(b * batch.t)] : &kNoPositions,
                                   scene ? static_cast<size_t>(t) + 1 : 1, demonstrated, static_cast<int>(m)));
      }
      const detail::StepDecision& d = decisions[detail::majorityDecision(decisions)];
      bool ok = d.end == (end[b][t] == 1);
      for (int64_t i = 0; ok && !d.end && i < n; ++i) {
        const detail::DecodedToken& k = d.tokens[static_cast<size_t>(i)];
        ok = k.action == act[b][t][i] && (k.action == 0 || k.target == tgt[b][t][i]);
      }
      right += ok ? 1 : 0;
    }
  return right / batch.valid.sum().item<double>();
}

SequenceModel::SequenceModel(std::shared_ptr<Impl> impl) : impl_(std::move(impl)) {}
SequenceModel::~SequenceModel() = default;

const task::TaskSpec& SequenceModel::spec() const {
  return impl_->spec;
}
std::string SequenceModel::variant() const {
  return toString(impl_->info.variant);
}
const ModelInfo& SequenceModel::info() const {
  return impl_->info;
}

namespace {

/// Mean/std of positions over every entity (one std for both axes for the scene variant,
/// so that its distances are distances); frame_dt and displacement std for gnn.
void normalisation(const task::TaskDir& dir, Variant variant, ModelInfo& info) {
  const bool gnn = variant == Variant::Gnn;
  double sum[2] = {0, 0}, sq[2] = {0, 0}, dsq[2] = {0, 0};
  double count = 0, dcount = 0, dt = 0;
  for (const auto& d : dir.demos) {
    auto add = [&](const std::vector<Eigen::Vector2d>& pos) {
      for (const auto& p : pos)
        for (int c = 0; c < 2; ++c) {
          sum[c] += p[c];
          sq[c] += p[c] * p[c];
        }
      count += static_cast<double>(pos.size());
    };
    if (gnn) {
      for (size_t r = 0; r < d.rows(); ++r) {
        add(d.positions[r]);
        if (r + 1 < d.rows()) {
          for (size_t i = 0; i < d.entities(); ++i)
            for (int c = 0; c < 2; ++c) dsq[c] += std::pow(d.positions[r + 1][i][c] - d.positions[r][i][c], 2);
          dcount += static_cast<double>(d.entities());
          dt += d.t[r + 1] - d.t[r];
        }
      }
    } else {
      for (const auto& s : d.snapshots) add(s.positions);
    }
  }
  double var[2];
  for (int c = 0; c < 2; ++c) {
    info.mean[c] = sum[c] / count;
    var[c] = std::max(0.0, sq[c] / count - info.mean[c] * info.mean[c]);
    info.delta_std[c] = dcount > 0 ? std::max(1e-5, std::sqrt(dsq[c] / dcount)) : 1.0;
  }
  for (int c = 0; c < 2; ++c)
    info.std[c] = std::max(1e-3, std::sqrt(variant == Variant::Scene ? (var[0] + var[1]) / 2 : var[c]));
  // Every displacement is counted once per entity; dt once per row pair.
  const double pairs = dcount > 0 ? dcount / static_cast<double>(dir.spec.entities.size()) : 0;
  info.frame_dt_s = pairs > 0 ? dt / pairs : 0.05;
}

}  // namespace

std::shared_ptr<SequenceModel::Impl> prepare(const task::TaskDir& train, const TrainOptions& options) {
  options.validate();
  if (train.demos.empty()) throw Error(Diagnostic{train.path, 0, 0, "no demonstrations to train on"});
  auto impl = std::make_shared<SequenceModel::Impl>();
  impl->spec = train.spec;
  impl->order = EntityOrder(train.spec);
  ModelInfo& info = impl->info;
  info.variant = options.variant;
  info.options = options;
  info.options.refinement.seed = options.seed;
  info.vocabulary = train.vocabulary();
  info.fingerprint = task::fingerprintOf(train);
  const int n = static_cast<int>(train.spec.entities.size());
  size_t steps = 0;
  for (const auto& d : train.demos) {
    steps += d.steps.size();
    for (size_t r = 0; r < d.rows(); ++r) requireFinite(d.positions[r], train.spec, d.source, "row", r);
  }
  if (steps == 0) throw Error(Diagnostic{train.path, 0, 0, "the demonstrations have no steps (no labelled actions)"});
  // The refinement in canonical order (k-means seeding visits the nodes in order), mapped back.
  std::vector<task::Demonstration> canonical;
  for (const auto& d : train.demos) canonical.push_back(impl->order.toCanonical(d));
  info.refined = graph::permuted(graph::refine(canonical, n, info.options.refinement), impl->order.task_of);
  info.plan = planTraining(train, info.options, info.refined);
  info.dependencies = graph::learnDependencies(train.spec, train.demos);
  normalisation(train, options.variant, info);
  return impl;
}

}  // namespace ddace::tgn
