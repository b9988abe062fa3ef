#include "ddace/exec/bodies_execution.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "ddace/common/error.h"
#include "ddace/task/end_point.h"

namespace ddace::exec {

namespace {
double lengthOf(const Path& p) {
  double s = 0;
  for (size_t i = 1; i < p.size(); ++i) s += (p[i] - p[i - 1]).norm();
  return s;
}
}  // namespace

// One motion of the trial: as it was sent and decided, and while it runs.
struct BodiesExecution::Motion {
  StepMotion motion;
  task::Token token;
  int step = 0;
  uint32_t batch = 0;  ///< motions started together (startMotions) share it, and their time limit
  double t0 = 0, limit_s = 0;
  Eigen::Vector2d final_at{0, 0};  ///< where it ends (its path's end)
  MotionContacts contacts;
  Path executed;
  bool moving = false;
};

BodiesExecution::BodiesExecution(const BodiesExecutionParams& params) : params_(params) {
  if (!(params_.noise_m >= 0) || !std::isfinite(params_.noise_m))
    throw Error("bodies execution: noise_m must be a finite number >= 0");
  // The one stop rule with this model's own noise as the tolerance.
  stop_tolerance_m_ = task::stopTolerance(params_.noise_m);
  stop_radius_m_ = task::stopRadius(params_.arrival_radius_m, stop_tolerance_m_);
  controller_.gains = params_.config.gains;
  controller_.safety = params_.config.safety;
  controller_.validate();
  params_.config.robot.position_noise_m = params_.noise_m;
  params_.config.robot.validate();
  params_.config.table.validate();
}

BodiesExecution::~BodiesExecution() = default;

Path BodiesExecution::follow(const Path&, bool, int) {
  throw Error("execution with bodies runs the motions of a step together (executeStep), not one by one");
}

void BodiesExecution::beginTrial(const task::TaskSpec& spec, const std::vector<Pose2D>& start) {
  DiffDriveParams robot = params_.config.robot;
  robot.seed = params_.seed * 1000003ULL + params_.first_trial + trials_++;  // fresh, reproducible noise per trial
  table_ = std::make_unique<TableSimulator>(spec, start, robot, params_.config.table);
  const size_t n = spec.entities.size();
  controllers_.clear();
  controllers_.resize(n);
  radius_m_.assign(n, 0);
  robot_.assign(n, false);
  names_ = spec.entityNames();
  spec_ = spec;
  for (size_t i = 0; i < n; ++i) {
    radius_m_[i] = table_->radiusM(static_cast<int>(i));
    robot_[i] = spec.entities[i].kind == task::EntityKind::Robot;
    if (robot_[i]) controllers_[i] = std::make_unique<RobotController>(names_[i], controller_);
  }
  motions_.clear();
  motion_of_.assign(n, -1);
  load_of_.assign(n, -1);
  stalled_until_s_.assign(n, -1);
  dead_.assign(n, false);
  loaded_.clear();
  allowed_ = AllowedContacts();
  ended_.clear();
  running_ = 0;
  contacts_seen_ = table_->contacts().size();
  touching_.assign(n * n, PairContact());
  report_ = {};
}

StepExecution BodiesExecution::executeStep(const task::TaskSpec& spec, const std::vector<task::Token>& tokens,
                                           const std::vector<Eigen::Vector2d>&,
                                           const std::vector<StepMotion>& motions) {
  if (!table_) throw Error("bodies execution: executeStep before beginTrial");
  StepExecution out;
  const size_t first = motions_.size();
  const double t0 = table_->time();
  out.failures = startMotions(spec, 0, tokens, motions);
  while (running_ > 0)
    for (const MotionEnd& e : cycle())  // a robot that stopped short, or the step's time limit
      if (!e.done && (robot_[e.entity] || e.time_limit)) out.failures.push_back(e.message);
  for (size_t m = first; m < motions_.size(); ++m) out.executed.push_back(std::move(motions_[m].executed));
  const int n = static_cast<int>(table_->size());
  out.duration_s = table_->time() - t0;
  out.positions.resize(n);
  for (int i = 0; i < n; ++i) out.positions[i] = table_->truePose(i).position();
  return out;
}

std::vector<std::string> BodiesExecution::startMotions(const task::TaskSpec&, int step,
                                                       const std::vector<task::Token>& tokens,
                                                       const std::vector<StepMotion>& motions) {
  if (!table_) throw Error("bodies execution: a motion started before beginTrial");
  const size_t first = addMotions(step, tokens, motions);
  decideNewContacts(first);
  redecideRunning(first, step);
  loaded_ = {table_->loadedPairs().begin(), table_->loadedPairs().end()};
  std::vector<std::string> failures = launch(first);
  allowContacts(first);
  return failures;
}

size_t BodiesExecution::addMotions(int step, const std::vector<task::Token>& tokens,
                                   const std::vector<StepMotion>& motions) {
  const int n = static_cast<int>(table_->size());
  const uint32_t batch = ++batches_;
  const size_t first = motions_.size();
  for (const StepMotion& mo : motions) {
    if (mo.entity < 0 || mo.entity >= n) throw Error("bodies execution: a motion of an entity outside the task");
    if (mo.token >= tokens.size()) throw Error("bodies execution: a motion of a token outside its step");
    stopMotion(mo.entity);  // replaced
    Motion m;
    m.motion = mo;
    m.token = tokens[mo.token];
    m.step = step;
    m.batch = batch;
    m.t0 = table_->time();
    m.final_at = mo.planned.empty() ? table_->truePose(mo.entity).position() : mo.planned.back();
    m.moving = true;
    motion_of_[mo.entity] = static_cast<int>(motions_.size());
    motions_.push_back(std::move(m));
  }
  return first;
}

void BodiesExecution::decideNewContacts(size_t first) {
  // What each may touch: decided once, as the coordinator's segments are by the path
  // follower node (exec::motionContacts), from where every body ends.
  for (size_t m = first; m < motions_.size(); ++m) {
    const int e = motions_[m].motion.entity;
    if (!(radius_m_[e] > 0)) continue;
    motions_[m].contacts = contactsOf(motions_[m]);
    load_of_[e] = -1;
    if (motions_[m].motion.robot) rideLoad(e);
    else dropLoad(motions_[m].contacts);  // only robots carry
  }
}

void BodiesExecution::redecideRunning(size_t first, int step) {
  // The step's robots already running decide again with the new motions, as the path
  // follower node does whenever its step's segments change: a robot bound for a goal that a
  // later-started one ends on may now end against it.
  for (size_t m = 0; m < first; ++m) {
    Motion& o = motions_[m];
    const int e = o.motion.entity;
    if (!o.moving || o.step != step || !o.motion.robot || !(radius_m_[e] > 0)) continue;
    MotionContacts c = contactsOf(o);
    if (load_of_[e] >= 0) {  // its load goes with it whatever is decided now
      c.load = o.contacts.load, c.load_rides = o.contacts.load_rides, c.load_end = o.contacts.load_end,
      c.load_at = o.contacts.load_at;
    } else {
      dropLoad(c);
    }
    o.contacts = c;
    controllers_[e]->setContacts(std::move(c));
  }
}

std::vector<std::string> BodiesExecution::launch(size_t first) {
  std::vector<std::string> failures;
  double limit_s = 0;
  for (size_t m = first; m < motions_.size(); ++m) {
    const std::string why = startMotion(m);
    if (!why.empty()) failures.push_back(why);
    else limit_s = std::max(limit_s, motions_[m].limit_s);
  }
  for (size_t m = first; m < motions_.size(); ++m) motions_[m].limit_s = limit_s;
  return failures;
}

void BodiesExecution::allowContacts(size_t first) {
  // The collisions are judged by what the running motions may touch, as decided.
  std::vector<DecidedMotion> decided;
  for (size_t m = 0; m < motions_.size(); ++m)
    if (motions_[m].moving || m >= first) {
      const Motion& mo = motions_[m];
      decided.push_back({mo.motion.entity, mo.motion.target, mo.final_at, mo.contacts});
    }
  allowed_ = AllowedContacts(names_, radius_m_, decided, controller_.safety.endsAgainstReachM());
}

std::vector<MotionEnd> BodiesExecution::cycle() {
  if (!table_) throw Error("bodies execution: a cycle before beginTrial");
  for (size_t i = 0; i < stalled_until_s_.size(); ++i)
    if (stalled_until_s_[i] >= 0 && table_->time() >= stalled_until_s_[i]) {
      stalled_until_s_[i] = -1;
      if (!dead_[i]) table_->setStalled(static_cast<int>(i), false);
    }
  cycleRobots();
  advanceTable();
  judgeContacts();
  // A batch past its time limit: whoever of it still moves stops where it is.
  std::set<uint32_t> late;
  for (const Motion& m : motions_)
    if (m.moving && !(table_->time() - m.t0 < m.limit_s)) late.insert(m.batch);
  for (uint32_t b : late) stopBatch(b);
  std::vector<MotionEnd> out;
  out.swap(ended_);
  return out;
}

void BodiesExecution::stopMotion(int entity) {
  const int m = entity >= 0 && entity < static_cast<int>(motion_of_.size()) ? motion_of_[entity] : -1;
  if (m < 0 || !motions_[m].moving) return;
  if (robot_[entity]) {
    controllers_[entity]->cancel();
    table_->commandWheels(entity, {});
  } else {
    table_->stopSegment(entity);
  }
  finish(static_cast<size_t>(m));
  endRide(entity, false);
}

bool BodiesExecution::moving(int entity) const {
  const int m = entity >= 0 && entity < static_cast<int>(motion_of_.size()) ? motion_of_[entity] : -1;
  return m >= 0 && motions_[m].moving;
}

const Path& BodiesExecution::executed(int entity) const {
  static const Path none;
  const int m = entity >= 0 && entity < static_cast<int>(motion_of_.size()) ? motion_of_[entity] : -1;
  return m >= 0 ? motions_[m].executed : none;
}

double BodiesExecution::time() const {
  return table_ ? table_->time() : 0;
}

std::vector<Eigen::Vector2d> BodiesExecution::positions() const {
  std::vector<Eigen::Vector2d> out;
  for (int i = 0; table_ && i < static_cast<int>(table_->size()); ++i) out.push_back(table_->truePose(i).position());
  return out;
}

void BodiesExecution::displace(int entity, const Eigen::Vector2d& by) {
  if (!table_) throw Error("bodies execution: a perturbation before beginTrial");
  table_->place(entity, table_->truePose(entity).position() + by);
}

void BodiesExecution::stall(int entity, double until_s) {
  if (!table_) throw Error("bodies execution: a perturbation before beginTrial");
  table_->setStalled(entity, true);
  stalled_until_s_.at(static_cast<size_t>(entity)) = until_s;
}

void BodiesExecution::kill(int entity) {
  if (!table_) throw Error("bodies execution: a perturbation before beginTrial");
  table_->setStalled(entity, true);
  dead_.at(static_cast<size_t>(entity)) = true;
}

void BodiesExecution::setSpeedFactor(int entity, double factor) {
  if (!table_) throw Error("bodies execution: a speed factor before beginTrial");
  table_->setWheelGain(entity, factor);
}

MotionContacts BodiesExecution::contactsOf(const Motion& motion) const {
  const int n = static_cast<int>(table_->size());
  const int i = motion.motion.entity;
  std::vector<BodyAtStart> others;
  for (int j = 0; j < n; ++j) {
    if (!(radius_m_[j] > 0) || j == i) continue;
    BodyAtStart b;
    b.name = names_[j], b.position = b.final_position = table_->truePose(j).position(), b.radius_m = radius_m_[j];
    b.object = spec_.entities[j].kind == task::EntityKind::Object;
    if (const int m = motion_of_[j]; m >= 0 && motions_[m].moving) {
      const Motion& o = motions_[m];
      b.final_position = o.final_at;
      b.step = o.step;
      b.action = o.token.action;
      b.target = targetName(o.token.target);
      b.way = o.motion.planned;
    }
    others.push_back(b);
  }
  return motionContacts(table_->truePose(i).position(), radius_m_[i], motion.final_at, motion.step, motion.token.action,
                        targetName(motion.token.target), others, controller_.safety.endsAgainstReachM(),
                        params_.arrival_radius_m, motion.motion.planned);
}

std::string BodiesExecution::targetName(int target) const {
  return target >= 0 && target < static_cast<int>(names_.size()) ? names_[target] : "";
}

void BodiesExecution::dropLoad(MotionContacts& contacts) {
  contacts.load.clear();
  contacts.load_ends_against.clear();
}

// Its load at its carrier rides in front of it, part of its body for the filter; one
// passed from afar moves along its own path.
void BodiesExecution::rideLoad(int carrier) {
  MotionContacts& contacts = motions_[static_cast<size_t>(motion_of_[carrier])].contacts;
  const int load = spec_.entityIndex(contacts.load);
  if (load < 0) return;
  if (!table_->carry(carrier, load)) {
    dropLoad(contacts);  // another carrier's, or too far
    return;
  }
  load_of_[carrier] = load;
  contacts.load_rides = params_.config.table.loads_ride;
}

std::string BodiesExecution::startMotion(size_t m) {
  Motion& motion = motions_[m];
  const StepMotion& mo = motion.motion;
  const int n = static_cast<int>(table_->size());
  motion.executed = {table_->truePose(mo.entity).position()};
  const double length_m = lengthOf(mo.planned);
  if (mo.robot) {
    RobotController& c = *controllers_.at(mo.entity);
    // Toward a body, it ends at its end point within the tracking noise: at the gap the
    // demonstrations stopped at. A carrier's load is what ends at the target.
    const bool against_body =
        mo.target >= 0 && mo.target < n && radius_m_[mo.target] > 0 && motion.contacts.load.empty();
    const double at_place = task::stopRadiusAgainstBody(stop_radius_m_, stop_tolerance_m_);
    c.start(PlannedPath{mo.planned, {}}, mo.target >= 0 ? names_[mo.target] : std::string(),
            against_body ? at_place : stop_radius_m_, stop_radius_m_, at_place);
    c.setContacts(motion.contacts);
    motion.limit_s = 3.0 * length_m / controller_.gains.cruise_speed_mps + 10.0;
  } else if (spec_.entities[mo.entity].kind != task::EntityKind::Object) {
    // A predicted token that moves a goal: a flat print takes no segment (the ROS
    // coordinator refuses it too). The trial fails; the evaluation goes on.
    motion.moving = false;
    return names_[mo.entity] + ": a " + task::toString(spec_.entities[mo.entity].kind) + " cannot move";
  } else {
    const auto status = table_->startSegment(mo.entity, next_segment_++, mo.planned);
    if (status && status->state != SegmentState::Accepted) {
      motion.moving = false;
      return names_[mo.entity] + ": " + status->message;
    }
    motion.limit_s = 3.0 * length_m / params_.config.table.object_speed_mps + 10.0;
  }
  ++running_;
  return "";
}

void BodiesExecution::finish(size_t m) {
  motions_[m].moving = false;
  --running_;
}

bool BodiesExecution::standing(int entity) const {
  const int m = motion_of_[entity];
  return m < 0 || !motions_[m].moving;
}

// A carrier stopped: arrived (its load goes on the last bit to its end alone), or not
// (the load stops where it is: its motion ends, failed). The two touch: no collision
// until they part.
void BodiesExecution::endRide(int carrier, bool arrived) {
  const int load = load_of_[carrier];
  if (load < 0) return;
  const int n = static_cast<int>(table_->size());
  load_of_[carrier] = -1;
  touching_[std::min(carrier, load) * n + std::max(carrier, load)].touchAllowed();
  const int m = motion_of_[load];
  if (arrived || m < 0 || !motions_[m].moving) {
    table_->endCarry(load);
    return;
  }
  table_->stopSegment(load);
  finish(static_cast<size_t>(m));
  motions_[m].executed.push_back(table_->truePose(load).position());
  ended_.push_back({load, false, names_[load] + " stopped: its carrier " + names_[carrier] + " stopped short"});
}

// One control cycle of every robot, from one tracker frame for everybody. A dead robot's
// controller gets a stale pose; the others see it where it stands.
void BodiesExecution::cycleRobots() {
  const int n = static_cast<int>(table_->size());
  measured_.resize(n);
  for (int i = 0; i < n; ++i) measured_[i] = table_->measuredPose(i);
  for (int i = 0; i < n; ++i) {
    if (!robot_[i]) continue;
    const int m = motion_of_[i];
    if (m < 0 || !motions_[m].moving) {
      table_->commandWheels(i, {});  // idle: zeros every cycle, as the follower node
      continue;
    }
    others_.clear();
    for (int j = 0; j < n; ++j)
      if (j != i && radius_m_[j] > 0) {
        others_.push_back({names_[j], measured_[j].position(), radius_m_[j], robot_[j]});
        others_.back().standing = standing(j);
      }
    const double age_s = dead_[i] ? 1e9 : 0.0;
    const ControlOutput c =
        controllers_[i]->cycle(measured_[i], dead_[i], age_s, radius_m_[i], others_, table_->time());
    table_->commandWheels(i, c.wheels);
    if (c.state == MotionState::Running) continue;
    finish(static_cast<size_t>(m));  // done, or failed (a deadlock): the robot stops there
    const bool done = c.state != MotionState::Failed;
    ended_.push_back({i, done, c.message});
    endRide(i, done);  // the load arrived with it, or stops
  }
}

// The table advances one period; objects that arrived end their motions.
void BodiesExecution::advanceTable() {
  for (const ObjectStatus& s : table_->step()) {
    const int m = motion_of_[s.entity];
    if ((s.state == SegmentState::Done || s.state == SegmentState::Failed) && m >= 0 && motions_[m].moving) {
      finish(static_cast<size_t>(m));
      motions_[m].executed.push_back(table_->truePose(s.entity).position());
      ended_.push_back({s.entity, s.state == SegmentState::Done, s.message});
    }
  }
  for (int e = 0; e < static_cast<int>(motion_of_.size()); ++e)
    if (const int m = motion_of_[e]; m >= 0 && motions_[m].moving)
      motions_[m].executed.push_back(table_->truePose(e).position());
}

// Collisions and the closest approach, on the true poses, by the run report's rule
// (PairContact): a contact that began between bodies apart and not allowed to touch; a
// pair touching by design (a motion that ended at its target) once it pushes in deeper
// than kPartedM when no longer allowed. Box2D keeps resting bodies within kPartedM, so the
// contacts come from its events.
void BodiesExecution::judgeContacts() {
  const int n = static_cast<int>(table_->size());
  const auto& contacts = table_->contacts();
  began_.clear();
  for (; contacts_seen_ < contacts.size(); ++contacts_seen_)
    began_.insert({contacts[contacts_seen_].a, contacts[contacts_seen_].b});
  for (int a = 0; a < n; ++a) {
    if (!(radius_m_[a] > 0)) continue;
    const Eigen::Vector2d pa = table_->truePose(a).position();
    for (int b = a + 1; b < n; ++b) {
      if (!(radius_m_[b] > 0) || loaded_.count({a, b})) continue;
      const Eigen::Vector2d pb = table_->truePose(b).position();
      const double gap = (pa - pb).norm() - radius_m_[a] - radius_m_[b];
      const bool ok = allowed_.allowed(a, b, pa, pb);
      PairContact& pair = touching_[a * n + b];
      if (pair.update(gap, began_.count({a, b}) > 0, ok, kPartedM))
        report_.collisions.push_back({table_->time(), a, b});
      if (pair.measured(ok) && gap < report_.closest.clearance_m) report_.closest = {gap, a, b, table_->time(), pa, pb};
    }
  }
}

// The time limit: whoever of the batch still moves stops where it is; its loads stop riding.
void BodiesExecution::stopBatch(uint32_t batch) {
  double limit_s = 0;
  for (size_t m = 0; m < motions_.size(); ++m) {
    Motion& motion = motions_[m];
    if (motion.batch != batch || !motion.moving) continue;
    limit_s = motion.limit_s;
    const int e = motion.motion.entity;
    if (motion.motion.robot) {
      controllers_[e]->cancel();
      table_->commandWheels(e, {});
      finish(m);
    } else {
      table_->stopSegment(e);
      if (table_->carrierOf(e) < 0) finish(m);  // a riding load stops with its carrier, below
    }
    char why[160];
    std::snprintf(why, sizeof why, "%s did not arrive within %.1f s (3x its path at cruise speed + 10 s)",
                  names_[e].c_str(), limit_s);
    MotionEnd end{e, false, why};
    end.time_limit = true;
    ended_.push_back(end);
  }
  for (const Motion& motion : motions_)
    if (motion.batch == batch && motion.motion.robot) {
      const size_t before = ended_.size();
      endRide(motion.motion.entity, false);
      ended_.resize(before);  // the load's end is reported above
    }
  for (size_t m = 0; m < motions_.size(); ++m)  // riding another batch's carrier
    if (motions_[m].batch == batch && motions_[m].moving) {
      table_->endCarry(motions_[m].motion.entity);
      finish(m);
    }
}

}  // namespace ddace::exec
