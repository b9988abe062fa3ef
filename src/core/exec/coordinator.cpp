#include "ddace/exec/coordinator.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace {
std::string seconds(double s) {
  std::ostringstream os;
  os << s << " s";
  return os.str();
}
}  // namespace

#include "ddace/common/error.h"
#include "ddace/exec/push_path.h"
#include "ddace/exec/ride_path.h"
#include "ddace/exec/table_simulator.h"

namespace ddace::exec {

const char* toString(RunState s) {
  switch (s) {
    case RunState::Idle:
      return "idle";
    case RunState::WaitingForEntities:
      return "waiting_for_entities";
    case RunState::Deciding:
      return "deciding";
    case RunState::Planning:
      return "planning";
    case RunState::Executing:
      return "executing";
    case RunState::Paused:
      return "paused";
    case RunState::Finished:
      return "finished";
    case RunState::Aborted:
      return "aborted";
    case RunState::EStopped:
      return "estopped";
  }
  return "?";
}

const char* toString(SegmentState s) {
  switch (s) {
    case SegmentState::Sent:
      return "sent";
    case SegmentState::Accepted:
      return "accepted";
    case SegmentState::Running:
      return "running";
    case SegmentState::Done:
      return "done";
    case SegmentState::Failed:
      return "failed";
    case SegmentState::Aborted:
      return "aborted";
  }
  return "?";
}

void CoordinatorConfig::validate() const {
  auto positive = [](double v, const char* name) {
    if (!(v > 0) || !std::isfinite(v))
      throw Error(std::string("coordinator parameter '") + name + "' must be positive");
  };
  positive(decision_timeout_s, "decision_timeout_s");
  positive(path_timeout_s, "path_timeout_s");
  positive(segment_timeout_s, "segment_timeout_s");
  if (!(segment_timeout_per_m_s >= 0) || !std::isfinite(segment_timeout_per_m_s))
    throw Error("coordinator parameter 'segment_timeout_per_m_s' must be >= 0");
  if (max_steps < 1) throw Error("coordinator parameter 'max_steps' must be at least 1");
  positive(arrival_radius_m, "arrival_radius_m");
  if (!(arrival_tolerance_m >= 0) || !std::isfinite(arrival_tolerance_m))
    throw Error("coordinator parameter 'arrival_tolerance_m' must be >= 0");
  if (max_replans < 0) throw Error("coordinator parameter 'max_replans' must be >= 0");
  positive(robot_lost_after_s, "robot_lost_after_s");
}

uint32_t firstIdAt(double wall_clock_s) {
  if (!std::isfinite(wall_clock_s) || wall_clock_s < 0) return 1;
  const auto ms = static_cast<uint64_t>(wall_clock_s * 1000.0);
  const auto id = static_cast<uint32_t>(ms & 0x7fffffffu);
  return id == 0 ? 1 : id;
}

Coordinator::Coordinator(task::TaskSpec spec, CoordinatorConfig config, task::EndPointModel end_points,
                         uint32_t first_id, graph::Dependencies dependencies, bool policy_reads_scene)
    : spec_(std::move(spec)),
      config_(config),
      end_points_(std::move(end_points)),
      dependencies_(std::move(dependencies)),
      policy_reads_scene_(policy_reads_scene),
      next_id_(first_id == 0 ? 1 : first_id) {
  config_.validate();
  if (spec_.entities.empty()) throw Error("coordinator: the task has no entities");
}

uint32_t Coordinator::nextId() {
  const uint32_t id = next_id_++;
  if (next_id_ == 0) next_id_ = 1;  // 0 means "none" on the wire
  return id;
}

const StepRecord* Coordinator::currentStep() const {
  for (const auto& s : steps_)
    if (!s.complete) return &s;
  return nullptr;
}

std::vector<int> Coordinator::activeEntities() const {
  std::vector<int> active;
  for (const auto& s : steps_)
    for (const auto& t : s.tokens)
      if (t.token.isMotion() && t.started_s >= 0 && t.state != SegmentState::Done) active.push_back(t.token.entity);
  return active;
}

std::vector<bool> Coordinator::goalConditionsMet() const {
  std::vector<bool> met;
  for (const auto& gc : spec_.goal_conditions) {
    const bool known = observation_.positions.size() == spec_.entities.size();
    met.push_back(known && task::goalConditionMet(spec_, gc, observation_.positions));
  }
  return met;
}

bool Coordinator::allTracked() const {
  if (observation_.tracked.size() != spec_.entities.size()) return false;
  for (size_t i = 0; i < observation_.tracked.size(); ++i)
    if (!observation_.tracked[i] && !(i < lost_.size() && lost_[i])) return false;
  return true;
}

void Coordinator::setState(RunState s, CoordinatorOutput& out) {
  if (s != state_) {
    out.log.push_back(std::string("state ") + toString(state_) + " -> " + toString(s));
    state_ = s;
    out.state_changed = true;
  }
}

void Coordinator::abort(const std::string& why, CoordinatorOutput& out) {
  reason_ = why;
  out.log.push_back("abort: " + why);
  stopActive(out);
  out.stop_all = true;
  pending_decision_ = 0;
  for (auto& s : steps_)
    for (auto& t : s.tokens) t.path_request = 0;
  setState(RunState::Aborted, out);
}

void Coordinator::stopActive(CoordinatorOutput& out) {
  for (auto& s : steps_)
    for (auto& t : s.tokens)
      if (t.segment_id != 0 && t.state != SegmentState::Done && t.state != SegmentState::Failed) {
        out.stop.push_back(t.token.entity);
        t.state = SegmentState::Aborted;
      }
}

void Coordinator::clearRun() {
  history_.clear();
  history_from_ = 0;
  ahead_ = -1;
  steps_.clear();
  decisions_requested_ = 0;
  last_decision_.reset();
  pending_decision_ = 0;
  end_decided_ = false;
  waiting_for_entities_ = false;
  blocked_on_tracking_ = false;
  dispatch_.reset();
  replans_ = 0;
  redecisions_ = 0;
  step_redecisions_.clear();
  withdrawn_.clear();
  began_at_.clear();
  lost_.assign(spec_.entities.size(), false);
  untracked_since_.assign(spec_.entities.size(), -1);
  lost_reports_.clear();
}

void Coordinator::requestDecisionIfDue(double now_s, CoordinatorOutput& out) {
  if (end_decided_ || pending_decision_ != 0 || ahead_ >= 0) return;
  if (!steps_.empty() && !dispatch_->mayDecide(policy_reads_scene_)) return;
  if (!allTracked()) {
    waiting_for_entities_ = true;
    return;
  }
  if (waiting_for_entities_) out.log.push_back("every entity is tracked");
  waiting_for_entities_ = false;
  if (static_cast<int>(steps_.size()) >= config_.max_steps) {
    abort("the policy did not say END within max_steps = " + std::to_string(config_.max_steps) + " steps", out);
    return;
  }
  task::Snapshot snap;
  snap.row = static_cast<int>(history_.size());
  // A policy that reads the scene decides from the scene as it is once it settled, else
  // (asked ahead) from the scene the decided steps will leave, as a fixed order always does;
  // either way a re-decided step's movers are read as decisionScene reads them.
  const bool ahead = policy_reads_scene_ && !dispatch_->allEnded();
  snap.positions = sceneOnceSettled(policy_reads_scene_ ? decisionScene() : observation_.positions);
  history_.push_back(snap);
  if (ahead) ahead_ = static_cast<int>(history_.size()) - 1;
  DecisionRequest req;
  req.id = nextId();
  req.step = static_cast<int>(steps_.size());
  // The policy's history begins where the task was last begun again (loseRobot).
  req.history.assign(history_.begin() + static_cast<std::ptrdiff_t>(std::min(history_from_, history_.size() - 1)),
                     history_.end());
  for (size_t i = 0; i < req.history.size(); ++i) req.history[i].row = static_cast<int>(i);
  req.lost = lostEntities();
  pending_decision_ = req.id;
  decision_since_s_ = now_s;
  ++decisions_requested_;
  out.log.push_back("requesting decision " + std::to_string(req.step + 1) +
                    (ahead ? " ahead, from the scene the running tokens will leave" : ""));
  out.decision = std::move(req);
}

std::vector<Eigen::Vector2d> Coordinator::decisionScene() const {
  const std::vector<Eigen::Vector2d>& now = observation_.positions;
  const auto atOnePlace = [&](int e) {
    for (int f = 0; f < static_cast<int>(now.size()); ++f)
      if (f != e && task::together(spec_, e, now[static_cast<size_t>(e)], f, now[static_cast<size_t>(f)])) return true;
    return false;
  };
  std::vector<Eigen::Vector2d> at = now;
  for (const auto& [e, p] : began_at_)
    if (atOnePlace(e)) at[static_cast<size_t>(e)] = p;
  return at;
}

std::vector<Eigen::Vector2d> Coordinator::sceneOnceSettled(std::vector<Eigen::Vector2d> at) const {
  for (const StepRecord& s : steps_) {
    if (s.complete) continue;
    std::vector<task::Token> tokens;
    for (const TokenRecord& t : s.tokens) tokens.push_back(t.token);
    at = task::stepEndPositions(spec_, end_points_, tokens, at, std::nullopt, s.step);
    for (const TokenRecord& t : s.tokens)
      if (t.token.isMotion() && t.started_s >= 0 && t.state != SegmentState::Done)
        at[static_cast<size_t>(t.token.entity)] = t.goal;
  }
  return at;
}

std::vector<std::vector<int>> Coordinator::insideOut(const std::vector<task::Token>& tokens,
                                                     const std::vector<Eigen::Vector2d>& scene) const {
  const std::vector<Eigen::Vector2d> ends = task::stepEndPositions(spec_, end_points_, tokens, scene);
  const auto robotMotion = [&](const task::Token& t) {
    return t.isMotion() && t.target >= 0 &&
           spec_.entities[static_cast<size_t>(t.entity)].kind == task::EntityKind::Robot;
  };
  const auto fromTarget = [&](const task::Token& t) {
    return (ends[static_cast<size_t>(t.entity)] - scene[static_cast<size_t>(t.target)]).norm();
  };
  std::vector<std::vector<int>> after(tokens.size());
  for (size_t i = 0; i < tokens.size(); ++i)
    for (size_t j = 0; j < tokens.size(); ++j)
      if (i != j && robotMotion(tokens[i]) && robotMotion(tokens[j]) && tokens[i].target == tokens[j].target &&
          fromTarget(tokens[j]) + config_.arrival_tolerance_m < fromTarget(tokens[i]))
        after[i].push_back(static_cast<int>(j));
  return after;
}

std::string Coordinator::unlikePrediction(const std::vector<Eigen::Vector2d>& predicted,
                                          const std::vector<Eigen::Vector2d>& settled) const {
  const double within = config_.arrival_radius_m + config_.arrival_tolerance_m;
  for (size_t e = 0; e < predicted.size() && e < settled.size(); ++e) {
    if (lost_[e]) continue;
    const double off = (settled[e] - predicted[e]).norm();
    if (off <= within) continue;
    std::ostringstream os;
    os << spec_.entities[e].name << " stands " << off << " m from where it was predicted (more than "
       << "arrival_radius_m + arrival_tolerance_m)";
    return os.str();
  }
  return "";
}

void Coordinator::settleAhead(CoordinatorOutput& out) {
  if (ahead_ < 0 || pending_decision_ != 0 || !dispatch_->settledBefore(ahead_)) return;
  if (!allTracked()) {
    waiting_for_entities_ = true;  // checked again once every entity is tracked
    return;
  }
  // The scene the decision read, settled: where everything is, the entities of its tokens
  // that started where they started (each after its own predecessors ended).
  // A re-decided step's movers stay where it began, as the decision read and recorded them.
  std::vector<Eigen::Vector2d> settled = observation_.positions;
  if (ahead_ < static_cast<int>(steps_.size()))
    for (const TokenRecord& t : steps_[static_cast<size_t>(ahead_)].tokens)
      if (t.started_s >= 0) settled[static_cast<size_t>(t.token.entity)] = t.start;
  for (const auto& [e, p] : began_at_) settled[static_cast<size_t>(e)] = p;
  task::Snapshot& read = history_[static_cast<size_t>(ahead_)];
  const std::string off = unlikePrediction(read.positions, settled);
  const std::string what =
      ahead_ == static_cast<int>(steps_.size()) ? std::string("END") : "step " + std::to_string(ahead_ + 1);
  if (!off.empty()) {
    withdrawAhead("the scene did not settle as predicted: " + off, out);
    return;
  }
  read.positions = settled;  // what later decisions read: the scene as it settled
  ahead_ = -1;
  began_at_.clear();
  out.log.push_back(what + ", decided ahead, holds: the scene settled as predicted");
}

void Coordinator::withdrawAhead(const std::string& why, CoordinatorOutput& out) {
  if (ahead_ < 0) return;
  const bool step = pending_decision_ == 0 && !end_decided_;
  out.log.push_back((pending_decision_ != 0 ? std::string("the request for decision ") + std::to_string(ahead_ + 1)
                     : step                 ? "step " + std::to_string(ahead_ + 1)
                                            : std::string("END")) +
                    ", asked ahead, is withdrawn: " + why);
  if (pending_decision_ != 0) {
    pending_decision_ = 0;  // its answer is ignored
  } else if (end_decided_) {
    end_decided_ = false;
    reason_.clear();
  } else {
    StepRecord& s = steps_.back();
    for (TokenRecord& t : s.tokens)
      if (t.token.isMotion() && t.started_s >= 0 && t.state != SegmentState::Done) {
        if (t.segment_id != 0) out.stop.push_back(t.token.entity);
        t.state = SegmentState::Aborted;
        t.path_request = 0;
      }
    withdrawn_.push_back(std::move(s));
    steps_.pop_back();
    dispatch_->withdrawLastStep();
  }
  history_.pop_back();
  ahead_ = -1;
}

void Coordinator::refreshState(CoordinatorOutput& out) {
  if (state_ == RunState::Finished || state_ == RunState::Aborted || state_ == RunState::EStopped) return;
  bool segment = false, path = false;
  for (const auto& s : steps_)
    for (const auto& t : s.tokens) {
      segment = segment || (t.segment_id != 0 && t.state != SegmentState::Done);
      path = path || t.path_request != 0;
    }
  setState(segment                  ? RunState::Executing
           : path                   ? RunState::Planning
           : pending_decision_ != 0 ? RunState::Deciding
                                    : RunState::WaitingForEntities,
           out);
}

void Coordinator::advance(double now_s, CoordinatorOutput& out) {
  startReady(now_s, out);
  for (auto& s : steps_) {
    if (s.complete) continue;
    bool all = true;
    for (const auto& t : s.tokens) all = all && t.state == SegmentState::Done;
    if (!all) continue;
    s.complete = true;
    s.finished_s = now_s;
    out.log.push_back("step " + std::to_string(s.step + 1) + " complete");
  }
  settleAhead(out);
  if (end_decided_ && dispatch_->allEnded()) {
    setState(RunState::Finished, out);
    return;
  }
  requestDecisionIfDue(now_s, out);
  refreshState(out);
}

void Coordinator::startReady(double now_s, CoordinatorOutput& out) {
  blocked_on_tracking_ = false;
  std::vector<TokenRef> motions;
  for (bool again = true; again;) {
    again = false;
    for (const TokenRef& r : dispatch_->readyTokens()) {
      TokenRecord& t = record(r);
      // A token starts from where its entities are: never from a pose the tracker lost.
      const int e = t.token.entity, target = t.token.target;
      if (!observation_.tracked.at(static_cast<size_t>(e)) ||
          (target >= 0 && !observation_.tracked.at(static_cast<size_t>(target)))) {
        blocked_on_tracking_ = true;
        continue;
      }
      dispatch_->start(r, now_s);
      again = true;  // a token of its step may start after it
      t.started_s = now_s;
      t.start = observation_.positions[static_cast<size_t>(e)];
      t.goal = t.start;
      if (t.token.isMotion()) {
        motions.push_back(r);
      } else {
        endToken(r, now_s, out, "");  // in place: ends as it starts, which may release others
      }
    }
  }
  if (motions.empty()) return;
  // Where the started bodies end, per step together (an end point depends on the step's
  // other tokens: a load, an end another motion takes), each started one at its start.
  for (size_t k = 0; k < steps_.size(); ++k) {
    if (std::none_of(motions.begin(), motions.end(), [&](const TokenRef& r) { return r.step == static_cast<int>(k); }))
      continue;
    const StepRecord& s = steps_[k];
    std::vector<task::Token> tokens;
    std::vector<Eigen::Vector2d> at = observation_.positions;
    for (const auto& t : s.tokens) {
      tokens.push_back(t.token);
      if (t.started_s >= 0) at[static_cast<size_t>(t.token.entity)] = t.start;
    }
    const std::vector<Eigen::Vector2d> ends =
        task::stepEndPositions(spec_, end_points_, tokens, at, std::nullopt, static_cast<int>(k));
    for (const TokenRef& r : motions)
      if (r.step == static_cast<int>(k)) record(r).goal = ends[static_cast<size_t>(record(r).token.entity)];
  }
  for (const TokenRef& r : motions)
    if (record(r).token.target >= 0) record(r).target_start = observation_.positions[record(r).token.target];
  requestPaths(motions, now_s, out);
}

Eigen::Vector2d Coordinator::endPointOf(TokenRef r, std::vector<Eigen::Vector2d> at) const {
  const StepRecord& s = steps_[static_cast<size_t>(r.step)];
  std::vector<task::Token> tokens;
  for (size_t i = 0; i < s.tokens.size(); ++i) {
    const TokenRecord& t = s.tokens[i];
    tokens.push_back(t.token);
    if (t.started_s >= 0 && static_cast<int>(i) != r.index) at[static_cast<size_t>(t.token.entity)] = t.start;
  }
  const int e = s.tokens[static_cast<size_t>(r.index)].token.entity;
  return task::stepEndPositions(spec_, end_points_, tokens, at, std::nullopt, r.step)[static_cast<size_t>(e)];
}

bool Coordinator::mayRecover(TokenRef r, int done, const std::string& why, CoordinatorOutput& out) {
  const TokenRecord& t = record(r);
  if (done >= config_.max_replans) {
    abort(config_.max_replans == 0 ? why
                                   : why + " (recovered " + std::to_string(done) +
                                         " times, max_replans = " + std::to_string(config_.max_replans) + ")",
          out);
    return false;
  }
  for (int e : {t.token.entity, t.token.target})
    if (e >= 0 && !observation_.tracked.at(static_cast<size_t>(e)) && !lost_.at(static_cast<size_t>(e))) {
      abort(why + "; no recovery: " + spec_.entities[static_cast<size_t>(e)].name + " is not tracked", out);
      return false;
    }
  return true;
}

void Coordinator::checkLost(double now_s, CoordinatorOutput& out) {
  if (config_.max_replans == 0) return;
  for (size_t i = 0; i < untracked_since_.size() && running(); ++i)
    if (!lost_[i] && untracked_since_[i] >= 0 && spec_.entities[i].kind == task::EntityKind::Robot &&
        now_s - untracked_since_[i] >= config_.robot_lost_after_s)
      loseRobot(static_cast<int>(i), "not tracked for " + seconds(config_.robot_lost_after_s), now_s, out);
}

std::vector<int> Coordinator::lostEntities() const {
  std::vector<int> out;
  for (size_t i = 0; i < lost_.size(); ++i)
    if (lost_[i]) out.push_back(static_cast<int>(i));
  return out;
}

std::string Coordinator::lostWhy(int e) const {
  const std::string& name = spec_.entities[static_cast<size_t>(e)].name;
  for (const std::string& r : lost_reports_)
    if (r.rfind(name + ": ", 0) == 0) return r.substr(name.size() + 2);
  return "";
}

void Coordinator::loseRobot(int e, const std::string& why, double now_s, CoordinatorOutput& out) {
  const std::string& name = spec_.entities[static_cast<size_t>(e)].name;
  lost_[static_cast<size_t>(e)] = true;
  lost_reports_.push_back(name + ": " + why);
  out.log.push_back(name + " is lost for good: " + why);
  if (!policy_reads_scene_) {
    abort(name + " is lost (" + why + "): the policy follows a fixed order that names it; no decision without it", out);
    return;
  }
  withdrawAhead(name + " is lost", out);  // it read the lost robot where it was predicted
  // Its tokens (and those meeting it) that have not ended: withdrawn with the latest step,
  // decided again without it; one of an earlier step cannot be.
  std::optional<TokenRef> latest;
  for (size_t k = 0; k < steps_.size(); ++k)
    for (size_t i = 0; i < steps_[k].tokens.size(); ++i) {
      const TokenRecord& t = steps_[k].tokens[i];
      if (t.state == SegmentState::Done || (t.token.entity != e && t.token.target != e)) continue;
      if (k + 1 != steps_.size() || history_.size() != steps_.size() || end_decided_) {
        abort(name + " is lost (" + why + ") and " + task::tokenKey(t.token, spec_) + " of step " +
                  std::to_string(k + 1) + " has not ended: no decision without it",
              out);
        return;
      }
      latest = TokenRef{static_cast<int>(k), static_cast<int>(i)};
    }
  if (latest) {
    // A carrier lost with its load leaves the load where no demonstrated step continues
    // from: the task is begun again from the scene as it is (the policy's first step).
    const std::string load = loadOf(*latest);
    redecide(*latest, name + " is lost: " + why, now_s, out, !load.empty());
    if (!load.empty() && running())
      out.log.push_back(name + " was lost carrying " + load +
                        ": the task is decided again from its first step, from the scene as it is");
    return;
  }
  advance(now_s, out);  // a decision may have waited for it to be tracked
}

void Coordinator::recover(TokenRef r, const std::string& why, bool target_moved, double now_s, CoordinatorOutput& out) {
  // Nobody can drive a robot the tracker does not see: with recovery on it is lost for good.
  const int e = record(r).token.entity;
  if (config_.max_replans > 0 && spec_.entities[static_cast<size_t>(e)].kind == task::EntityKind::Robot &&
      !observation_.tracked.at(static_cast<size_t>(e))) {
    loseRobot(e, why + " while it is not tracked", now_s, out);
    return;
  }
  // A decision asked ahead read the scene this token was to leave.
  if (ahead_ != r.step) withdrawAhead(why, out);
  // Only the latest decision, made from the scene and not yet followed by another, is
  // re-made: a fixed order would decide the same step again.
  const bool may_redecide = policy_reads_scene_ && r.step + 1 == static_cast<int>(steps_.size()) &&
                            history_.size() == steps_.size() && pending_decision_ == 0 && !end_decided_;
  const auto k = static_cast<size_t>(r.step);
  const int redecided = k < step_redecisions_.size() ? step_redecisions_[k] : 0;
  // What the decision read moved: decide again. The token could not run: a path from where
  // it is, and once that is used up, another decision (someone else may do it).
  const std::string pusher = pusherOf(r);
  if (!pusher.empty() && !(may_redecide && redecided < config_.max_replans)) {
    abort(why + "; no recovery: nothing moves " + spec_.entities[static_cast<size_t>(e)].name + " but its carrier " +
              pusher + (may_redecide ? " (re-decided " + std::to_string(redecided) + " times)" : ""),
          out);
    return;
  }
  if (may_redecide && (target_moved || !pusher.empty() ||
                       (record(r).replans >= config_.max_replans && redecided < config_.max_replans)))
    redecide(r, why, now_s, out);
  else replan(r, why, now_s, out);
}

std::string Coordinator::pusherOf(TokenRef r) const {
  if (config_.loads_ride) return "";
  const StepRecord& s = steps_[static_cast<size_t>(r.step)];
  const task::Token& load = s.tokens[static_cast<size_t>(r.index)].token;
  for (const TokenRecord& t : s.tokens)
    if (carries(spec_, r.step, t.token, r.step, load)) return spec_.entities[static_cast<size_t>(t.token.entity)].name;
  return "";
}

std::string Coordinator::loadOf(TokenRef r) const {
  const StepRecord& s = steps_[static_cast<size_t>(r.step)];
  const task::Token& carrier = s.tokens[static_cast<size_t>(r.index)].token;
  if (!carrier.isMotion() || spec_.entities[static_cast<size_t>(carrier.entity)].kind != task::EntityKind::Robot)
    return "";
  for (const TokenRecord& t : s.tokens)
    if (t.state != SegmentState::Done && t.token.isMotion() && t.token.action == carrier.action &&
        t.token.target == carrier.target &&
        spec_.entities[static_cast<size_t>(t.token.entity)].kind == task::EntityKind::Object)
      return spec_.entities[static_cast<size_t>(t.token.entity)].name;
  return "";
}

void Coordinator::redecide(TokenRef r, const std::string& why, double now_s, CoordinatorOutput& out, bool begin_again) {
  const auto k = static_cast<size_t>(r.step);
  if (step_redecisions_.size() <= k) step_redecisions_.resize(k + 1, 0);
  if (!mayRecover(r, step_redecisions_[k], why, out)) return;
  ++step_redecisions_[k];
  ++redecisions_;
  StepRecord& s = steps_[k];
  // Where the step's movers began: the policy reads a step's motion from one decision's
  // scene to the next, and a robot stopped part-way has done neither that step nor another
  // (decisionScene, onDecision). A task begun again reads the scene as it is.
  const std::vector<Eigen::Vector2d>& begun = history_.back().positions;
  began_at_.clear();
  for (const TokenRecord& t : s.tokens)
    if (!begin_again && t.token.isMotion() && t.started_s >= 0)
      began_at_.emplace_back(t.token.entity, begun[static_cast<size_t>(t.token.entity)]);
  for (TokenRecord& t : s.tokens)
    if (t.token.isMotion() && t.started_s >= 0 && t.state != SegmentState::Done) {
      if (t.segment_id != 0) out.stop.push_back(t.token.entity);
      t.state = SegmentState::Aborted;
      t.path_request = 0;
    }
  out.log.push_back("re-deciding step " + std::to_string(k + 1) + " from the scene as it is (" +
                    std::to_string(step_redecisions_[k]) + " of " + std::to_string(config_.max_replans) + "): " + why);
  withdrawn_.push_back(std::move(s));
  steps_.pop_back();
  history_.pop_back();
  if (ahead_ == static_cast<int>(k)) ahead_ = -1;  // decided again: from the scene as it is, or ahead anew
  if (begin_again) history_from_ = history_.size();
  dispatch_->withdrawLastStep();
  advance(now_s, out);  // asks for the step again from a snapshot of now
}

void Coordinator::replan(TokenRef r, const std::string& why, double now_s, CoordinatorOutput& out) {
  TokenRecord& t = record(r);
  const std::string key = task::tokenKey(t.token, spec_);
  if (!mayRecover(r, t.replans, why, out)) return;
  ++t.replans;
  ++replans_;
  if (t.segment_id != 0) out.stop.push_back(t.token.entity);  // never on with an old segment
  t.start = observation_.positions[static_cast<size_t>(t.token.entity)];
  // The end point moves with its target only: a robot pushed aside keeps the end it had.
  const int target = t.token.target;
  if (target >= 0 && (observation_.positions[static_cast<size_t>(target)] - t.target_start).norm() >
                         config_.arrival_radius_m + config_.arrival_tolerance_m) {
    std::vector<Eigen::Vector2d> at = observation_.positions;
    at[static_cast<size_t>(t.token.entity)] = t.start;
    t.goal = endPointOf(r, at);
    t.target_start = observation_.positions[static_cast<size_t>(target)];
  }
  t.done_claimed = false;
  out.log.push_back("re-planning " + key + " from where it is (" + std::to_string(t.replans) + " of " +
                    std::to_string(config_.max_replans) + "): " + why);
  requestPaths({r}, now_s, out);
  refreshState(out);
}

void Coordinator::endToken(TokenRef r, double now_s, CoordinatorOutput& out, const std::string& why) {
  TokenRecord& t = record(r);
  t.state = SegmentState::Done;
  t.progress = 1.0;
  dispatch_->end(r, now_s);
  if (!why.empty()) out.log.push_back(why);
}

std::optional<TokenRef> Coordinator::findRunning(uint32_t id, bool by_segment) const {
  if (id == 0) return std::nullopt;
  for (size_t k = 0; k < steps_.size(); ++k)
    for (size_t i = 0; i < steps_[k].tokens.size(); ++i) {
      const TokenRecord& t = steps_[k].tokens[i];
      if (t.started_s >= 0 && (by_segment ? t.segment_id : t.path_request) == id)
        return TokenRef{static_cast<int>(k), static_cast<int>(i)};
    }
  return std::nullopt;
}

CoordinatorOutput Coordinator::start(double now_s) {
  CoordinatorOutput out;
  if (state_ == RunState::Idle) {
    reason_.clear();
    clearRun();
    for (size_t i = 0; i < observation_.tracked.size() && i < untracked_since_.size(); ++i)
      if (!observation_.tracked[i]) untracked_since_[i] = now_s;
    dispatch_.emplace(spec_, config_.dispatch, dependencies_);
    out.log.push_back(std::string("dispatch: ") + toString(config_.dispatch));
    advance(now_s, out);
    out.state_changed = true;
  } else if (state_ == RunState::Paused) {
    // Re-plan what had started and not ended from where the robots stopped; goals stay.
    std::vector<TokenRef> unfinished;
    for (size_t k = 0; k < steps_.size(); ++k)
      for (size_t i = 0; i < steps_[k].tokens.size(); ++i) {
        const TokenRecord& t = steps_[k].tokens[i];
        if (t.token.isMotion() && t.started_s >= 0 && t.state != SegmentState::Done)
          unfinished.push_back({static_cast<int>(k), static_cast<int>(i)});
      }
    if (!unfinished.empty()) requestPaths(unfinished, now_s, out);
    advance(now_s, out);
    out.state_changed = true;
  } else {
    out.log.push_back(std::string("start refused in state ") + toString(state_) +
                      (state_ == RunState::Finished || state_ == RunState::Aborted || state_ == RunState::EStopped
                           ? " (reset first)"
                           : " (already running)"));
  }
  return out;
}

CoordinatorOutput Coordinator::pause(double) {
  CoordinatorOutput out;
  if (!running() || state_ == RunState::Paused) {
    out.log.push_back(std::string("pause refused in state ") + toString(state_));
    return out;
  }
  if (pending_decision_ != 0 && !history_.empty()) history_.pop_back();
  if (pending_decision_ != 0) ahead_ = -1;  // asked again on resume
  pending_decision_ = 0;
  for (auto& s : steps_)
    for (auto& t : s.tokens) t.path_request = 0;
  stopActive(out);
  setState(RunState::Paused, out);
  return out;
}

CoordinatorOutput Coordinator::reset(double) {
  CoordinatorOutput out;
  stopActive(out);
  out.stop_all = true;
  clearRun();
  reason_.clear();
  setState(RunState::Idle, out);
  out.state_changed = true;
  return out;
}

CoordinatorOutput Coordinator::emergencyStop(double, const std::string& why) {
  CoordinatorOutput out;
  reason_ = "emergency stop: " + why;
  out.log.push_back(reason_);
  stopActive(out);
  out.stop_all = true;
  pending_decision_ = 0;
  for (auto& s : steps_)
    for (auto& t : s.tokens) t.path_request = 0;
  setState(RunState::EStopped, out);
  out.state_changed = true;
  return out;
}

CoordinatorOutput Coordinator::onEntities(const EntityObservation& obs, double now_s) {
  CoordinatorOutput out;
  if (obs.positions.size() != spec_.entities.size() || obs.tracked.size() != spec_.entities.size())
    throw Error("coordinator: an observation must have one position and one tracked flag per task entity (" +
                std::to_string(spec_.entities.size()) + ")");
  observation_ = obs;
  last_seen_.resize(obs.positions.size(), Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN()));
  for (size_t i = 0; i < obs.positions.size(); ++i)
    if (obs.tracked[i] && obs.positions[i].allFinite()) last_seen_[i] = obs.positions[i];
  if (!running() || state_ == RunState::Paused) return out;
  for (size_t i = 0; i < obs.tracked.size() && i < untracked_since_.size(); ++i)
    untracked_since_[i] = obs.tracked[i] ? -1 : untracked_since_[i] < 0 ? now_s : untracked_since_[i];
  checkLost(now_s, out);
  if (!running()) return out;
  updateDistances();
  // A DONE that came before the tracked pose agreed counts once it does.
  bool ended = false;
  for (size_t k = 0; k < steps_.size(); ++k)
    for (size_t i = 0; i < steps_[k].tokens.size(); ++i) {
      TokenRecord& t = steps_[k].tokens[i];
      if (!t.done_claimed || t.segment_id == 0 || t.state == SegmentState::Done) continue;
      judgeBehindItsLoad(t);
      if (arrived(t)) {
        endToken({static_cast<int>(k), static_cast<int>(i)}, now_s, out,
                 "done: " + task::tokenKey(t.token, spec_) + " (tracked pose now within the arrival radius)");
        ended = true;
      }
    }
  if (ended || waiting_for_entities_ || blocked_on_tracking_) advance(now_s, out);
  if (state_ == RunState::Aborted || config_.max_replans == 0) return out;
  // A target moved under a running token (by a hand, not by a token of the run): its end
  // point is elsewhere now. Without re-planning the token runs on to its old end point.
  std::vector<bool> moving(spec_.entities.size(), false);
  for (const auto& s : steps_)
    for (const auto& t : s.tokens)
      if (t.token.isMotion() && t.started_s >= 0 && t.state != SegmentState::Done)
        moving[static_cast<size_t>(t.token.entity)] = true;
  for (size_t k = 0; k < steps_.size(); ++k)
    for (size_t i = 0; i < steps_[k].tokens.size(); ++i) {
      const TokenRecord& t = steps_[k].tokens[i];
      const int target = t.token.target;
      if (!t.token.isMotion() || t.started_s < 0 || t.state == SegmentState::Done || target < 0 ||
          moving[static_cast<size_t>(target)] || !observation_.tracked[static_cast<size_t>(target)])
        continue;
      const double moved = (observation_.positions[static_cast<size_t>(target)] - t.target_start).norm();
      if (moved <= config_.arrival_radius_m + config_.arrival_tolerance_m) continue;
      std::ostringstream os;
      os << spec_.entities[static_cast<size_t>(target)].name << " moved " << moved << " m while "
         << task::tokenKey(t.token, spec_) << " ran (more than arrival_radius_m + arrival_tolerance_m)";
      recover({static_cast<int>(k), static_cast<int>(i)}, os.str(), true, now_s, out);
      return out;
    }
  return out;
}

