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

// One step's motions while they run: what was decided when the step began and what is
// still moving.
struct BodiesExecution::Step {
  const task::TaskSpec& spec;
  const std::vector<task::Token>& tokens;
  const std::vector<StepMotion>& motions;
  StepExecution out;
  double t0 = 0;
  double limit_s = 0;                               ///< the step's time limit (the longest motion's)
  int running = 0;                                  ///< motions still running
  std::vector<bool> moving;                         ///< per motion
  std::vector<int> motion_of;                       ///< per entity: its motion, or -1
  std::vector<Eigen::Vector2d> start_at, final_at;  ///< per entity: where it is / ends
  std::vector<MotionContacts> contacts;             ///< per entity: what its motion may touch
  std::vector<int> load_of;                         ///< per carrier: the load riding with it, or -1
  std::set<std::pair<int, int>> loaded;             ///< pairs placed overlapping (never judged)
  AllowedContacts allowed;
  // Scratch of every cycle.
  std::vector<Pose2D> measured;
  std::set<std::pair<int, int>> began;
  std::vector<SafetyBody> others;

  Step(const task::TaskSpec& s, const std::vector<task::Token>& t, const std::vector<StepMotion>& m)
      : spec(s), tokens(t), motions(m) {}
  /// Motion `m` stopped (arrived, failed or stopped short).
  void finish(size_t m) {
    moving[m] = false;
    --running;
  }
  bool standing(int entity) const { return motion_of[entity] < 0 || !moving[motion_of[entity]]; }
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
  robot.seed = params_.seed * 1000003ULL + (++trials_);  // fresh, reproducible noise per trial
  table_ = std::make_unique<TableSimulator>(spec, start, robot, params_.config.table);
  const size_t n = spec.entities.size();
  controllers_.clear();
  controllers_.resize(n);
  radius_m_.assign(n, 0);
  robot_.assign(n, false);
  names_ = spec.entityNames();
  for (size_t i = 0; i < n; ++i) {
    radius_m_[i] = table_->radiusM(static_cast<int>(i));
    robot_[i] = spec.entities[i].kind == task::EntityKind::Robot;
    if (robot_[i]) controllers_[i] = std::make_unique<RobotController>(names_[i], controller_);
  }
  contacts_seen_ = table_->contacts().size();
  touching_.assign(n * n, PairContact());
  report_ = {};
}

StepExecution BodiesExecution::executeStep(const task::TaskSpec& spec, const std::vector<task::Token>& tokens,
                                           const std::vector<Eigen::Vector2d>&,
                                           const std::vector<StepMotion>& motions) {
  if (!table_) throw Error("bodies execution: executeStep before beginTrial");
  Step step(spec, tokens, motions);
  decideContacts(step);
  for (size_t m = 0; m < motions.size(); ++m) startMotion(step, m);
  // The collisions are judged by what the step's motions may touch, as decided above.
  std::vector<DecidedMotion> decided;
  for (const StepMotion& mo : motions)
    decided.push_back({mo.entity, mo.target, step.final_at[mo.entity], step.contacts[mo.entity]});
  step.allowed = AllowedContacts(names_, radius_m_, decided, controller_.safety.margin_m);

  while (step.running > 0 && table_->time() - step.t0 < step.limit_s) {
    cycleRobots(step);
    advanceTable(step);
    judgeContacts(step);
  }
  stopUnfinished(step);
  const int n = static_cast<int>(table_->size());
  step.out.duration_s = table_->time() - step.t0;
  step.out.positions.resize(n);
  for (int i = 0; i < n; ++i) step.out.positions[i] = table_->truePose(i).position();
  return std::move(step.out);
}

// Where the step's bodies end (the motions' end points, else where they stand) and what
// each motion may touch: decided once, as the coordinator decides them for the robots'
// segments (exec::motionContacts, the path follower node's answer).
void BodiesExecution::decideContacts(Step& step) {
  const int n = static_cast<int>(table_->size());
  const auto& motions = step.motions;
  step.t0 = table_->time();
  step.out.executed.resize(motions.size());
  step.moving.assign(motions.size(), true);
  step.motion_of.assign(n, -1);
  for (size_t m = 0; m < motions.size(); ++m) {
    const StepMotion& mo = motions[m];
    if (mo.entity < 0 || mo.entity >= n) throw Error("bodies execution: a motion of an entity outside the task");
    step.motion_of[mo.entity] = static_cast<int>(m);
  }
  step.final_at.resize(n);
  step.start_at.resize(n);
  for (int j = 0; j < n; ++j) step.final_at[j] = step.start_at[j] = table_->truePose(j).position();
  for (const StepMotion& mo : motions)
    if (!mo.planned.empty()) step.final_at[mo.entity] = mo.planned.back();
  const std::vector<BodyAtStart> bodies = bodiesAtStart(step);
  step.contacts.assign(n, MotionContacts());
  step.load_of.assign(n, -1);
  for (const StepMotion& mo : motions) {
    if (!(radius_m_[mo.entity] > 0)) continue;
    step.contacts[mo.entity] = contactsOf(step, bodies, mo.entity);
    if (mo.robot) rideLoad(step, mo.entity);
    else dropLoad(step.contacts[mo.entity]);  // only robots carry
  }
  step.loaded = {table_->loadedPairs().begin(), table_->loadedPairs().end()};
}

