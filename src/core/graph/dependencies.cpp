// The precedence between tokens (include/ddace/graph/dependencies.h).
#include "ddace/graph/dependencies.h"

#include <algorithm>
#include <map>
#include <tuple>
#include <utility>

#include <yaml-cpp/yaml.h>

#include "ddace/common/error.h"
#include "ddace/common/yaml_checker.h"
#include "ddace/task/end_point.h"

namespace ddace::graph {

std::vector<int> involvedEntities(const task::TaskSpec& spec, const std::vector<task::Token>& step, size_t i) {
  const task::Token& t = step.at(i);
  std::vector<int> out{t.entity};
  if (t.target >= 0) out.push_back(t.target);
  const int load = task::carriedLoad(spec, step, i);
  if (load >= 0) out.push_back(step[static_cast<size_t>(load)].entity);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

bool shareEntities(const task::TaskSpec& spec, const std::vector<task::Token>& later, size_t i,
                   const std::vector<task::Token>& earlier, size_t j) {
  const std::vector<int> a = involvedEntities(spec, later, i), b = involvedEntities(spec, earlier, j);
  for (int e : a)
    if (std::binary_search(b.begin(), b.end(), e)) return true;
  return false;
}

bool Dependencies::waitsFor(const task::TaskSpec& spec, const std::vector<task::Token>& later, size_t i,
                            const std::vector<task::Token>& earlier, size_t j) const {
  if (!learned || shareEntities(spec, later, i, earlier, j)) return true;
  const WaitEvidence* e = find(task::tokenKey(later[i], spec), task::tokenKey(earlier[j], spec));
  return e != nullptr && e->waits();
}

const WaitEvidence* Dependencies::find(const std::string& token, const std::string& after) const {
  const auto it = std::lower_bound(evidence.begin(), evidence.end(), std::make_pair(token, after),
                                   [](const WaitEvidence& e, const std::pair<std::string, std::string>& k) {
                                     return std::tie(e.token, e.after) < std::tie(k.first, k.second);
                                   });
  return it != evidence.end() && it->token == token && it->after == after ? &*it : nullptr;
}

namespace {

/// Index of `token` in `step` (sorted by entity: each entity once).
size_t indexIn(const std::vector<task::Token>& step, const task::Token& token) {
  for (size_t i = 0; i < step.size(); ++i)
    if (step[i] == token) return i;
  throw Error("a segment's token is not in its step");
}

}  // namespace

Dependencies learnDependencies(const task::TaskSpec& spec, const std::vector<task::Demonstration>& demos) {
  Dependencies deps;
  deps.learned = true;
  deps.demonstrations = static_cast<int>(demos.size());
  std::map<std::pair<std::string, std::string>, WaitEvidence> pairs;
  for (const task::Demonstration& d : demos) {
    // Per demonstration each pair counts once (a key may recur in a demonstration).
    std::map<std::pair<std::string, std::string>, std::pair<bool, bool>> seen;  // (waited, early)
    for (const task::Segment& b : d.segments) {
      const auto& b_step = d.steps.at(static_cast<size_t>(b.step)).tokens;
      const size_t bi = indexIn(b_step, b.token);
      // When B was free to start: every token it involves an entity of had ended.
      int ready_row = -1;
      for (const task::Segment& a : d.segments)
        if (a.step < b.step && shareEntities(spec, b_step, bi, d.steps[static_cast<size_t>(a.step)].tokens,
                                             indexIn(d.steps[static_cast<size_t>(a.step)].tokens, a.token)))
          ready_row = std::max(ready_row, a.last_row);
      for (const task::Segment& a : d.segments) {
        if (a.step >= b.step) continue;
        const auto& a_step = d.steps[static_cast<size_t>(a.step)].tokens;
        if (shareEntities(spec, b_step, bi, a_step, indexIn(a_step, a.token))) continue;
        const bool early = b.first_row <= a.last_row;
        const bool waited = !early && a.last_row > ready_row;
        if (!early && !waited) continue;
        auto& s = seen[{task::tokenKey(b.token, spec), task::tokenKey(a.token, spec)}];
        s.first = s.first || waited;
        s.second = s.second || early;
      }
    }
    for (const auto& [keys, s] : seen) {
      WaitEvidence& e = pairs[keys];
      e.token = keys.first;
      e.after = keys.second;
      // A demonstration where the key pair recurs both ways counts as early: it did not need it.
      if (s.second) ++e.started_early;
      else if (s.first) ++e.shown_waiting;
    }
  }
  for (auto& [keys, e] : pairs) deps.evidence.push_back(std::move(e));
  return deps;
}

void emitDependencies(YAML::Emitter& y, const Dependencies& deps) {
  y << YAML::BeginMap;
  y << YAML::Key << "demonstrations" << YAML::Value << deps.demonstrations;
  y << YAML::Key << "pairs" << YAML::Value << YAML::BeginSeq;
  for (const WaitEvidence& e : deps.evidence) {
    y << YAML::Flow << YAML::BeginMap;
    y << YAML::Key << "token" << YAML::Value << e.token;
    y << YAML::Key << "after" << YAML::Value << e.after;
    y << YAML::Key << "shown_waiting" << YAML::Value << e.shown_waiting;
    y << YAML::Key << "started_early" << YAML::Value << e.started_early;
    y << YAML::Key << "waits" << YAML::Value << e.waits();
    y << YAML::EndMap;
  }
  y << YAML::EndSeq;
  y << YAML::EndMap;
}

Dependencies parseDependencies(const YAML::Node& node, const std::string& path, const task::TaskSpec& spec) {
  YamlChecker c(path);
  Dependencies deps;
  deps.learned = true;
  if (!c.expectMap(node, "dependencies")) c.throwIfErrors();
  c.onlyKeys(node, {"demonstrations", "pairs"}, "dependencies");
  if (const YAML::Node n = c.required(node, "demonstrations", "dependencies: "))
    c.integer(n, "dependencies: demonstrations", 0, 1 << 30, deps.demonstrations);
  const YAML::Node pairs = c.required(node, "pairs", "dependencies: ");
  if (pairs && !pairs.IsSequence()) c.error(pairs, "dependencies: pairs must be a list");
  c.throwIfErrors();
  const auto key = [&](const YAML::Node& n, const std::string& what, std::string& out) {
    if (!c.scalar(n, what, out)) return;
    try {
      task::parseTokenKey(out, spec);
    } catch (const Error& e) {
      c.error(n, what + ": " + e.what());
    }
  };
  for (const YAML::Node& p : pairs) {
    WaitEvidence e;
    bool waits = false;
    if (!c.expectMap(p, "a dependency pair")) continue;
    c.onlyKeys(p, {"token", "after", "shown_waiting", "started_early", "waits"}, "a dependency pair");
    if (const YAML::Node n = c.required(p, "token")) key(n, "token", e.token);
    if (const YAML::Node n = c.required(p, "after")) key(n, "after", e.after);
    if (const YAML::Node n = c.required(p, "shown_waiting"))
      c.integer(n, "shown_waiting (at most the demonstrations)", 0, deps.demonstrations, e.shown_waiting);
    if (const YAML::Node n = c.required(p, "started_early"))
      c.integer(n, "started_early (at most the demonstrations)", 0, deps.demonstrations, e.started_early);
    if (const YAML::Node n = c.required(p, "waits"); n && c.boolean(n, "waits", waits) && waits != e.waits())
      c.error(n, "waits: " + std::string(waits ? "true" : "false") + " contradicts shown_waiting " +
                     std::to_string(e.shown_waiting) + " and started_early " + std::to_string(e.started_early));
    if (!deps.evidence.empty() &&
        !(std::tie(deps.evidence.back().token, deps.evidence.back().after) < std::tie(e.token, e.after)))
      c.error(p, "dependency pairs must be sorted by token and after, each pair once");
    deps.evidence.push_back(std::move(e));
  }
  c.throwIfErrors();
  return deps;
}

}  // namespace ddace::graph