void Coordinator::judgeBehindItsLoad(TokenRecord& t) {
  if (t.pushed_load < 0 || t.path.points.empty()) return;
  const auto l = static_cast<size_t>(t.pushed_load);
  if (observation_.positions.size() <= l || !observation_.tracked[l]) return;
  t.goal = carrierEnd(t.path.points.back(), t.pushed_load_end, observation_.positions[l], config_.loads_ride);
}

bool Coordinator::arrived(const TokenRecord& t) const {
  const auto e = static_cast<size_t>(t.token.entity);
  if (observation_.positions.size() <= e || !observation_.tracked[e]) return false;
  return task::arrived(observation_.positions[e], t.goal, config_.arrival_radius_m + config_.arrival_tolerance_m);
}

void Coordinator::updateDistances() {
  for (auto& s : steps_)
    for (auto& t : s.tokens) {
      const auto e = static_cast<size_t>(t.token.entity);
      if (t.segment_id != 0 && t.state != SegmentState::Done && observation_.positions.size() > e &&
          observation_.tracked[e])
        t.distance_to_goal_m = (observation_.positions[e] - t.goal).norm();
    }
}

CoordinatorOutput Coordinator::onDecision(uint32_t id, const Decision& d, double now_s,
                                          const DecisionProbabilities& prob) {
  CoordinatorOutput out;
  if (!running() || state_ == RunState::Paused || id != pending_decision_ || id == 0) {
    out.log.push_back("ignoring decision " + std::to_string(id) + " (not the one asked for)");
    return out;
  }
  pending_decision_ = 0;
  if (!prob.tokens.empty() && prob.tokens.size() != d.tokens.size()) {
    abort("the policy returned " + std::to_string(prob.tokens.size()) + " probabilities for " +
              std::to_string(d.tokens.size()) + " tokens",
          out);
    return out;
  }
  last_decision_ = AcceptedDecision{d, prob};
  if (d.end) {
    recordBeganAt();
    end_decided_ = true;
    reason_ = "the policy predicted END after " + std::to_string(steps_.size()) + " steps";
    out.log.push_back(reason_);
    advance(now_s, out);  // finished once every token has ended
    return out;
  }
  const int n = static_cast<int>(spec_.entities.size());
  if (d.tokens.empty()) {
    abort("the policy returned a step without tokens", out);
    return out;
  }
  StepRecord step;
  step.step = static_cast<int>(steps_.size());
  step.decided_s = now_s;
  std::vector<bool> seen(n, false);
  for (size_t i = 0; i < d.tokens.size(); ++i) {
    const task::Token& tok = d.tokens[i];
    if (tok.entity < 0 || tok.entity >= n || tok.target >= n || tok.target == tok.entity || tok.action.empty()) {
      abort("the policy returned an invalid token (entity " + std::to_string(tok.entity) + ", target " +
                std::to_string(tok.target) + ", action '" + tok.action + "')",
            out);
      return out;
    }
    for (int e : {tok.entity, tok.target})
      if (e >= 0 && lost_[static_cast<size_t>(e)]) {
        abort(spec_.entities[static_cast<size_t>(e)].name + " is lost (" + lostWhy(e) + ") and step " +
                  std::to_string(steps_.size() + 1) + " as decided needs it (" + task::tokenKey(tok, spec_) +
                  "): no decision without it",
              out);
        return out;
      }
    if (seen[tok.entity]) {
      abort("the policy gave entity " + spec_.entities[tok.entity].name + " two tokens in one step", out);
      return out;
    }
    seen[tok.entity] = true;
    TokenRecord r;
    r.token = tok;
    step.tokens.push_back(std::move(r));
  }
  const std::string unsupported = undemonstratedMotion(d.tokens);
  if (!unsupported.empty()) {
    const std::vector<int> lost = lostEntities();
    std::string lost_names;
    for (int e : lost) lost_names += (lost_names.empty() ? "" : ", ") + spec_.entities[static_cast<size_t>(e)].name;
    abort((lost.empty() ? std::string() : lost_names + " is lost and ") + "step " + std::to_string(step.step + 1) +
              " as decided" + (lost.empty() ? "" : " without it") + " moves " + unsupported +
              ": no demonstration has such a motion" + (lost.empty() ? "" : "; no decision without it"),
          out);
    return out;
  }
  std::ostringstream os;
  os << "step " << step.step + 1 << ":";
  for (const auto& t : step.tokens) os << " " << task::tokenKey(t.token, spec_);
  out.log.push_back(os.str());
  steps_.push_back(std::move(step));
  dispatch_->addStep(d.tokens, now_s, insideOut(d.tokens, history_.back().positions));
  recordBeganAt();
  advance(now_s, out);
  return out;
}

