// "End scene" (docs/tgn.md): when a run is over, from what the last scene of every training
// demonstration had in common, counted by kind so that it holds for other team sizes. No torch.
#include <algorithm>
#include <map>
#include <set>
#include <string>

#include "ddace/task/end_point.h"
#include "ddace/tgn/detail.h"

namespace ddace::tgn::detail {

namespace {

/// How many entities of `c.kind` are with one of `c.with` in `counts` (endCountsOf).
int countHere(const std::map<std::pair<std::string, std::string>, int>& counts, const EndCount& c) {
  const auto it = counts.find({c.kind, c.with});
  return it == counts.end() ? 0 : it->second;
}

bool holds(const EndScene& end, const task::TaskSpec& spec, const std::vector<Eigen::Vector2d>& pos) {
  const auto counts = endCountsOf(spec, pos);
  return std::all_of(end.counts.begin(), end.counts.end(),
                     [&](const EndCount& c) { return countHere(counts, c) >= c.count; });
}

int ofKind(const task::TaskSpec& spec, const std::string& kind) {
  return static_cast<int>(std::count_if(spec.entities.begin(), spec.entities.end(),
                                        [&](const task::Entity& e) { return kindKey(e) == kind; }));
}

/// task::togetherDistance of every pair of `spec`'s entities, [N * N].
std::vector<double> togetherDistances(const task::TaskSpec& spec) {
  const int n = static_cast<int>(spec.entities.size());
  std::vector<double> together(static_cast<size_t>(n * n), 0.0);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      if (i != j) together[static_cast<size_t>(i * n + j)] = task::togetherDistance(spec, i, j);
  return together;
}

/// endCountsOf with entities at one place through neighbours too (placesOf): a carrier
/// behind the load it pushed onto a goal is at the goal.
std::map<std::pair<std::string, std::string>, int> placeCountsOf(const task::TaskSpec& spec,
                                                                 const std::vector<Eigen::Vector2d>& pos) {
  const std::vector<int> place_of = placesOf(pos, togetherDistances(spec));
  std::map<std::pair<std::string, std::string>, int> counts;
  for (size_t e = 0; e < pos.size(); ++e) {
    std::set<std::string> with;
    for (size_t f = 0; f < pos.size(); ++f)
      if (f != e && place_of[f] == place_of[e]) with.insert(kindKey(spec.entities[f]));
    for (const auto& w : with) ++counts[{kindKey(spec.entities[e]), w}];
  }
  return counts;
}

}  // namespace

std::vector<int> placesOf(const std::vector<Eigen::Vector2d>& pos, const std::vector<double>& together) {
  const int n = static_cast<int>(pos.size());
  std::vector<int> place_of(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) place_of[static_cast<size_t>(i)] = i;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j)
      if ((pos[static_cast<size_t>(j)] - pos[static_cast<size_t>(i)]).norm() <=
          together[static_cast<size_t>(i * n + j)]) {
        const int a = place_of[static_cast<size_t>(i)], b = place_of[static_cast<size_t>(j)];
        if (a != b)
          for (int& p : place_of) p = p == std::max(a, b) ? std::min(a, b) : p;
      }
  return place_of;
}

std::map<std::pair<std::string, std::string>, int> endCountsOf(const task::TaskSpec& spec,
                                                               const std::vector<Eigen::Vector2d>& pos) {
  const int n = static_cast<int>(spec.entities.size());
  const std::vector<double> together = togetherDistances(spec);
  std::map<std::pair<std::string, std::string>, int> counts;
  for (int e = 0; e < n; ++e) {
    std::set<std::string> with;
    for (int f = 0; f < n; ++f)
      if (f != e && (pos[static_cast<size_t>(f)] - pos[static_cast<size_t>(e)]).norm() <=
                        together[static_cast<size_t>(e * n + f)])
        with.insert(kindKey(spec.entities[static_cast<size_t>(f)]));
    for (const auto& w : with) ++counts[{kindKey(spec.entities[static_cast<size_t>(e)]), w}];
  }
  return counts;
}

