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
  const int n = static_cast<int>(table_->size());
  StepExecution out;
  out.executed.resize(motions.size());
  const double t0 = table_->time();

  struct Mover {
    double length_m = 0;
    bool running = true;
  };
  std::vector<Mover> movers(motions.size());
  std::vector<int> motion_of(n, -1);
  for (size_t m = 0; m < motions.size(); ++m) {
    const StepMotion& mo = motions[m];
    if (mo.entity < 0 || mo.entity >= n) throw Error("bodies execution: a motion of an entity outside the task");
    motion_of[mo.entity] = static_cast<int>(m);
  }

  // Where the step's bodies end (the motions' end points, else where they stand) and what
  // each motion may touch: decided once, as the coordinator decides them for the robots'
  // segments (exec::motionContacts, the path follower node's answer).
  std::vector<Eigen::Vector2d> final_at(n), start_at(n);
  for (int j = 0; j < n; ++j) final_at[j] = start_at[j] = table_->truePose(j).position();
  for (const StepMotion& mo : motions)
    if (!mo.planned.empty()) final_at[mo.entity] = mo.planned.back();
  std::vector<BodyAtStart> bodies;
  for (int j = 0; j < n; ++j) {
    if (!(radius_m_[j] > 0)) continue;
    BodyAtStart b;
    b.name = names_[j], b.position = start_at[j], b.final_position = final_at[j], b.radius_m = radius_m_[j];
    b.object = spec.entities[j].kind == task::EntityKind::Object;
    if (const int m = motion_of[j]; m >= 0) {
      const task::Token& t = tokens.at(motions[m].token);
      b.step = 0;
      b.action = t.action;
      b.target = t.target >= 0 && t.target < n ? names_[t.target] : "";
    }
    bodies.push_back(b);
  }
  const auto contactsOf = [&](int i) {
    std::vector<BodyAtStart> others;
    for (const BodyAtStart& b : bodies)
      if (b.name != names_[i]) others.push_back(b);
    const task::Token& t = tokens.at(motions[motion_of[i]].token);
    return motionContacts(start_at[i], radius_m_[i], final_at[i], 0, t.action,
                          t.target >= 0 && t.target < n ? names_[t.target] : "", others, controller_.safety.margin_m,
                          params_.arrival_radius_m);
  };
  // Its load at its carrier rides in front of it, part of its body for the filter; one
  // passed from afar moves along its own path.
  std::vector<int> load_of(n, -1);  // the load riding with each carrier of the step
  std::vector<MotionContacts> contacts(n);
  for (const StepMotion& mo : motions) {
    if (!(radius_m_[mo.entity] > 0)) continue;
    contacts[mo.entity] = contactsOf(mo.entity);
    if (!mo.robot) {
      contacts[mo.entity].load.clear();  // only robots carry
      contacts[mo.entity].load_ends_against.clear();
      continue;
    }
    const int load = spec.entityIndex(contacts[mo.entity].load);
    if (load >= 0 && !(table_->carrierOf(load) < 0 && table_->ride(mo.entity, load))) {
      contacts[mo.entity].load.clear();  // another carrier's, or too far to ride
      contacts[mo.entity].load_ends_against.clear();
    } else if (load >= 0) {
      load_of[mo.entity] = load;
      contacts[mo.entity].load_rides = true;
    }
  }
  std::set<std::pair<int, int>> loaded(table_->loadedPairs().begin(), table_->loadedPairs().end());

  double limit_s = 0;
  int running = 0;
  for (size_t m = 0; m < motions.size(); ++m) {
    const StepMotion& mo = motions[m];
    out.executed[m] = {table_->truePose(mo.entity).position()};
    Mover& mv = movers[m];
    mv.length_m = lengthOf(mo.planned);
    if (mo.robot) {
      RobotController& c = *controllers_.at(mo.entity);
      // Toward a body, it stops where it is still at one place with it (where the body ends);
      // a carrier's load is what ends at the target.
      double stop = stop_radius_m_;
      if (mo.target >= 0 && mo.target < n && radius_m_[mo.target] > 0 && contacts[mo.entity].load.empty())
        stop = task::stopRadiusToward(
            stop, stop_tolerance_m_,
            task::togetherDistance(radius_m_[mo.entity] + radius_m_[mo.target], params_.arrival_radius_m),
            (final_at[mo.entity] - final_at[mo.target]).norm());
      c.start(PlannedPath{mo.planned, {}}, mo.target >= 0 ? names_[mo.target] : std::string(), stop, stop_radius_m_);
      c.setContacts(contacts[mo.entity]);
      limit_s = std::max(limit_s, 3.0 * mv.length_m / controller_.gains.cruise_speed_mps + 10.0);
    } else if (spec.entities[mo.entity].kind != task::EntityKind::Object) {
      // A predicted token that moves a goal: a flat print takes no segment (the ROS
      // coordinator refuses it too). The trial fails; the evaluation goes on.
      mv.running = false;
      out.failures.push_back(names_[mo.entity] + ": a " + task::toString(spec.entities[mo.entity].kind) +
                             " cannot move");
      continue;
    } else {
      const auto status = table_->startSegment(mo.entity, next_segment_++, mo.planned);
      if (status && status->state != SegmentState::Accepted) {
        mv.running = false;
        out.failures.push_back(names_[mo.entity] + ": " + status->message);
        continue;
      }
      limit_s = std::max(limit_s, 3.0 * mv.length_m / params_.config.table.object_speed_mps + 10.0);
    }
    ++running;
  }
  // The collisions are judged by what the step's motions may touch, as decided above.
  std::vector<DecidedMotion> decided;
  for (const StepMotion& mo : motions)
    decided.push_back({mo.entity, mo.target, final_at[mo.entity], contacts[mo.entity]});
  const AllowedContacts allowed(names_, radius_m_, decided, controller_.safety.margin_m);

  // A carrier stopped: arrived (its load goes on the last bit to its end alone), or failed
  // (the load stops where it is). The two touch: no collision until they part.
  const auto endRide = [&](int carrier, bool arrived) {
    const int load = load_of[carrier];
    if (load < 0) return;
    load_of[carrier] = -1;
    touching_[std::min(carrier, load) * n + std::max(carrier, load)].touchAllowed();
    const int m = motion_of[load];
    if (arrived || m < 0 || !movers[m].running) {
      table_->endRide(load);
      return;
    }
    table_->stopSegment(load);
    movers[m].running = false;
    --running;
    out.executed[m].push_back(table_->truePose(load).position());
  };

  std::vector<Pose2D> measured(n);
  std::set<std::pair<int, int>> began;  // contacts begun in this cycle
  std::vector<SafetyBody> others;
  others.reserve(n);
  while (running > 0 && table_->time() - t0 < limit_s) {
    for (int i = 0; i < n; ++i) measured[i] = table_->measuredPose(i);  // one tracker frame for everybody
    for (int i = 0; i < n; ++i) {
      if (!robot_[i]) continue;
      const int m = motion_of[i];
      if (m < 0 || !movers[m].running) {
        table_->commandWheels(i, {});  // idle: zeros every cycle, as the follower node
        continue;
      }
      others.clear();
      for (int j = 0; j < n; ++j)
        if (j != i && radius_m_[j] > 0) {
          others.push_back({names_[j], measured[j].position(), radius_m_[j], robot_[j]});
          others.back().standing = motion_of[j] < 0 || !movers[motion_of[j]].running;
        }
      const ControlOutput c = controllers_[i]->cycle(measured[i], false, 0.0, radius_m_[i], others, table_->time());
      table_->commandWheels(i, c.wheels);
      if (c.state == MotionState::Running) continue;
      movers[m].running = false;  // done, or failed (a deadlock): the robot stops there
      --running;
      endRide(i, c.state == MotionState::Done);  // the load arrived with it, or stops
      if (c.state == MotionState::Failed) out.failures.push_back(c.message);
    }
    for (const ObjectStatus& s : table_->step()) {
      const int m = motion_of[s.entity];
      if (s.state == SegmentState::Done && m >= 0 && movers[m].running) {
        movers[m].running = false;
        --running;
        out.executed[m].push_back(table_->truePose(s.entity).position());
      }
    }
    for (size_t m = 0; m < motions.size(); ++m)
      if (movers[m].running) out.executed[m].push_back(table_->truePose(motions[m].entity).position());

    // Collisions and the closest approach, on the true poses, by the run report's rule
    // (PairContact): a contact that began between bodies apart and not allowed to touch; a
    // pair touching by design (a motion that ended at its target) once it pushes in
    // deeper than kPartedM when no longer allowed. Box2D keeps resting bodies within
    // kPartedM, so the contacts come from its events.
    const auto& contacts = table_->contacts();
    began.clear();
    for (; contacts_seen_ < contacts.size(); ++contacts_seen_)
      began.insert({contacts[contacts_seen_].a, contacts[contacts_seen_].b});
    for (int a = 0; a < n; ++a) {
      if (!(radius_m_[a] > 0)) continue;
      const Eigen::Vector2d pa = table_->truePose(a).position();
      for (int b = a + 1; b < n; ++b) {
        if (!(radius_m_[b] > 0) || loaded.count({a, b})) continue;
        const Eigen::Vector2d pb = table_->truePose(b).position();
        const double gap = (pa - pb).norm() - radius_m_[a] - radius_m_[b];
        const bool ok = allowed.allowed(a, b, pa, pb);
        PairContact& pair = touching_[a * n + b];
        if (pair.update(gap, began.count({a, b}) > 0, ok, kPartedM))
          report_.collisions.push_back({table_->time(), a, b});
        if (pair.measured(ok) && gap < report_.closest.clearance_m)
          report_.closest = {gap, a, b, table_->time(), pa, pb};
      }
    }
  }
  // The time limit: whoever still moves stops where it is.
  for (size_t m = 0; m < motions.size(); ++m) {
    if (!movers[m].running) continue;
    const int e = motions[m].entity;
    if (motions[m].robot) {
      table_->commandWheels(e, {});
    } else {
      table_->stopSegment(e);
    }
    char why[160];
    std::snprintf(why, sizeof why, "%s did not arrive within %.1f s (3x its path at cruise speed + 10 s)",
                  names_[e].c_str(), limit_s);
    out.failures.push_back(why);
  }
  for (int i = 0; i < n; ++i) endRide(i, false);
  out.duration_s = table_->time() - t0;
  out.positions.resize(n);
  for (int i = 0; i < n; ++i) out.positions[i] = table_->truePose(i).position();
  return out;
}

}  // namespace ddace::exec