void Coordinator::recordBeganAt() {
  for (const auto& [e, p] : began_at_) history_.back().positions[static_cast<size_t>(e)] = p;
  if (ahead_ < 0) began_at_.clear();  // decided ahead: held until the scene settles (settleAhead)
}

std::string Coordinator::undemonstratedMotion(const std::vector<task::Token>& tokens) const {
  if (end_points_.by_class.empty()) return "";  // nothing learned to hold a decision to
  for (size_t i = 0; i < tokens.size(); ++i) {
    if (!tokens[i].isMotion()) continue;
    const std::string motion = task::motionClass(spec_, tokens, i);
    if (end_points_.by_class.count(motion) == 0) return task::tokenKey(tokens[i], spec_) + " (" + motion + ")";
  }
  return "";
}

CoordinatorOutput Coordinator::onDecisionError(uint32_t id, const std::string& error, double) {
  CoordinatorOutput out;
  if (!running() || state_ == RunState::Paused || id != pending_decision_ || id == 0) return out;
  abort("no decision for step " + std::to_string(steps_.size() + 1) + ": " + error, out);
  return out;
}

void Coordinator::requestPaths(const std::vector<TokenRef>& tokens, double now_s, CoordinatorOutput& out) {
  const uint32_t batch = next_batch_++;
  for (const TokenRef& r : tokens) {
    TokenRecord& t = record(r);
    PathRequest req;
    req.id = nextId();
    req.step = r.step;
    req.token = t.token;
    // From where the entity is (after a pause: where it stopped); the goal stays fixed.
    req.start = observation_.positions.at(static_cast<size_t>(t.token.entity));
    req.goal = t.goal;
    t.path_request = req.id;
    t.path_requested_s = now_s;
    t.batch = batch;
    t.path = {};
    t.segment_id = 0;
    t.segment_sent_s = -1;
    t.state = SegmentState::Sent;
    out.paths.push_back(req);
  }
}

