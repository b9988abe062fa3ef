// When each decided token of a run may start: the coordinator's dispatch rule.
//
//   steps  (the paper's): a token starts when every token of every earlier step has ended;
//          the next decision is asked for when every token has ended.
//   async: a token starts when its own predecessors have ended (graph/dependencies.h:
//          the earlier tokens it involves an entity of, and those people showed it
//          waiting for), never before. The next decision is asked for as soon as the last
//          one was made when the policy does not read the scene (a fixed order: its
//          decisions follow from the steps so far); a policy that reads the scene is asked
//          ahead once every step before the latest has ended: what it reads is then the
//          scene as it is and the end points of the latest step's tokens, so it decides
//          from the scene those will leave (predicted), and the decision holds only if the
//          scene settles as predicted (exec::Coordinator commits or withdraws it).
//
// Within a step, under either mode, a token may be held until others of its step have
// started (addStep's `start_after`): the coordinator holds a robot whose end is farther from
// a target than another robot's of the step bound for the same target, so places at one
// target are taken from the inside out, from a common start as demonstrated, not in the
// order the robots happen to be released.
//
// Dispatch keeps the record: when each token started and ended, whom it waited for, and
// the precedence violations of the record (a token that started before one of its
// predecessors under the learned dependencies ended), counted from the times alone so
// that a record of either mode can be checked.
//
// Owns: the precedence of a run's tokens and the record of their times. Must not: plan
// paths, talk to executors or read clocks (time comes in as `now_s`).
// Units: seconds.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "ddace/graph/dependencies.h"
#include "ddace/task/demonstration.h"
#include "ddace/task/task_spec.h"

namespace ddace::exec {

enum class DispatchMode : uint8_t { Steps = 0, Async = 1 };
/// "steps", "async".
const char* toString(DispatchMode mode);
/// Parses "steps" or "async"; throws ddace::Error naming `what` and the choices otherwise.
DispatchMode parseDispatchMode(const std::string& text, const std::string& what);

/// A token of a run: its step and its index in the step's tokens.
struct TokenRef {
  int step = 0;
  int index = 0;
  bool operator==(const TokenRef& o) const { return step == o.step && index == o.index; }
};

/// Whom a started token waited for: the predecessor whose end released it, and the token of
/// its own step it was held for after that (addStep's start_after).
struct Wait {
  TokenRef token;
  bool released = false;  ///< it had predecessors; released_by names the last to end
  TokenRef released_by;   ///< the predecessor that ended last before it started
  double ready_s = 0;     ///< when that predecessor ended (none: its step was decided)
  double start_s = 0;     ///< when it started (later than ready_s while held or awaiting a decision)
  bool held = false;      ///< a token of its step it starts after started later than ready_s
  TokenRef held_by;       ///< that token (the last of them to start)
};

class Dispatch {
 public:
  /// `deps`: the learned dependencies (a model's manifest); in steps mode they are only
  /// the measure of violations.
  Dispatch(task::TaskSpec spec, DispatchMode mode, graph::Dependencies deps);

  DispatchMode mode() const { return mode_; }
  /// Appends a decided step. Its tokens' predecessors are the earlier steps' tokens the
  /// mode makes them wait for; `start_after[i]` (empty: none) the indexes of tokens of the
  /// same step that must have started before token i starts. Throws ddace::Error for an
  /// index outside the step or a token held after itself.
  void addStep(const std::vector<task::Token>& tokens, double decided_s,
               const std::vector<std::vector<int>>& start_after = {});
  /// Forgets the last decided step (it is decided again from the scene as it is): its
  /// tokens that ran are no longer the run's. Throws ddace::Error when there is none.
  void withdrawLastStep();
  int steps() const { return static_cast<int>(steps_.size()); }
  const std::vector<task::Token>& tokens(int step) const;
  const task::Token& token(TokenRef t) const;
  /// The tokens `t` waits for under the mode.
  const std::vector<TokenRef>& predecessors(TokenRef t) const;
  /// Under the learned dependencies (what violations() checks against).
  std::vector<TokenRef> learnedPredecessors(TokenRef t) const;

  /// Not started, every predecessor has ended and every token of its step it starts after
  /// has started.
  bool ready(TokenRef t) const;
  /// Every ready token, in step then token order.
  std::vector<TokenRef> readyTokens() const;
  /// Records the start; throws ddace::Error when `t` is not ready (never starts a token
  /// before a predecessor ended).
  void start(TokenRef t, double now_s);
  /// Records the end; throws ddace::Error when `t` has not started or already ended.
  void end(TokenRef t, double now_s);
  bool started(TokenRef t) const;
  bool ended(TokenRef t) const;
  /// When `t` started, ended (`now_s` as given; -1: not yet).
  double startTime(TokenRef t) const { return at(t).start_s; }
  double endTime(TokenRef t) const { return at(t).end_s; }
  /// Every token of every step has ended.
  bool allEnded() const;
  /// Whether the next decision may be asked for now (see the header comment).
  bool mayDecide(bool policy_reads_scene) const;
  /// Every token of every step before `step` has ended (every step: allEnded()).
  bool settledBefore(int step) const;

  /// Tokens that started before one of their learned predecessors ended (from the times).
  int violations() const;
  /// From the first decision to the last end (0 before anything ended).
  double makespan() const;
  /// For every started token that had a predecessor or was held for a token of its step:
  /// who released it, who held it, and when (seconds from the first decision).
  std::vector<Wait> waits() const;

 private:
  struct Record {
    task::Token token;
    std::vector<TokenRef> predecessors;
    std::vector<int> start_after;  ///< tokens of its step that start before it
    double start_s = -1, end_s = -1;
  };
  Record& at(TokenRef t);
  const Record& at(TokenRef t) const;

  task::TaskSpec spec_;
  DispatchMode mode_;
  graph::Dependencies deps_;
  std::vector<std::vector<Record>> steps_;
  std::vector<std::vector<task::Token>> tokens_;
  std::vector<double> decided_s_;  ///< per step
  double first_decision_s_ = -1;
};

/// One token's time under a dispatch mode, in a schedule of known durations.
struct ScheduledToken {
  TokenRef token;
  double start_s = 0, end_s = 0;
};

/// The run of `steps` (decided in order, each token taking `durations[step][index]`
/// seconds once started, decisions taking no time) under `mode`: every token started as
/// soon as Dispatch allows it, every decision asked for as soon as mayDecide() allows.
/// For execution models whose motions do not interact (points), this is the run itself.
/// Fills `schedule` (may be null) and returns the Dispatch with its record.
Dispatch scheduleSteps(const task::TaskSpec& spec, const graph::Dependencies& deps, DispatchMode mode,
                       bool policy_reads_scene, const std::vector<std::vector<task::Token>>& steps,
                       const std::vector<std::vector<double>>& durations, std::vector<ScheduledToken>* schedule);

}  // namespace ddace::exec
