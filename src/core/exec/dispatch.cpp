// The coordinator's dispatch rule (include/ddace/exec/dispatch.h).
#include "ddace/exec/dispatch.h"

#include <algorithm>
#include <limits>
#include <utility>

#include "ddace/common/error.h"

namespace ddace::exec {

const char* toString(DispatchMode mode) {
  return mode == DispatchMode::Async ? "async" : "steps";
}

DispatchMode parseDispatchMode(const std::string& text, const std::string& what) {
  if (text == "steps") return DispatchMode::Steps;
  if (text == "async") return DispatchMode::Async;
  throw Error(what + " '" + text + "' is not one of steps, async");
}

Dispatch::Dispatch(task::TaskSpec spec, DispatchMode mode, graph::Dependencies deps)
    : spec_(std::move(spec)), mode_(mode), deps_(std::move(deps)) {}

void Dispatch::addStep(const std::vector<task::Token>& tokens, double decided_s,
                       const std::vector<std::vector<int>>& start_after) {
  if (!start_after.empty() && start_after.size() != tokens.size())
    throw Error("dispatch: one list of tokens to start after per token of the step");
  for (size_t i = 0; i < start_after.size(); ++i)
    for (int j : start_after[i])
      if (j < 0 || j >= static_cast<int>(tokens.size()) || j == static_cast<int>(i))
        throw Error("dispatch: token " + std::to_string(i) + " of the step cannot start after token " +
                    std::to_string(j));
  if (first_decision_s_ < 0) first_decision_s_ = decided_s;
  const int k = steps();
  tokens_.push_back(tokens);
  std::vector<Record> records(tokens.size());
  for (size_t i = 0; i < tokens.size(); ++i) {
    records[i].token = tokens[i];
    if (!start_after.empty()) records[i].start_after = start_after[i];
    for (int s = 0; s < k; ++s)
      for (size_t j = 0; j < tokens_[static_cast<size_t>(s)].size(); ++j)
        if (mode_ == DispatchMode::Steps || deps_.waitsFor(spec_, tokens, i, tokens_[static_cast<size_t>(s)], j))
          records[i].predecessors.push_back({s, static_cast<int>(j)});
  }
  steps_.push_back(std::move(records));
  decided_s_.push_back(decided_s);
}

void Dispatch::withdrawLastStep() {
  if (steps_.empty()) throw Error("dispatch: no step to withdraw");
  steps_.pop_back();
  tokens_.pop_back();
  decided_s_.pop_back();
}

const std::vector<task::Token>& Dispatch::tokens(int step) const {
  return tokens_.at(static_cast<size_t>(step));
}

Dispatch::Record& Dispatch::at(TokenRef t) {
  return steps_.at(static_cast<size_t>(t.step)).at(static_cast<size_t>(t.index));
}

const Dispatch::Record& Dispatch::at(TokenRef t) const {
  return steps_.at(static_cast<size_t>(t.step)).at(static_cast<size_t>(t.index));
}

const task::Token& Dispatch::token(TokenRef t) const {
  return at(t).token;
}

const std::vector<TokenRef>& Dispatch::predecessors(TokenRef t) const {
  return at(t).predecessors;
}

std::vector<TokenRef> Dispatch::learnedPredecessors(TokenRef t) const {
  std::vector<TokenRef> out;
  const auto& later = tokens(t.step);
  for (int s = 0; s < t.step; ++s)
    for (size_t j = 0; j < tokens(s).size(); ++j)
      if (deps_.waitsFor(spec_, later, static_cast<size_t>(t.index), tokens(s), j))
        out.push_back({s, static_cast<int>(j)});
  return out;
}

bool Dispatch::started(TokenRef t) const {
  return at(t).start_s >= 0;
}

bool Dispatch::ended(TokenRef t) const {
  return at(t).end_s >= 0;
}

bool Dispatch::ready(TokenRef t) const {
  if (started(t)) return false;
  for (const TokenRef& p : predecessors(t))
    if (!ended(p)) return false;
  for (int j : at(t).start_after)
    if (!started({t.step, j})) return false;
  return true;
}

std::vector<TokenRef> Dispatch::readyTokens() const {
  std::vector<TokenRef> out;
  for (int s = 0; s < steps(); ++s)
    for (int i = 0; i < static_cast<int>(steps_[static_cast<size_t>(s)].size()); ++i)
      if (ready({s, i})) out.push_back({s, i});
  return out;
}

void Dispatch::start(TokenRef t, double now_s) {
  if (!ready(t))
    throw Error("dispatch: " + task::tokenKey(token(t), spec_) + " of step " + std::to_string(t.step + 1) +
                (started(t) ? " has already started" : " is not ready: a predecessor has not ended"));
  at(t).start_s = now_s;
}

void Dispatch::end(TokenRef t, double now_s) {
  if (!started(t) || ended(t))
    throw Error("dispatch: " + task::tokenKey(token(t), spec_) + " of step " + std::to_string(t.step + 1) +
                (started(t) ? " has already ended" : " has not started"));
  at(t).end_s = now_s;
}

bool Dispatch::allEnded() const {
  for (const auto& step : steps_)
    for (const Record& r : step)
      if (r.end_s < 0) return false;
  return true;
}

bool Dispatch::settledBefore(int step) const {
  for (int s = 0; s < std::min(step, steps()); ++s)
    for (const Record& r : steps_[static_cast<size_t>(s)])
      if (r.end_s < 0) return false;
  return true;
}

bool Dispatch::mayDecide(bool policy_reads_scene) const {
  if (mode_ == DispatchMode::Steps) return allEnded();
  return !policy_reads_scene || settledBefore(steps() - 1);
}

int Dispatch::violations() const {
  int n = 0;
  for (int s = 0; s < steps(); ++s)
    for (int i = 0; i < static_cast<int>(steps_[static_cast<size_t>(s)].size()); ++i) {
      const Record& r = at({s, i});
      if (r.start_s < 0) continue;
      for (const TokenRef& p : learnedPredecessors({s, i}))
        if (at(p).end_s < 0 || at(p).end_s > r.start_s) ++n;
    }
  return n;
}

double Dispatch::makespan() const {
  double last = -1;
  for (const auto& step : steps_)
    for (const Record& r : step) last = std::max(last, r.end_s);
  return last < 0 ? 0 : last - first_decision_s_;
}

std::vector<Wait> Dispatch::waits() const {
  std::vector<Wait> out;
  for (int s = 0; s < steps(); ++s)
    for (int i = 0; i < static_cast<int>(steps_[static_cast<size_t>(s)].size()); ++i) {
      const Record& r = at({s, i});
      if (r.start_s < 0 || (r.predecessors.empty() && r.start_after.empty())) continue;
      Wait w;
      w.token = {s, i};
      w.released = !r.predecessors.empty();
      w.ready_s = w.released ? -std::numeric_limits<double>::infinity() : decided_s_[static_cast<size_t>(s)];
      for (const TokenRef& p : r.predecessors)
        if (at(p).end_s > w.ready_s) w.ready_s = at(p).end_s, w.released_by = p;
      double held_s = w.ready_s;
      for (int j : r.start_after)
        if (at({s, j}).start_s > held_s) held_s = at({s, j}).start_s, w.held = true, w.held_by = {s, j};
      if (!w.held && !w.released) continue;  // neither released nor held: nothing waited
      w.ready_s -= first_decision_s_;
      w.start_s = r.start_s - first_decision_s_;
      out.push_back(w);
    }
  return out;
}

Dispatch scheduleSteps(const task::TaskSpec& spec, const graph::Dependencies& deps, DispatchMode mode,
                       bool policy_reads_scene, const std::vector<std::vector<task::Token>>& steps,
                       const std::vector<std::vector<double>>& durations, std::vector<ScheduledToken>* schedule) {
  if (durations.size() != steps.size()) throw Error("scheduleSteps: one list of durations per step");
  Dispatch d(spec, mode, deps);
  std::vector<ScheduledToken> running;
  size_t decided = 0;
  double now = 0;
  while (true) {
    // Decide what may be decided, start what may start (decisions take no time).
    while (decided < steps.size() && (decided == 0 || d.mayDecide(policy_reads_scene))) {
      if (durations[decided].size() != steps[decided].size())
        throw Error("scheduleSteps: one duration per token of step " + std::to_string(decided + 1));
      d.addStep(steps[decided], now);
      ++decided;
    }
    for (std::vector<TokenRef> ready = d.readyTokens(); !ready.empty(); ready = d.readyTokens())
      for (const TokenRef& t : ready) {
        d.start(t, now);
        running.push_back({t, now, now + durations[static_cast<size_t>(t.step)][static_cast<size_t>(t.index)]});
      }
    if (running.empty()) break;
    // The next end.
    const auto next = std::min_element(running.begin(), running.end(), [](const auto& a, const auto& b) {
      return a.end_s < b.end_s ||
             (a.end_s == b.end_s &&
              (a.token.step < b.token.step || (a.token.step == b.token.step && a.token.index < b.token.index)));
    });
    now = next->end_s;
    d.end(next->token, now);
    if (schedule) schedule->push_back(*next);
    running.erase(next);
  }
  return d;
}

}  // namespace ddace::exec