CoordinatorOutput Coordinator::onPath(uint32_t id, const PlannedPath& path, const std::string& error, double now_s) {
  CoordinatorOutput out;
  if (!running() || state_ == RunState::Paused) return out;
  const std::optional<TokenRef> ref = findRunning(id, /*by_segment=*/false);
  if (!ref) return out;
  TokenRecord& t = record(*ref);
  const std::string key = task::tokenKey(t.token, spec_);
  if (!error.empty() || path.points.empty()) {
    abort("no path for " + key + ": " + (error.empty() ? "the path is empty" : error), out);
    return out;
  }
  for (const auto& p : path.points)
    if (!p.allFinite()) {
      abort("the path for " + key + " has a non-finite point", out);
      return out;
    }
  for (double sd : path.stddev_m)
    if (!std::isfinite(sd) || sd < 0) {
      abort("the path for " + key + " has a non-finite or negative standard deviation", out);
      return out;
    }
  // A path for another token (another start or goal) must not drive this entity.
  const double end_error = (path.points.back() - t.goal).norm();
  if (end_error > config_.arrival_radius_m) {
    std::ostringstream os;
    os << "the path for " << key << " ends " << end_error
       << " m from its end point (more than arrival_radius_m = " << config_.arrival_radius_m
       << " m): not a path for this token";
    abort(os.str(), out);
    return out;
  }
  t.path = carrierPath(*ref, path);
  t.path_request = 0;
  sendBatch(t.batch, now_s, out);
  refreshState(out);
  return out;
}

