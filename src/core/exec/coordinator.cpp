#include "ddace/exec/coordinator.h"

#include <algorithm>
#include <cmath>
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
}

uint32_t firstIdAt(double wall_clock_s) {
  if (!std::isfinite(wall_clock_s) || wall_clock_s < 0) return 1;
  const auto ms = static_cast<uint64_t>(wall_clock_s * 1000.0);
  const auto id = static_cast<uint32_t>(ms & 0x7fffffffu);
  return id == 0 ? 1 : id;
}

Coordinator::Coordinator(task::TaskSpec spec, CoordinatorConfig config, task::EndPointModel end_points,
                         uint32_t first_id)
    : spec_(std::move(spec)),
      config_(config),
      end_points_(std::move(end_points)),
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
  if (steps_.empty() || steps_.back().complete) return nullptr;
  return &steps_.back();
}

std::vector<int> Coordinator::activeEntities() const {
  std::vector<int> active;
  if (const StepRecord* s = currentStep())
    for (const auto& t : s->tokens)
      if (t.token.isMotion() && t.state != SegmentState::Done) active.push_back(t.token.entity);
  return active;
}

std::vector<bool> Coordinator::goalConditionsMet() const {
  std::vector<bool> met;
  for (const auto& gc : spec_.goal_conditions) {
    const int e = spec_.entityIndex(gc.entity), at = spec_.entityIndex(gc.at);
    const bool known = e >= 0 && at >= 0 && observation_.positions.size() == spec_.entities.size();
    met.push_back(known && (observation_.positions[e] - observation_.positions[at]).norm() <= gc.tolerance);
  }
  return met;
}

bool Coordinator::allTracked() const {
  if (observation_.tracked.size() != spec_.entities.size()) return false;
  for (bool t : observation_.tracked)
    if (!t) return false;
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
  pending_paths_.clear();
  setState(RunState::Aborted, out);
}

void Coordinator::stopActive(CoordinatorOutput& out) {
  if (StepRecord* s = steps_.empty() ? nullptr : &steps_.back()) {
    for (auto& t : s->tokens) {
      if (t.segment_id != 0 && t.state != SegmentState::Done && t.state != SegmentState::Failed) {
        out.stop.push_back(t.token.entity);
        t.state = SegmentState::Aborted;
      }
    }
  }
}

void Coordinator::requestDecisionOrWait(double now_s, CoordinatorOutput& out) {
  if (!allTracked()) {
    setState(RunState::WaitingForEntities, out);
    return;
  }
  if (static_cast<int>(steps_.size()) >= config_.max_steps) {
    abort("the policy did not say END within max_steps = " + std::to_string(config_.max_steps) + " steps", out);
    return;
  }
  task::Snapshot snap;
  snap.row = static_cast<int>(history_.size());
  snap.positions = observation_.positions;
  history_.push_back(snap);
  DecisionRequest req;
  req.id = nextId();
  req.step = static_cast<int>(steps_.size());
  req.history = history_;
  pending_decision_ = req.id;
  pending_since_s_ = now_s;
  ++decisions_requested_;
  out.log.push_back("requesting decision " + std::to_string(req.step + 1));
  out.decision = std::move(req);
  setState(RunState::Deciding, out);
}

