#include "ddace/label/label.h"

#include <algorithm>
#include <cstdio>
#include <set>

#include "ddace/common/error.h"

namespace ddace::label {

using Eigen::Vector2d;

namespace {

std::string kindOf(const task::Entity& e, bool typed) {
  std::string s = task::toString(e.kind);
  if (typed && !e.type.empty()) s += "/" + e.type;
  return s;
}

std::string key(const task::TaskSpec& spec, int mover, int target, int load, bool typed) {
  std::string s =
      kindOf(spec.entities[mover], typed) + ">" + (target >= 0 ? kindOf(spec.entities[target], typed) : "none");
  if (load == 1) s += "+load";
  if (load == 2) s += "+carried";
  return s;
}

/// "goal,robot": the kinds among `entities`, sorted, each once.
std::string tiedKinds(const task::TaskSpec& spec, const std::vector<int>& entities) {
  std::set<std::string> kinds;
  for (int e : entities) kinds.insert(task::toString(spec.entities[e].kind));
  std::string s;
  for (const auto& k : kinds) s += (s.empty() ? "" : ",") + k;
  return s;
}

std::string metres(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", v);
  return buf;
}

}  // namespace

std::string kindKey(const task::TaskSpec& spec, int mover, int target, int load) {
  return key(spec, mover, target, load, true);
}
std::string coarseKindKey(const task::TaskSpec& spec, int mover, int target, int load) {
  return key(spec, mover, target, load, false);
}

Labeller::Labeller(const task::TaskSpec& spec, const Example* example)
    : spec_(spec),
      example_(example),
      options_(SegmentationOptions::forTask(spec)),
      segmenter_(spec.entities.size(), options_) {}

void Labeller::row(double t, const std::vector<Vector2d>& positions) {
  segmenter_.row(t, positions);
  auto found = segmenter_.take();
  for (auto& m : found) motions_.push_back(std::move(m));
}

Inference Labeller::finish() {
  segmenter_.finish();
  for (auto& m : segmenter_.take()) motions_.push_back(std::move(m));
  Inference out;
  const auto& E = spec_.entities;
  const size_t n = E.size();
  const double r = spec_.arrival_radius;
  const int last_row = segmenter_.rows() - 1;
  auto note = [&](int row, const std::string& message) { out.notes.push_back({row, message}); };

  // A goal is a mark on the table: its motion (a print pushed aside) is no token.
  std::vector<Motion> ms;
  for (auto& m : motions_) {
    if (E[m.entity].kind == task::EntityKind::Goal)
      note(m.on_row, "goal " + E[m.entity].name + " moved " + metres((m.end - m.start).norm()) +
                         " m; a goal does not act, its motion is no token (check the marker)");
    else ms.push_back(std::move(m));
  }
  motions_.clear();
  // Entities that moved with a motion all the way (at most touching): its loads or carrier.
  auto staysWith = [&](const Motion& m, int j) {
    return m.max_distance[j] <= contactDistance(spec_, m.entity, j) + r &&
           (m.at_offset[j] - m.at_onset[j]).norm() >= options_.nudge_m;
  };
  auto candidatesOf = [&](const Motion& m) {
    std::vector<bool> c(n, true);
    for (size_t j = 0; j < n; ++j) c[j] = static_cast<int>(j) != m.entity && !staysWith(m, static_cast<int>(j));
    return c;
  };

  // 1. A pause: a motion that stopped away from every entity, or over one but goes on in
  // the heading it came in (not taking along what it stopped at), goes on within pause_s.
  auto pausedOnItsWay = [&](const Motion& a, const Motion& b) {
    const EndPoint ep = endPoint(spec_, a.entity, a.start, a.end, a.at_onset, candidatesOf(a));
    if (ep.target < 0) return true;
    if (a.end_dir.dot(b.start_dir) < std::cos(options_.heading_rad)) return false;
    // Went to an object and moves on with it: a fetch, then a carry.
    for (int c : ep.tied)
      if (staysWith(b, c)) return false;
    return !staysWith(b, ep.target);
  };
  std::stable_sort(ms.begin(), ms.end(), [](const Motion& a, const Motion& b) {
    return a.entity != b.entity ? a.entity < b.entity : a.on_row < b.on_row;
  });
  std::vector<Motion> merged;
  for (auto& m : ms) {
    if (!merged.empty() && merged.back().entity == m.entity) {
      Motion& a = merged.back();
      if (m.on_t - a.off_t <= options_.pause_s && pausedOnItsWay(a, m)) {
        a.off_row = m.off_row;
        a.off_t = m.off_t;
        a.end = m.end;
        a.end_dir = m.end_dir;
        a.at_offset = m.at_offset;
        for (size_t j = 0; j < n; ++j) a.max_distance[j] = std::max(a.max_distance[j], m.max_distance[j]);
        a.resumed = true;
        continue;
      }
    }
    merged.push_back(std::move(m));
  }
  std::stable_sort(merged.begin(), merged.end(), [](const Motion& a, const Motion& b) { return a.on_row < b.on_row; });

  // 2. Steps: motions that overlap in time; a step ends when every one of them has stopped.
  std::vector<std::vector<Motion>> groups;
  int max_off = -1;
  for (auto& m : merged) {
    if (groups.empty() || m.on_row > max_off) groups.emplace_back();
    max_off = std::max(max_off, m.off_row);
    // One token per entity and step: a second motion of the same entity joins its first.
    auto& g = groups.back();
    auto same = std::find_if(g.begin(), g.end(), [&](const Motion& o) { return o.entity == m.entity; });
    if (same != g.end()) {
      note(m.on_row, E[m.entity].name + " moved again in the same step (first motion ended at line " +
                         std::to_string(same->off_row + 2) + "); taken as one motion");
      same->off_row = m.off_row;
      same->off_t = m.off_t;
      same->end = m.end;
      same->end_dir = m.end_dir;
      same->at_offset = m.at_offset;
      for (size_t j = 0; j < n; ++j) same->max_distance[j] = std::max(same->max_distance[j], m.max_distance[j]);
      continue;
    }
    g.push_back(std::move(m));
  }

  // The example's steps: its motion steps, and the in-place-only steps before each of them.
  std::vector<const task::Step*> ex_motion;
  std::vector<std::vector<const task::Step*>> ex_inplace_before(1);
  bool ex_has_inplace = false;
  if (example_) {
    for (const auto& s : example_->steps) {
      const bool motion =
          std::any_of(s.tokens.begin(), s.tokens.end(), [](const task::Token& t) { return t.isMotion(); });
      for (const auto& t : s.tokens) ex_has_inplace = ex_has_inplace || !t.isMotion();
      if (motion) {
        ex_motion.push_back(&s);
        ex_inplace_before.emplace_back();
      } else {
        ex_inplace_before.back().push_back(&s);
      }
    }
  }
  bool aligned = example_ && ex_motion.size() == groups.size();
  for (size_t k = 0; aligned && k < groups.size(); ++k) {
    std::set<int> a, b;
    for (const auto& m : groups[k]) a.insert(m.entity);
    for (const auto& t : ex_motion[k]->tokens)
      if (t.isMotion()) b.insert(t.entity);
    aligned = a == b;
  }
  auto exampleTarget = [&](size_t k, int entity) {
    for (const auto& t : ex_motion[k]->tokens)
      if (t.entity == entity) return t.target;
    return -1;
  };
  if (example_ && ex_has_inplace && !aligned)
    note(0, "the example's in-place actions are not placed: this demonstration's motion has other steps than " +
                example_->source + "'s");

  // Action words: the example's, then task.yaml's action_rules (the first that matches),
  // else the task's first action (said when an example or rules were there to ask).
  auto rule = [&](int mover, int target, int load) -> const task::ActionRule* {
    for (const auto& r : spec_.action_rules)
      if (r.matches(E[mover], E[target], load)) return &r;
    return nullptr;
  };
  auto word = [&](int mover, int target, int load, int row) -> std::string {
    if (example_) {
      for (const auto& k : {kindKey(spec_, mover, target, load), coarseKindKey(spec_, mover, target, load)}) {
        auto it = example_->words.find(k);
        if (it != example_->words.end()) return it->second;
      }
    }
    if (const task::ActionRule* r = rule(mover, target, load)) return r->action;
    if (example_ || !spec_.action_rules.empty()) {
      std::string where;
      if (example_) where = "in the example " + example_->source;
      if (!spec_.action_rules.empty()) where += std::string(example_ ? " nor " : "") + "in task.yaml's action_rules";
      note(row, "no motion of the kind " + kindKey(spec_, mover, target, load) + " " + where +
                    "; took the task's first action");
    }
    return spec_.actions.empty() ? "move" : spec_.actions.front();
  };

  // In-place-only steps of the example, spread over the rows between two motion steps.
  auto placeInPlace = [&](const std::vector<const task::Step*>& steps, int from, int to) {
    const int count = static_cast<int>(steps.size());
    if (count == 0) return;
    const int span = to - from + 1;
    if (span < 2 * count + 1) {
      note(std::max(from, 0), "no still time to place the example's in-place step(s) here");
      return;
    }
    for (int j = 0; j < count; ++j) {
      InferredStep st;
      st.keyframe_row = from + span * (2 * j + 1) / (2 * count + 1);
      const int last = from + span * (2 * j + 2) / (2 * count + 1) - 1;
      for (const auto& t : steps[j]->tokens) {
        InferredToken it;
        it.token = t;
        it.first_row = it.onset_row = st.keyframe_row;
        it.last_row = std::max(last, st.keyframe_row);
        it.in_place = true;
        it.kind = "in-place";
        st.tokens.push_back(it);
      }
      out.steps.push_back(std::move(st));
    }
  };

  int prev_off = -1;
  for (size_t k = 0; k < groups.size(); ++k) {
    auto& g = groups[k];
    InferredStep step;
    step.keyframe_row = g.front().on_row;
    int step_off = 0;
    for (const auto& m : g)
      step.keyframe_row = std::min(step.keyframe_row, m.on_row), step_off = std::max(step_off, m.off_row);
    if (aligned) placeInPlace(ex_inplace_before[k], prev_off + 1, step.keyframe_row - 1);

    // 3. Loads: an object that stayed with a moving robot of the step all the way.
    std::vector<int> carrier(g.size(), -1);
    for (size_t i = 0; i < g.size(); ++i) {
      if (E[g[i].entity].kind != task::EntityKind::Object) continue;
      double best = 1e9;
      for (size_t j = 0; j < g.size(); ++j) {
        const int rb = g[j].entity;
        if (j == i || E[rb].kind != task::EntityKind::Robot || !staysWith(g[i], rb)) continue;
        if (g[i].max_distance[rb] < best) best = g[i].max_distance[rb], carrier[i] = static_cast<int>(j);
      }
    }
    // 4. Targets: carriers and lone movers first, then their loads.
    std::vector<InferredToken> tokens(g.size());
    for (int pass = 0; pass < 2; ++pass) {
      for (size_t i = 0; i < g.size(); ++i) {
        const Motion& m = g[i];
        const bool is_load = carrier[i] >= 0;
        if (is_load != (pass == 1)) continue;
        InferredToken& tok = tokens[i];
        tok.token.entity = m.entity;
        tok.first_row = step.keyframe_row;
        tok.onset_row = m.on_row;
        tok.last_row = m.off_row;
        const bool has_load = std::find(carrier.begin(), carrier.end(), static_cast<int>(i)) != carrier.end();
        tok.load = is_load ? 2 : has_load ? 1 : 0;
        if (is_load) {
          tok.carrier = g[carrier[i]].entity;
          tok.token.target = tokens[carrier[i]].token.target;
        } else {
          int load = -1;
          for (size_t j = 0; j < g.size() && load < 0; ++j)
            if (carrier[j] == static_cast<int>(i)) load = g[j].entity;
          const EndPoint ep = endPoint(spec_, m.entity, m.start, m.end, m.at_onset, candidatesOf(m), load);
          tok.token.target = ep.target;
          if (ep.target < 0) {
            tok.token.target = ep.nearest;
            if (ep.nearest >= 0)
              note(m.off_row, E[m.entity].name + " stopped halfway: " + metres(ep.nearest_m) + " m from " +
                                  E[ep.nearest].name + ", the nearest entity, taken as its target");
          } else if (!ep.tied.empty()) {
            std::vector<int> all = ep.tied;
            all.push_back(ep.target);
            tok.tied = all;
            bool resolved = false;
            if (aligned) {
              const int want = exampleTarget(k, m.entity);
              if (std::find(all.begin(), all.end(), want) != all.end()) tok.token.target = want, resolved = true;
            }
            if (!resolved && example_) {
              auto it = example_->tie_kind.find(tiedKinds(spec_, all));
              int found = -1, count = 0;
              if (it != example_->tie_kind.end())
                for (int c : all)
                  if (E[c].kind == it->second) found = c, ++count;
              if (count == 1) tok.token.target = found, resolved = true;
            }
            if (!resolved) {
              std::string names;
              for (int c : all) names += (names.empty() ? "" : " and ") + E[c].name;
              note(m.off_row, E[m.entity].name + " ended between " + names + " (the same distance within " +
                                  metres(r / 2) + " m); took " + E[ep.target].name);
            }
          }
        }
        if (tok.token.target < 0) continue;
        tok.kind = kindKey(spec_, m.entity, tok.token.target, tok.load);
        // An object moving alone is reported unless the example shows such a motion or a
        // rule of task.yaml names the word of an object's motion there.
        const task::ActionRule* object_rule = rule(m.entity, tok.token.target, tok.load);
        const bool object_rule_stated = object_rule && object_rule->mover_kind == task::EntityKind::Object;
        if (E[m.entity].kind == task::EntityKind::Object && !is_load &&
            !(example_ && example_->words.count(tok.kind)) && !object_rule_stated)
          note(m.on_row, "object " + E[m.entity].name + " moved alone (no robot with it) to " +
                             E[tok.token.target].name + "; check it");
        tok.token.action = word(m.entity, tok.token.target, tok.load, m.on_row);
      }
    }
    // 5. In-place actions of the aligned example step, for the entities that did not move.
    if (aligned)
      for (const auto& t : ex_motion[k]->tokens)
        if (!t.isMotion()) {
          InferredToken it;
          it.token = t;
          it.first_row = it.onset_row = step.keyframe_row;
          it.last_row = step_off;
          it.in_place = true;
          it.kind = "in-place";
          tokens.push_back(it);
        }
    for (auto& t : tokens)
      if (t.token.target >= 0 || t.in_place) step.tokens.push_back(std::move(t));
    std::sort(step.tokens.begin(), step.tokens.end(),
              [](const InferredToken& a, const InferredToken& b) { return a.token.entity < b.token.entity; });
    if (!step.tokens.empty()) out.steps.push_back(std::move(step));
    prev_off = step_off;
  }
  if (aligned) placeInPlace(ex_inplace_before.back(), prev_off + 1, last_row);
  std::stable_sort(out.notes.begin(), out.notes.end(), [](const Note& a, const Note& b) { return a.row < b.row; });
  return out;
}

Inference inferLabels(const task::Demonstration& d, const task::TaskSpec& spec, const Example* example) {
  Labeller l(spec, example);
  for (size_t i = 0; i < d.rows(); ++i) l.row(d.t[i], d.positions[i]);
  return l.finish();
}

Example Example::fromDemonstration(const task::Demonstration& d, const task::TaskSpec& spec) {
  Example ex;
  ex.source = d.source;
  ex.steps = d.steps;
  const Inference inf = inferLabels(d, spec, nullptr);
  std::map<std::string, std::map<std::string, int>> votes;
  for (const auto& step : inf.steps)
    for (const auto& t : step.tokens) {
      const int mid = (t.onset_row + t.last_row) / 2;
      const task::Label& l = d.labels[mid][t.token.entity];
      if (l.isNull() || l.target < 0) continue;
      // The word of a kind of motion: as labelled; the kind: as the motion shows it.
      ++votes[kindKey(spec, t.token.entity, l.target, t.load)][l.action];
      ++votes[coarseKindKey(spec, t.token.entity, l.target, t.load)][l.action];
      if (!t.tied.empty() && std::find(t.tied.begin(), t.tied.end(), l.target) != t.tied.end())
        ex.tie_kind[tiedKinds(spec, t.tied)] = spec.entities[l.target].kind;
    }
  for (const auto& [k, words] : votes) {
    auto best =
        std::max_element(words.begin(), words.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
    ex.words[k] = best->first;
  }
  if (ex.words.empty())
    throw Error(Diagnostic{d.source, 0, 0,
                           "the example has no labelled motion to take action words from (label its motions, "
                           "or leave --example out)"});
  return ex;
}

LabelCursor::LabelCursor(const Inference& inference, size_t entities) : labels_(entities) {
  for (const auto& s : inference.steps)
    for (const auto& t : s.tokens)
      spans_.push_back({t.first_row, t.last_row, t.token.entity, {t.token.action, t.token.target}});
  std::stable_sort(spans_.begin(), spans_.end(), [](const Span& a, const Span& b) { return a.first < b.first; });
}

const std::vector<task::Label>& LabelCursor::at(int row) {
  open_.erase(std::remove_if(open_.begin(), open_.end(), [&](const Span& s) { return s.last < row; }), open_.end());
  while (next_ < spans_.size() && spans_[next_].first <= row) open_.push_back(spans_[next_++]);
  std::fill(labels_.begin(), labels_.end(), task::Label{});
  for (const auto& s : open_)
    if (s.first <= row) labels_[s.entity] = s.label;
  return labels_;
}

void applyLabels(task::Demonstration& d, const Inference& inference) {
  LabelCursor cursor(inference, d.entities());
  d.has_label_columns.assign(d.entities(), false);
  for (const auto& s : inference.steps)
    for (const auto& t : s.tokens) d.has_label_columns[t.token.entity] = true;
  d.labels.resize(d.rows());
  for (size_t i = 0; i < d.rows(); ++i) d.labels[i] = cursor.at(static_cast<int>(i));
  d.analyze();
}

bool unlabelled(const task::Demonstration& d) {
  for (const auto& row : d.labels)
    for (const auto& l : row)
      if (!l.isNull()) return false;
  return true;
}

}  // namespace ddace::label