PlannedPath Coordinator::carrierPath(TokenRef ref, const PlannedPath& planned) {
  StepRecord& s = steps_[static_cast<size_t>(ref.step)];
  const size_t n = spec_.entities.size();
  std::vector<task::Token> step;
  // Every entity where it was last seen (never seen: NaN), the step's where it started.
  std::vector<Eigen::Vector2d> at(n, Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN()));
  for (size_t e = 0; e < n && e < last_seen_.size(); ++e) at[e] = last_seen_[e];
  for (const TokenRecord& t : s.tokens) {
    step.push_back(t.token);
    at[static_cast<size_t>(t.token.entity)] = t.start;
  }
  const std::optional<int> load = pushedLoad(spec_, step, static_cast<size_t>(ref.index), at);
  if (!load) return planned;
  const TokenRecord* l = nullptr;
  for (const TokenRecord& t : s.tokens)
    if (t.token.entity == *load) l = &t;
  // Planned from where the load is now (a re-plan: it may have moved).
  const auto e = static_cast<size_t>(*load);
  const bool seen = observation_.positions.size() > e && observation_.tracked[e];
  if (seen) at[e] = observation_.positions[e];
  // A riding load's carrier drives the path shown where it passes the bodies standing, as
  // the simulator decides it (ride_path.h).
  if (drivesShownPath(spec_, step, static_cast<size_t>(ref.index), *load, at, planned.points, config_.loads_ride))
    return planned;
  TokenRecord& c = record(ref);
  c.pushed_load = config_.loads_ride ? -1 : *load;
  c.pushed_load_end = l->goal;
  PlannedPath out;
  out.points = pushPath(planned.points.front(), at[e], l->goal, spec_.contactDistance(c.token.entity, *load), c.goal,
                        static_cast<int>(planned.points.size()),
                        pushObstacles(spec_, step, static_cast<size_t>(ref.index), *load, at));
  out.stddev_m.assign(out.points.size(), 0.0);
  c.goal = carrierEnd(out.points.back(), l->goal, l->goal, config_.loads_ride);
  return out;
}