CoordinatorOutput Coordinator::start(double now_s) {
  CoordinatorOutput out;
  if (state_ == RunState::Idle) {
    reason_.clear();
    history_.clear();
    steps_.clear();
    decisions_requested_ = 0;
    last_decision_.reset();
    requestDecisionOrWait(now_s, out);
    out.state_changed = true;
  } else if (state_ == RunState::Paused) {
    if (currentStep() != nullptr)
      requestPaths(now_s, out);  // re-plan what is left of the step from where robots stopped
    else requestDecisionOrWait(now_s, out);
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
  if (state_ != RunState::WaitingForEntities && state_ != RunState::Deciding && state_ != RunState::Planning &&
      state_ != RunState::Executing) {
    out.log.push_back(std::string("pause refused in state ") + toString(state_));
    return out;
  }
  if (state_ == RunState::Deciding && !history_.empty()) history_.pop_back();
  pending_decision_ = 0;
  pending_paths_.clear();
  stopActive(out);
  setState(RunState::Paused, out);
  return out;
}

CoordinatorOutput Coordinator::reset(double) {
  CoordinatorOutput out;
  stopActive(out);
  out.stop_all = true;
  history_.clear();
  steps_.clear();
  decisions_requested_ = 0;
  last_decision_.reset();
  pending_decision_ = 0;
  pending_paths_.clear();
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
  pending_paths_.clear();
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
  if (state_ == RunState::WaitingForEntities && allTracked()) {
    out.log.push_back("every entity is tracked");
    requestDecisionOrWait(now_s, out);
  } else if (state_ == RunState::Executing && !steps_.empty()) {
    updateDistances();
    // A DONE that came before the tracked pose agreed counts once it does.
    bool any = false;
    for (auto& t : steps_.back().tokens)
      if (t.done_claimed && t.state != SegmentState::Done && arrived(t)) {
        t.state = SegmentState::Done;
        t.progress = 1.0;
        out.log.push_back("done: " + task::tokenKey(t.token, spec_) + " (tracked pose now within the arrival radius)");
        any = true;
      }
    if (any) completeStepIfDone(now_s, out);
  }
  return out;
}

bool Coordinator::arrived(const TokenRecord& t) const {
  const auto e = static_cast<size_t>(t.token.entity);
  if (observation_.positions.size() <= e || !observation_.tracked[e]) return false;
  return task::arrived(observation_.positions[e], t.goal, config_.arrival_radius_m + config_.arrival_tolerance_m);
}

void Coordinator::updateDistances() {
  for (auto& t : steps_.back().tokens) {
    const auto e = static_cast<size_t>(t.token.entity);
    if (t.segment_id != 0 && observation_.positions.size() > e && observation_.tracked[e])
      t.distance_to_goal_m = (observation_.positions[e] - t.goal).norm();
  }
}

CoordinatorOutput Coordinator::onDecision(uint32_t id, const Decision& d, double now_s,
                                          const DecisionProbabilities& prob) {
  CoordinatorOutput out;
  if (state_ != RunState::Deciding || id != pending_decision_ || id == 0) {
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
    reason_ = "the policy predicted END after " + std::to_string(steps_.size()) + " steps";
    out.log.push_back(reason_);
    setState(RunState::Finished, out);
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
  const auto& decided = history_.back().positions;
  std::vector<bool> seen(n, false);
  for (size_t i = 0; i < d.tokens.size(); ++i) {
    const task::Token& tok = d.tokens[i];
    if (tok.entity < 0 || tok.entity >= n || tok.target >= n || tok.target == tok.entity || tok.action.empty()) {
      abort("the policy returned an invalid token (entity " + std::to_string(tok.entity) + ", target " +
                std::to_string(tok.target) + ", action '" + tok.action + "')",
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
    r.start = decided[tok.entity];
    r.state = tok.isMotion() ? SegmentState::Sent : SegmentState::Done;
    if (!tok.isMotion()) r.progress = 1.0;
    step.tokens.push_back(std::move(r));
  }
  // Once every token is known valid: where the step's bodies end, together (an end point
  // depends on the step's other tokens: a load, an end another motion takes).
  const std::vector<Eigen::Vector2d> ends = task::stepEndPositions(spec_, end_points_, d.tokens, decided);
  for (size_t i = 0; i < d.tokens.size(); ++i) step.tokens[i].goal = ends[static_cast<size_t>(d.tokens[i].entity)];
  std::ostringstream os;
  os << "step " << step.step + 1 << ":";
  for (const auto& t : step.tokens) os << " " << task::tokenKey(t.token, spec_);
  out.log.push_back(os.str());
  steps_.push_back(std::move(step));
  requestPaths(now_s, out);
  return out;
}

CoordinatorOutput Coordinator::onDecisionError(uint32_t id, const std::string& error, double) {
  CoordinatorOutput out;
  if (state_ != RunState::Deciding || id != pending_decision_ || id == 0) return out;
  abort("no decision for step " + std::to_string(steps_.size() + 1) + ": " + error, out);
  return out;
}

void Coordinator::requestPaths(double now_s, CoordinatorOutput& out) {
  StepRecord& s = steps_.back();
  pending_paths_.assign(s.tokens.size(), 0);
  bool any = false;
  for (size_t i = 0; i < s.tokens.size(); ++i) {
    TokenRecord& t = s.tokens[i];
    if (!t.token.isMotion() || t.state == SegmentState::Done) continue;
    PathRequest req;
    req.id = nextId();
    req.step = s.step;
    req.token = t.token;
    // After a pause the entity continues from where it stopped; the goal stays fixed.
    req.start = (s.segments_sent_s >= 0 && observation_.positions.size() > static_cast<size_t>(t.token.entity))
                    ? observation_.positions[t.token.entity]
                    : t.start;
    req.goal = t.goal;
    pending_paths_[i] = req.id;
    t.path = {};
    t.segment_id = 0;
    t.state = SegmentState::Sent;
    out.paths.push_back(req);
    any = true;
  }
  pending_since_s_ = now_s;
  if (any) {
    setState(RunState::Planning, out);
  } else {
    setState(RunState::Executing, out);
    completeStepIfDone(now_s, out);
  }
}

CoordinatorOutput Coordinator::onPath(uint32_t id, const PlannedPath& path, const std::string& error, double now_s) {
  CoordinatorOutput out;
  if (state_ != RunState::Planning || id == 0) return out;
  StepRecord& s = steps_.back();
  size_t slot = pending_paths_.size();
  for (size_t i = 0; i < pending_paths_.size(); ++i)
    if (pending_paths_[i] == id) slot = i;
  if (slot == pending_paths_.size()) return out;
  const std::string key = task::tokenKey(s.tokens[slot].token, spec_);
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
  const double end_error = (path.points.back() - s.tokens[slot].goal).norm();
  if (end_error > config_.arrival_radius_m) {
    std::ostringstream os;
    os << "the path for " << key << " ends " << end_error
       << " m from its end point (more than arrival_radius_m = " << config_.arrival_radius_m
       << " m): not a path for this token";
    abort(os.str(), out);
    return out;
  }
  s.tokens[slot].path = carrierPath(s, slot, path);
  pending_paths_[slot] = 0;
  for (uint32_t p : pending_paths_)
    if (p != 0) return out;

  // Every path is in: send all segments together so the robots start together.
  for (auto& t : s.tokens) {
    if (!t.token.isMotion() || t.state == SegmentState::Done) continue;
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
    t.state = SegmentState::Sent;
    t.progress = 0;
    t.timeout_s = cmd.timeout_s;
    t.done_claimed = false;
    t.distance_to_goal_m = std::numeric_limits<double>::quiet_NaN();
    out.segments.push_back(std::move(cmd));
  }
  s.segments_sent_s = now_s;
  segments_since_s_ = now_s;
  setState(RunState::Executing, out);
  updateDistances();
  return out;
}

PlannedPath Coordinator::carrierPath(StepRecord& s, size_t slot, const PlannedPath& planned) {
  std::vector<task::Token> step;
  for (const TokenRecord& t : s.tokens) step.push_back(t.token);
  const std::optional<int> load = pushedLoad(spec_, step, slot, history_.back().positions);
  if (!load) return planned;
  const TokenRecord* l = nullptr;
  for (const TokenRecord& t : s.tokens)
    if (t.token.entity == *load) l = &t;
  // A re-plan after a pause starts where the load is now.
  const auto e = static_cast<size_t>(*load);
  const bool seen = s.segments_sent_s >= 0 && observation_.positions.size() > e && observation_.tracked[e];
  TokenRecord& c = s.tokens[slot];
  PlannedPath out;
  out.points = pushPath(planned.points.front(), seen ? observation_.positions[e] : l->start, l->goal,
                        spec_.contactDistance(c.token.entity, *load), c.goal, static_cast<int>(planned.points.size()));
  out.stddev_m.assign(out.points.size(), 0.0);
  c.goal = out.points.back();  // behind the load's end point: where the push stops
  return out;
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
  if (state_ != RunState::Executing || steps_.empty() || r.segment_id == 0) return out;
  StepRecord& s = steps_.back();
  TokenRecord* rec = nullptr;
  for (auto& t : s.tokens)
    if (t.segment_id == r.segment_id && t.token.entity == r.topic_entity) rec = &t;
  if (rec == nullptr) {
    bool other = false;  // a running segment of another entity: a status on the wrong topic
    for (const auto& t : s.tokens) other = other || t.segment_id == r.segment_id;
    if (other)
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
    abort("segment " + key + " " + toString(st) + (r.message.empty() ? "" : ": " + r.message), out);
    return out;
  }
  if (st != SegmentState::Done) {
    if (!rec->done_claimed) rec->state = st;
    return out;
  }
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
  rec->state = SegmentState::Done;
  rec->progress = 1.0;
  out.log.push_back("done: " + key);
  completeStepIfDone(now_s, out);
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

void Coordinator::completeStepIfDone(double now_s, CoordinatorOutput& out) {
  StepRecord& s = steps_.back();
  for (const auto& t : s.tokens)
    if (t.state != SegmentState::Done) return;
  s.finished_s = now_s;
  s.complete = true;
  out.log.push_back("step " + std::to_string(s.step + 1) + " complete");
  requestDecisionOrWait(now_s, out);
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
  history_.clear();
  steps_.clear();
  abort(why, out);
  out.state_changed = true;
  return out;
}

CoordinatorOutput Coordinator::onTick(double now_s) {
  CoordinatorOutput out;
  if (state_ == RunState::Deciding && now_s - pending_since_s_ > config_.decision_timeout_s) {
    abort("no decision within decision_timeout_s = " + seconds(config_.decision_timeout_s), out);
  } else if (state_ == RunState::Planning && now_s - pending_since_s_ > config_.path_timeout_s) {
    abort("not every path arrived within path_timeout_s = " + seconds(config_.path_timeout_s), out);
  } else if (state_ == RunState::Executing && !steps_.empty()) {
    for (const auto& t : steps_.back().tokens) {
      if (t.segment_id == 0 || t.state == SegmentState::Done) continue;
      const double timeout = t.timeout_s;
      if (now_s - segments_since_s_ > timeout) {
        std::ostringstream os;
        os << "segment " << task::tokenKey(t.token, spec_) << " timed out after " << timeout << " s (progress "
           << t.progress << ")";
        abort(os.str(), out);
        break;
      }
    }
  }
  return out;
}

}  // namespace ddace::exec