std::vector<BodyAtStart> BodiesExecution::bodiesAtStart(const Step& step) const {
  const int n = static_cast<int>(table_->size());
  std::vector<BodyAtStart> bodies;
  for (int j = 0; j < n; ++j) {
    if (!(radius_m_[j] > 0)) continue;
    BodyAtStart b;
    b.name = names_[j], b.position = step.start_at[j], b.final_position = step.final_at[j], b.radius_m = radius_m_[j];
    b.object = step.spec.entities[j].kind == task::EntityKind::Object;
    if (const int m = step.motion_of[j]; m >= 0) {
      const task::Token& t = step.tokens.at(step.motions[m].token);
      b.step = 0;
      b.action = t.action;
      b.target = targetName(t.target);
    }
    bodies.push_back(b);
  }
  return bodies;
}

MotionContacts BodiesExecution::contactsOf(const Step& step, const std::vector<BodyAtStart>& bodies, int i) const {
  std::vector<BodyAtStart> others;
  for (const BodyAtStart& b : bodies)
    if (b.name != names_[i]) others.push_back(b);
  const task::Token& t = step.tokens.at(step.motions[step.motion_of[i]].token);
  return motionContacts(step.start_at[i], radius_m_[i], step.final_at[i], 0, t.action, targetName(t.target), others,
                        controller_.safety.margin_m, params_.arrival_radius_m);
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
void BodiesExecution::rideLoad(Step& step, int carrier) {
  MotionContacts& contacts = step.contacts[carrier];
  const int load = step.spec.entityIndex(contacts.load);
  if (load < 0) return;
  if (!(table_->carrierOf(load) < 0 && table_->ride(carrier, load))) {
    dropLoad(contacts);  // another carrier's, or too far to ride
    return;
  }
  step.load_of[carrier] = load;
  contacts.load_rides = true;
}

void BodiesExecution::startMotion(Step& step, size_t m) {
  const StepMotion& mo = step.motions[m];
  const int n = static_cast<int>(table_->size());
  step.out.executed[m] = {table_->truePose(mo.entity).position()};
  const double length_m = lengthOf(mo.planned);
  if (mo.robot) {
    RobotController& c = *controllers_.at(mo.entity);
    // Toward a body, it stops where it is still at one place with it (where the body ends);
    // a carrier's load is what ends at the target.
    double stop = stop_radius_m_;
    if (mo.target >= 0 && mo.target < n && radius_m_[mo.target] > 0 && step.contacts[mo.entity].load.empty())
      stop = task::stopRadiusToward(
          stop, stop_tolerance_m_,
          task::togetherDistance(radius_m_[mo.entity] + radius_m_[mo.target], params_.arrival_radius_m),
          (step.final_at[mo.entity] - step.final_at[mo.target]).norm());
    c.start(PlannedPath{mo.planned, {}}, mo.target >= 0 ? names_[mo.target] : std::string(), stop, stop_radius_m_);
    c.setContacts(step.contacts[mo.entity]);
    step.limit_s = std::max(step.limit_s, 3.0 * length_m / controller_.gains.cruise_speed_mps + 10.0);
  } else if (step.spec.entities[mo.entity].kind != task::EntityKind::Object) {
    // A predicted token that moves a goal: a flat print takes no segment (the ROS
    // coordinator refuses it too). The trial fails; the evaluation goes on.
    step.moving[m] = false;
    step.out.failures.push_back(names_[mo.entity] + ": a " + task::toString(step.spec.entities[mo.entity].kind) +
                                " cannot move");
    return;
  } else {
    const auto status = table_->startSegment(mo.entity, next_segment_++, mo.planned);
    if (status && status->state != SegmentState::Accepted) {
      step.moving[m] = false;
      step.out.failures.push_back(names_[mo.entity] + ": " + status->message);
      return;
    }
    step.limit_s = std::max(step.limit_s, 3.0 * length_m / params_.config.table.object_speed_mps + 10.0);
  }
  ++step.running;
}

// A carrier stopped: arrived (its load goes on the last bit to its end alone), or failed
// (the load stops where it is). The two touch: no collision until they part.
void BodiesExecution::endRide(Step& step, int carrier, bool arrived) {
  const int load = step.load_of[carrier];
  if (load < 0) return;
  const int n = static_cast<int>(table_->size());
  step.load_of[carrier] = -1;
  touching_[std::min(carrier, load) * n + std::max(carrier, load)].touchAllowed();
  const int m = step.motion_of[load];
  if (arrived || m < 0 || !step.moving[m]) {
    table_->endRide(load);
    return;
  }
  table_->stopSegment(load);
  step.finish(m);
  step.out.executed[m].push_back(table_->truePose(load).position());
}

// One control cycle of every robot, from one tracker frame for everybody.
void BodiesExecution::cycleRobots(Step& step) {
  const int n = static_cast<int>(table_->size());
  step.measured.resize(n);
  for (int i = 0; i < n; ++i) step.measured[i] = table_->measuredPose(i);
  for (int i = 0; i < n; ++i) {
    if (!robot_[i]) continue;
    const int m = step.motion_of[i];
    if (m < 0 || !step.moving[m]) {
      table_->commandWheels(i, {});  // idle: zeros every cycle, as the follower node
      continue;
    }
    step.others.clear();
    for (int j = 0; j < n; ++j)
      if (j != i && radius_m_[j] > 0) {
        step.others.push_back({names_[j], step.measured[j].position(), radius_m_[j], robot_[j]});
        step.others.back().standing = step.standing(j);
      }
    const ControlOutput c =
        controllers_[i]->cycle(step.measured[i], false, 0.0, radius_m_[i], step.others, table_->time());
    table_->commandWheels(i, c.wheels);
    if (c.state == MotionState::Running) continue;
    step.finish(m);                                  // done, or failed (a deadlock): the robot stops there
    endRide(step, i, c.state == MotionState::Done);  // the load arrived with it, or stops
    if (c.state == MotionState::Failed) step.out.failures.push_back(c.message);
  }
}

// The table advances one period; objects that arrived end their motions.
void BodiesExecution::advanceTable(Step& step) {
  for (const ObjectStatus& s : table_->step()) {
    const int m = step.motion_of[s.entity];
    if (s.state == SegmentState::Done && m >= 0 && step.moving[m]) {
      step.finish(m);
      step.out.executed[m].push_back(table_->truePose(s.entity).position());
    }
  }
  for (size_t m = 0; m < step.motions.size(); ++m)
    if (step.moving[m]) step.out.executed[m].push_back(table_->truePose(step.motions[m].entity).position());
}

// Collisions and the closest approach, on the true poses, by the run report's rule
// (PairContact): a contact that began between bodies apart and not allowed to touch; a
// pair touching by design (a motion that ended at its target) once it pushes in deeper
// than kPartedM when no longer allowed. Box2D keeps resting bodies within kPartedM, so the
// contacts come from its events.
void BodiesExecution::judgeContacts(Step& step) {
  const int n = static_cast<int>(table_->size());
  const auto& contacts = table_->contacts();
  step.began.clear();
  for (; contacts_seen_ < contacts.size(); ++contacts_seen_)
    step.began.insert({contacts[contacts_seen_].a, contacts[contacts_seen_].b});
  for (int a = 0; a < n; ++a) {
    if (!(radius_m_[a] > 0)) continue;
    const Eigen::Vector2d pa = table_->truePose(a).position();
    for (int b = a + 1; b < n; ++b) {
      if (!(radius_m_[b] > 0) || step.loaded.count({a, b})) continue;
      const Eigen::Vector2d pb = table_->truePose(b).position();
      const double gap = (pa - pb).norm() - radius_m_[a] - radius_m_[b];
      const bool ok = step.allowed.allowed(a, b, pa, pb);
      PairContact& pair = touching_[a * n + b];
      if (pair.update(gap, step.began.count({a, b}) > 0, ok, kPartedM))
        report_.collisions.push_back({table_->time(), a, b});
      if (pair.measured(ok) && gap < report_.closest.clearance_m) report_.closest = {gap, a, b, table_->time(), pa, pb};
    }
  }
}

// The time limit: whoever still moves stops where it is; every load stops riding.
void BodiesExecution::stopUnfinished(Step& step) {
  for (size_t m = 0; m < step.motions.size(); ++m) {
    if (!step.moving[m]) continue;
    const int e = step.motions[m].entity;
    if (step.motions[m].robot) {
      table_->commandWheels(e, {});
    } else {
      table_->stopSegment(e);
    }
    char why[160];
    std::snprintf(why, sizeof why, "%s did not arrive within %.1f s (3x its path at cruise speed + 10 s)",
                  names_[e].c_str(), step.limit_s);
    step.out.failures.push_back(why);
  }
  for (int i = 0; i < static_cast<int>(table_->size()); ++i) endRide(step, i, false);
}

}  // namespace ddace::exec