void Coordinator::sendBatch(uint32_t batch, double now_s, CoordinatorOutput& out) {
  for (const auto& s : steps_)
    for (const auto& t : s.tokens)
      if (t.batch == batch && t.path_request != 0) return;
  // Every path of the batch is in: its segments go out together so its robots start together.
  for (auto& s : steps_)
    for (auto& t : s.tokens) {
      if (t.batch != batch || !t.token.isMotion() || t.state == SegmentState::Done || t.segment_id != 0) continue;
      SegmentCommand cmd;
      cmd.entity = t.token.entity;
      cmd.segment_id = nextId();
      cmd.step = s.step;
      cmd.token = t.token;
      cmd.path = t.path;
      cmd.goal = t.goal;
      double length = 0;
      for (size_t i = 1; i < t.path.points.size(); ++i) length += (t.path.points[i] - t.path.points[i - 1]).norm();
      cmd.timeout_s = config_.segment_timeout_s + config_.segment_timeout_per_m_s * length;
      t.segment_id = cmd.segment_id;
      t.segment_sent_s = now_s;
      t.state = SegmentState::Sent;
      t.progress = 0;
      t.timeout_s = cmd.timeout_s;
      t.done_claimed = false;
      t.distance_to_goal_m = std::numeric_limits<double>::quiet_NaN();
      out.segments.push_back(std::move(cmd));
    }
  updateDistances();
}

