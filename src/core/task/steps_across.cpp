// Step grouping across the demonstrations of one task (docs/task-format.md, "Step
// grouping", rule 6): steps a demonstration reads as its own, which the others show as one.
#include <algorithm>
#include <map>
#include <optional>
#include <set>

#include "ddace/task/demonstration.h"

namespace ddace::task {
namespace {

/// A step by the kinds of its tokens: per token "action mover-kind/type target-kind/type",
/// sorted (a multiset).
using Form = std::vector<std::string>;

std::string entityKind(const TaskSpec& spec, int e) {
  if (e < 0) return "-";
  const Entity& entity = spec.entities[static_cast<size_t>(e)];
  return std::string(toString(entity.kind)) + "/" + entity.type;
}

Form formOf(const std::vector<Token>& tokens, const TaskSpec& spec) {
  Form f;
  for (const Token& t : tokens)
    f.push_back(t.action + " " + entityKind(spec, t.entity) + " " + entityKind(spec, t.target));
  std::sort(f.begin(), f.end());
  return f;
}

std::set<int> entitiesOf(const Step& step) {
  std::set<int> e;
  for (const Token& t : step.tokens) {
    e.insert(t.entity);
    if (t.target >= 0) e.insert(t.target);
  }
  return e;
}

/// `part` is a sub-multiset of `whole` (both sorted).
bool within(const Form& part, const Form& whole) {
  return std::includes(whole.begin(), whole.end(), part.begin(), part.end());
}

Form joined(const Form& a, const Form& b) {
  Form f;
  std::merge(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(f));
  return f;
}

/// The runs that make `steps` read as `target` (one form per step), each run of steps
/// sharing no entity; nullopt when no such runs do. Each step of `target` takes the
/// fewest consecutive steps whose forms add up to it: a step adds at least one token, so
/// no other run can.
std::optional<std::vector<StepRun>> runsInto(const std::vector<Step>& steps, const std::vector<Form>& forms,
                                             const std::vector<Form>& target) {
  std::vector<StepRun> runs;
  size_t i = 0;
  for (const Form& want : target) {
    if (i == steps.size()) return std::nullopt;
    const size_t first = i;
    Form have = forms[i];
    std::set<int> entities = entitiesOf(steps[i]);
    for (++i; have != want; ++i) {
      if (i == steps.size() || !within(have, want)) return std::nullopt;
      const std::set<int> next = entitiesOf(steps[i]);
      if (std::any_of(next.begin(), next.end(), [&](int e) { return entities.count(e) > 0; })) return std::nullopt;
      entities.insert(next.begin(), next.end());
      have = joined(have, forms[i]);
    }
    if (i - 1 > first) runs.push_back({first, i - 1, 0, 0});
  }
  if (i != steps.size()) return std::nullopt;
  return runs;
}

}  // namespace

std::vector<std::vector<StepRun>> stepsShownAsOne(const std::vector<std::vector<Step>>& steps_of,
                                                  const TaskSpec& spec) {
  std::vector<std::vector<Form>> forms;
  for (const auto& steps : steps_of) {
    forms.emplace_back();
    for (const Step& s : steps) forms.back().push_back(formOf(s.tokens, spec));
  }
  std::map<std::vector<Form>, size_t> shown;  // demonstrations per sequence of forms
  for (const auto& f : forms) ++shown[f];
  std::vector<std::vector<StepRun>> out(steps_of.size());
  for (size_t d = 0; d < steps_of.size(); ++d) {
    const size_t own = shown[forms[d]];
    size_t best = own;
    // The sequence most demonstrations show (the first of them in demonstration order),
    // shown by more than the demonstration's own.
    for (size_t o = 0; o < steps_of.size(); ++o) {
      const size_t n = shown[forms[o]];
      if (n <= best || forms[o].size() >= forms[d].size()) continue;
      if (auto runs = runsInto(steps_of[d], forms[d], forms[o])) {
        best = n;
        for (StepRun& r : *runs) r.shown_by = n, r.demonstrations = steps_of.size();
        out[d] = std::move(*runs);
      }
    }
  }
  return out;
}

std::vector<Step> mergedSteps(const std::vector<Step>& steps, const std::vector<StepRun>& runs) {
  std::vector<Step> out;
  size_t r = 0;
  for (size_t k = 0; k < steps.size(); ++k) {
    const bool inside = r < runs.size() && k > runs[r].first && k <= runs[r].last;
    if (!inside) {
      out.push_back(steps[k]);
    } else {
      Step& into = out.back();
      const Step& s = steps[k];
      into.merged.push_back({s.keyframe_row, s.tokens, runs[r].shown_by, runs[r].demonstrations});
      into.tokens.insert(into.tokens.end(), s.tokens.begin(), s.tokens.end());
      std::sort(into.tokens.begin(), into.tokens.end());
      into.late.insert(into.late.end(), s.late.begin(), s.late.end());
    }
    if (r < runs.size() && k == runs[r].last) ++r;
  }
  return out;
}

void Demonstration::mergeSteps(const std::vector<StepRun>& runs) {
  if (runs.empty()) return;
  // The index of every step after merging.
  std::vector<int> index(steps.size());
  int next = -1;
  size_t r = 0;
  for (size_t k = 0; k < steps.size(); ++k) {
    const bool inside = r < runs.size() && k > runs[r].first && k <= runs[r].last;
    index[k] = inside ? next : ++next;
    if (r < runs.size() && k == runs[r].last) ++r;
  }
  steps = mergedSteps(steps, runs);
  keyframes.clear();
  for (const Step& s : steps) keyframes.push_back(s.keyframe_row);
  for (Segment& seg : segments) seg.step = index[static_cast<size_t>(seg.step)];
  std::stable_sort(segments.begin(), segments.end(), [](const Segment& a, const Segment& b) {
    return a.step != b.step ? a.step < b.step : a.token < b.token;
  });
  std::vector<Snapshot> kept;
  for (size_t k = 0; k < index.size(); ++k)
    if (k == 0 || index[k] != index[k - 1]) kept.push_back(snapshots[k]);
  kept.push_back(snapshots.back());  // END
  snapshots = std::move(kept);
}

}  // namespace ddace::task