EndScene endSceneOf(const task::TaskDir& train) {
  EndScene end;
  if (train.demos.size() < 2) return end;  // one demonstration shows nothing in common yet
  std::map<std::pair<std::string, std::string>, int> least;
  for (size_t d = 0; d < train.demos.size(); ++d) {
    const auto counts = endCountsOf(train.spec, train.demos[d].snapshots.back().positions);
    if (d == 0) least = counts;
    for (auto& [pair, count] : least) {
      const auto it = counts.find(pair);
      count = std::min(count, it == counts.end() ? 0 : it->second);
    }
  }
  for (const auto& [pair, count] : least)
    if (count > 0) end.counts.push_back({pair.first, pair.second, count});
  if (end.counts.empty()) return end;
  // Telling: no scene before a demonstration's last had every count.
  end.telling = std::none_of(train.demos.begin(), train.demos.end(), [&](const task::Demonstration& d) {
    return std::any_of(d.snapshots.begin(), d.snapshots.end() - 1,
                       [&](const task::Snapshot& s) { return holds(end, train.spec, s.positions); });
  });
  return end;
}

int followedCount(int count, const std::vector<std::pair<int, int>>& trained_and_other) {
  int followed = -1;
  for (const auto& [trained, other] : trained_and_other)
    if (count == trained) followed = followed < 0 ? other : std::min(followed, other);
  return followed;
}

EndScene endSceneFor(const EndScene& end, const task::TaskSpec& trained, const task::TaskSpec& other,
                     std::vector<bool>& waits) {
  EndScene out;
  out.telling = end.telling;
  waits.clear();
  // A count grows with the team only as far as every kind it equalled in training grew: boxes
  // carried by 2 robots with 2 boxes to 2 goals, run with 4 robots, 2 boxes and 4 goals, end
  // with 2 robots at goals, not 4. It shrinks with its own kinds only: with a robot lost,
  // the 2 boxes still end at goals.
  std::set<std::string> kinds;
  for (const auto& e : trained.entities) kinds.insert(kindKey(e));
  std::vector<std::pair<int, int>> every;
  for (const std::string& kind : kinds) every.push_back({ofKind(trained, kind), ofKind(other, kind)});
  for (const EndCount& c : end.counts) {
    const int kind_other = ofKind(other, c.kind);
    int followed = followedCount(
        c.count, {{ofKind(trained, c.kind), kind_other}, {ofKind(trained, c.with), ofKind(other, c.with)}});
    if (followed > c.count) followed = std::max(c.count, followedCount(c.count, every));
    // With another of its own kind: none where the kind has one entity.
    const int most = c.kind == c.with && kind_other < 2 ? 0 : kind_other;
    const int count = std::min(followed >= 0 ? followed : c.count, most);
    if (count <= 0) continue;
    out.counts.push_back({c.kind, c.with, count});
    waits.push_back(count > c.count);
  }
  if (out.counts.empty()) out.telling = false;
  return out;
}

double endProbability(double p, const EndScene& end, const std::vector<bool>& waits, const task::TaskSpec& spec,
                      const std::vector<Eigen::Vector2d>& pos) {
  if (end.counts.empty()) return p;
  const auto counts = endCountsOf(spec, pos);
  bool all = true;
  for (size_t k = 0; k < end.counts.size(); ++k) {
    const EndCount& c = end.counts[k];
    const bool has = countHere(counts, c) >= c.count;
    if (!has && k < waits.size() && waits[k]) return 0.0;  // the team is larger: the END head's count is short
    all = all && has;
  }
  return end.telling && all ? 1.0 : p;
}

std::string endSceneShort(const EndScene& end, const task::TaskSpec& spec, const std::vector<Eigen::Vector2d>& pos) {
  if (end.counts.empty()) return "";
  // Through neighbours: with bodies a carrier stops behind its load, short of the goal the
  // demonstrations' carriers reached with it; that is no task left undone.
  const auto counts = placeCountsOf(spec, pos);
  std::string lacks;
  for (const EndCount& c : end.counts) {
    const int here = countHere(counts, c);
    if (here >= c.count) continue;
    lacks += (lacks.empty() ? "" : "; ") + std::to_string(c.count) + " " + c.kind + " with " +
             (c.kind == c.with ? "another" : c.with) + " (" + std::to_string(here) + " here)";
  }
  return lacks;
}

}  // namespace ddace::tgn::detail