CoordinatorOutput Coordinator::onSegmentStatus(const StatusReport& r, double now_s) {
  CoordinatorOutput out;
  const int n = static_cast<int>(spec_.entities.size());
  if (r.topic_entity < 0 || r.topic_entity >= n) return out;
  const std::string& topic_name = spec_.entities[r.topic_entity].name;
  if (r.entity != topic_name) {
    out.log.push_back("ignoring a status for '" + r.entity + "' on " + topic_name + "'s status topic (segment " +
                      std::to_string(r.segment_id) + ")");
    return out;
  }
  if (r.code < static_cast<int>(SegmentState::Accepted) || r.code > static_cast<int>(SegmentState::Aborted)) {
    out.log.push_back("ignoring a status of " + topic_name + " with invalid code " + std::to_string(r.code));
    return out;
  }
  if (!running() || state_ == RunState::Paused || r.segment_id == 0) return out;
  const std::optional<TokenRef> ref = findRunning(r.segment_id, /*by_segment=*/true);
  if (!ref) return out;
  TokenRecord* rec = &record(*ref);
  if (rec->token.entity != r.topic_entity) {  // a running segment of another entity: a status on the wrong topic
    out.log.push_back("ignoring a status for segment " + std::to_string(r.segment_id) + " on " + topic_name +
                      "'s topic: that segment belongs to another entity");
    return out;
  }
  if (rec->state == SegmentState::Done) return out;
  const std::string key = task::tokenKey(rec->token, spec_);
  const auto st = static_cast<SegmentState>(r.code);
  if (std::isfinite(r.progress)) rec->progress = std::clamp(r.progress, 0.0, 1.0);
  if (st == SegmentState::Failed || st == SegmentState::Aborted) {
    rec->state = st;
    recover(*ref, "segment " + key + " " + toString(st) + (r.message.empty() ? "" : ": " + r.message), false, now_s,
            out);
    return out;
  }
  if (st != SegmentState::Done) {
    if (!rec->done_claimed) rec->state = st;
    return out;
  }
  judgeBehindItsLoad(*rec);
  updateDistances();
  if (!arrived(*rec)) {
    if (!rec->done_claimed) {
      std::ostringstream os;
      os << "ignoring DONE of " << key << " (segment " << r.segment_id << "): the tracked position is "
         << rec->distance_to_goal_m << " m from its end point (arrival radius " << config_.arrival_radius_m
         << " m); the segment runs on until it arrives or times out";
      out.log.push_back(os.str());
    }
    rec->done_claimed = true;
    rec->state = SegmentState::Running;
    return out;
  }
  endToken(*ref, now_s, out, "done: " + key);
  advance(now_s, out);
  return out;
}

CoordinatorOutput Coordinator::onSegmentStatus(int entity, uint32_t segment_id, SegmentState state, double progress,
                                               const std::string& message, double now_s) {
  StatusReport r;
  r.topic_entity = entity;
  if (entity >= 0 && entity < static_cast<int>(spec_.entities.size())) r.entity = spec_.entities[entity].name;
  r.segment_id = segment_id;
  r.code = static_cast<int>(state);
  r.progress = progress;
  r.message = message;
  return onSegmentStatus(r, now_s);
}

bool Coordinator::running() const {
  return state_ == RunState::WaitingForEntities || state_ == RunState::Deciding || state_ == RunState::Planning ||
         state_ == RunState::Executing || state_ == RunState::Paused;
}

CoordinatorOutput Coordinator::abortRun(const std::string& why, double) {
  CoordinatorOutput out;
  if (running()) abort(why, out);
  return out;
}

CoordinatorOutput Coordinator::abortStart(const std::string& why, double) {
  CoordinatorOutput out;
  if (state_ != RunState::Idle) return out;
  clearRun();
  abort(why, out);
  out.state_changed = true;
  return out;
}

CoordinatorOutput Coordinator::onTick(double now_s) {
  CoordinatorOutput out;
  if (!running() || state_ == RunState::Paused) return out;
  checkLost(now_s, out);
  if (!running()) return out;
  if (pending_decision_ != 0 && now_s - decision_since_s_ > config_.decision_timeout_s) {
    abort("no decision within decision_timeout_s = " + seconds(config_.decision_timeout_s), out);
    return out;
  }
  for (const auto& s : steps_)
    for (const auto& t : s.tokens)
      if (t.path_request != 0 && now_s - t.path_requested_s > config_.path_timeout_s) {
        abort("not every path arrived within path_timeout_s = " + seconds(config_.path_timeout_s), out);
        return out;
      }
  for (size_t k = 0; k < steps_.size(); ++k)
    for (size_t i = 0; i < steps_[k].tokens.size(); ++i) {
      const TokenRecord& t = steps_[k].tokens[i];
      if (t.segment_id != 0 && t.state != SegmentState::Done && now_s - t.segment_sent_s > t.timeout_s) {
        std::ostringstream os;
        os << "segment " << task::tokenKey(t.token, spec_) << " timed out after " << t.timeout_s << " s (progress "
           << t.progress << ")";
        recover({static_cast<int>(k), static_cast<int>(i)}, os.str(), false, now_s, out);
        return out;
      }
    }
  return out;
}

}  // namespace ddace::exec
