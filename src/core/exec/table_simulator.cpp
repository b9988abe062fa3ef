#include "ddace/exec/table_simulator.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

#include <Eigen/Geometry>
#include <box2d/box2d.h>

#include "ddace/common/error.h"
#include "ddace/exec/safety_filter.h"
#include "ddace/task/end_point.h"

namespace ddace::exec {

namespace {
// Box2D is tuned for bodies of 0.1 to 10 units and keeps contacts within a 5 mm "slop" of
// a unit: one unit is 10 cm here, so a 2 cm Hamster is 0.2 units and the slop 0.5 mm.
constexpr double kUnitsPerMetre = 10.0;
b2Vec2 toWorld(const Eigen::Vector2d& p) {
  return {static_cast<float>(p.x() * kUnitsPerMetre), static_cast<float>(p.y() * kUnitsPerMetre)};
}
Eigen::Vector2d fromWorld(const b2Vec2& p) {
  return {p.x / kUnitsPerMetre, p.y / kUnitsPerMetre};
}
}  // namespace

/// The Box2D world of the table: one body per robot and object, a listener recording every
/// contact that begins and a filter keeping loaded pairs apart.
struct TableSimulator::Physics : public b2ContactListener, public b2ContactFilter {
  b2World world{b2Vec2(0, 0)};
  std::vector<b2Body*> bodies;  ///< by entity index; null for goals
  std::set<std::pair<int, int>> loaded;
  std::set<std::pair<int, int>> riding;    ///< carrier and load of a carry step (ride())
  std::vector<std::pair<int, int>> began;  ///< contacts begun during the current step

  static int indexOf(b2Fixture* f) { return static_cast<int>(f->GetBody()->GetUserData().pointer) - 1; }
  bool ShouldCollide(b2Fixture* a, b2Fixture* b) override {
    const int i = indexOf(a), j = indexOf(b);
    const std::pair<int, int> p{std::min(i, j), std::max(i, j)};
    return !loaded.count(p) && !riding.count(p);
  }
  void BeginContact(b2Contact* c) override {
    const int i = indexOf(c->GetFixtureA()), j = indexOf(c->GetFixtureB());
    began.emplace_back(std::min(i, j), std::max(i, j));
  }
};

TableSimulator::~TableSimulator() = default;
TableSimulator::TableSimulator(TableSimulator&&) noexcept = default;

void TableSimulatorParams::validate() const {
  if (!(object_speed_mps > 0) || !std::isfinite(object_speed_mps))
    throw Error("object_speed_mps must be positive and finite");
  if (!(object_damping_hz >= 0) || !std::isfinite(object_damping_hz))
    throw Error("object_damping_hz must be a finite number >= 0");
  if (status_every_cycles < 1) throw Error("status_every_cycles must be at least 1");
}

TableSimulator::TableSimulator(const task::TaskSpec& spec, const std::vector<Pose2D>& start,
                               const DiffDriveParams& robot, const TableSimulatorParams& params,
                               const std::vector<std::string>& stalled)
    : spec_(spec), names_(spec.entityNames()), robot_(robot), params_(params) {
  robot_.validate();
  params_.validate();
  const size_t n = spec.entities.size();
  if (start.size() != n)
    throw Error("task '" + spec.name + "' has " + std::to_string(n) + " entities but the scene " +
                std::to_string(start.size()) + " start poses");
  for (const std::string& s : stalled) {
    const int i = spec.entityIndex(s);
    if (i < 0 || spec.entities[i].kind != task::EntityKind::Robot)
      throw Error("stalled '" + s + "' is not a robot of task '" + spec.name + "'");
  }
  entities_.resize(n);
  for (size_t i = 0; i < n; ++i) {
    Entity& e = entities_[i];
    e.kind = spec.entities[i].kind;
    e.pose = start[i];
    if (e.kind != task::EntityKind::Robot) continue;
    DiffDriveParams p = robot_;
    p.seed = robot_.seed + i;  // independent noise per robot
    e.robot = std::make_unique<DiffDriveModel>(p, start[i]);
    e.robot->setStalled(std::find(stalled.begin(), stalled.end(), names_[i]) != stalled.end());
  }

  physics_ = std::make_unique<Physics>();
  physics_->world.SetContactListener(physics_.get());
  physics_->world.SetContactFilter(physics_.get());
  physics_->bodies.assign(n, nullptr);
  std::vector<double> radii(n, 0.0);
  for (size_t i = 0; i < n; ++i) {
    const BodyShape shape = bodyShape(spec, static_cast<int>(i));
    if (shape.obstacle && shape.radius_m > 0) radii[i] = entities_[i].radius_m = shape.radius_m;
  }
  // The start decides which pairs are loaded (overlapping): they never collide.
  meter_ = std::make_unique<ClearanceMeter>(radii, 0.0);
  measureClearance();
  for (const auto& p : meter_->loadedPairs()) physics_->loaded.insert(p);
  for (size_t i = 0; i < n; ++i) {
    if (!params_.bodies || !(radii[i] > 0)) continue;
    b2BodyDef def;
    def.type = b2_dynamicBody;
    def.position = toWorld(start[i].position());
    def.angle = static_cast<float>(start[i].yaw);
    def.bullet = true;  // no tunnelling between small fast discs
    const bool robot = entities_[i].kind == task::EntityKind::Robot;
    if (!robot) {
      def.linearDamping = static_cast<float>(params_.object_damping_hz);
      def.angularDamping = static_cast<float>(params_.object_damping_hz);
    }
    def.userData.pointer = i + 1;
    b2Body* body = physics_->world.CreateBody(&def);
    b2CircleShape circle;
    circle.m_radius = static_cast<float>(radii[i] * kUnitsPerMetre);
    b2FixtureDef fixture;
    fixture.shape = &circle;
    fixture.density = robot ? 4.0f : 1.0f;  // a driven robot outweighs a box it pushes
    fixture.friction = 0.3f;
    fixture.restitution = 0.0f;
    body->CreateFixture(&fixture);
    physics_->bodies[i] = body;
  }
  // Bodies touching as the table is set are in contact already: no contact begins for them.
  physics_->world.Step(0, 8, 3);
  physics_->began.clear();
}

void TableSimulator::halt(int i) {
  Entity& e = entities_[i];
  e.moving = false;
  if (const int carrier = e.carrier; carrier >= 0) {  // a carried load stays where it is
    e.carrier = -1;
    physics_->riding.erase({std::min(carrier, i), std::max(carrier, i)});
    for (int k : {carrier, i})  // contacts already made are filtered again
      if (b2Body* body = physics_->bodies[k])
        for (b2Fixture* f = body->GetFixtureList(); f; f = f->GetNext()) f->Refilter();
  }
  if (b2Body* body = physics_->bodies[i]) {  // at rest where it is, table friction back on
    body->SetLinearVelocity(b2Vec2(0, 0));
    body->SetLinearDamping(static_cast<float>(params_.object_damping_hz));
  }
}

void TableSimulator::measureClearance() {
  std::vector<Eigen::Vector2d> at(entities_.size());
  for (size_t i = 0; i < entities_.size(); ++i) at[i] = entities_[i].pose.position();
  meter_->update(time_s_, at);
}

void TableSimulator::checkIndex(int i) const {
  if (i < 0 || static_cast<size_t>(i) >= entities_.size())
    throw Error("entity index " + std::to_string(i) + " is not in the task");
}

const TableSimulator::Entity& TableSimulator::entity(int i) const {
  checkIndex(i);
  return entities_[i];
}

TableSimulator::Entity& TableSimulator::object(int i) {
  checkIndex(i);
  Entity& e = entities_[i];
  if (e.kind != task::EntityKind::Object) throw Error("'" + names_[i] + "' is not an object: it takes no segments");
  return e;
}

ObjectStatus TableSimulator::report(int i, SegmentState state, std::string message) const {
  const Entity& e = entities_[i];
  ObjectStatus s;
  s.entity = i;
  s.segment_id = e.segment_id;
  s.state = state;
  if (e.carried && e.carrier >= 0) {  // riding: how much nearer its goal it came
    const double from = (e.carried->goal() - e.carried->start()).norm();
    const double left = (e.carried->goal() - e.pose.position()).norm();
    s.progress = from > 0 ? std::clamp(1 - left / from, 0.0, 1.0) : 1.0;
    s.distance_to_goal_m = left;
  } else if (e.carried) {
    s.progress = e.carried->progress();
    s.distance_to_goal_m = (e.carried->goal() - e.pose.position()).norm();
  }
  s.message = std::move(message);
  return s;
}

bool TableSimulator::carry(int carrier, int load) {
  const Entity& c = entity(carrier);
  if (!c.robot) throw Error("'" + names_[carrier] + "' is not a robot: it carries nothing");
  Entity& l = object(load);
  if (l.carrier == carrier) return true;
  if (!(c.radius_m > 0) || !(l.radius_m > 0) || l.carrier >= 0) return false;
  const Eigen::Vector2d d = l.pose.position() - c.pose.position();
  if (!task::together(spec_, carrier, c.pose.position(), load, l.pose.position())) return false;
  l.carrier = carrier;
  if (!params_.loads_ride) {
    if (b2Body* body = physics_->bodies[load]) {  // at rest until its carrier drives into it
      body->SetLinearVelocity(b2Vec2(0, 0));
      body->SetLinearDamping(static_cast<float>(params_.object_damping_hz));
    }
    return true;
  }
  l.ride_offset0 = Eigen::Rotation2Dd(-c.pose.yaw) * d;
  l.ride_contact_m = c.radius_m + l.radius_m;
  l.ride_travel_m = 0;
  physics_->riding.insert({std::min(carrier, load), std::max(carrier, load)});
  for (int i : {carrier, load})  // contacts already made are filtered again
    if (b2Body* body = physics_->bodies[i])
      for (b2Fixture* f = body->GetFixtureList(); f; f = f->GetNext()) f->Refilter();
  return true;
}

void TableSimulator::endCarry(int load) {
  Entity& l = object(load);
  if (l.carrier < 0) return;
  if (!l.moving) {
    halt(load);  // ends the carry
    return;
  }
  const Eigen::Vector2d goal = l.carried->goal();
  if (!params_.loads_ride) {  // judged where it lies, as on the real table
    ObjectStatus s = report(load, SegmentState::Done);
    if (!task::arrived(l.pose.position(), goal, spec_.arrival_radius + task::kArrivalToleranceM)) {
      char why[200];
      std::snprintf(why, sizeof why, "%s is %.1f cm from its end point when its carrier %s was done",
                    names_[load].c_str(), 100 * (goal - l.pose.position()).norm(), names_[l.carrier].c_str());
      s.state = SegmentState::Failed;
      s.message = why;
    }
    push_ended_.push_back(s);
    halt(load);
    return;
  }
  halt(load);
  l.carried = std::make_unique<CarriedObject>(std::vector<Eigen::Vector2d>{l.pose.position(), goal}, l.pose.position(),
                                              params_.object_speed_mps);
  l.moving = true;
}

int TableSimulator::carrierOf(int load) const {
  return entity(load).carrier;
}

void TableSimulator::commandWheels(int i, const WheelSpeeds& wheels) {
  const Entity& e = entity(i);
  if (!e.robot) throw Error("'" + names_[i] + "' is not a robot: it has no wheels");
  e.robot->command(wheels, time_s_);
}

void TableSimulator::place(int i, const Eigen::Vector2d& position) {
  checkIndex(i);
  if (!position.allFinite()) throw Error("'" + names_[i] + "' placed at a non-finite position");
  Entity& e = entities_[i];
  if (e.carrier >= 0 || e.moving) halt(i);
  e.pose.x = position.x();
  e.pose.y = position.y();
  if (e.robot) e.robot->setTruePose(e.pose);
  if (b2Body* body = physics_->bodies[i]) {
    body->SetTransform(toWorld(position), static_cast<float>(e.pose.yaw));
    body->SetLinearVelocity(b2Vec2(0, 0));
    body->SetAngularVelocity(0);
  }
}

void TableSimulator::setStalled(int i, bool stalled) {
  checkIndex(i);
  Entity& e = entities_[i];
  if (!e.robot) throw Error("'" + names_[i] + "' is not a robot: it has no wheels to stall");
  e.robot->setStalled(stalled);
}

void TableSimulator::setWheelGain(int i, double gain) {
  checkIndex(i);
  Entity& e = entities_[i];
  if (!e.robot) throw Error("'" + names_[i] + "' is not a robot: it has no wheels to slow");
  e.robot->setWheelGain(gain);
}

std::optional<ObjectStatus> TableSimulator::startSegment(int i, uint32_t segment_id,
                                                         const std::vector<Eigen::Vector2d>& path) {
  Entity& e = object(i);
  if (estopped_) {
    e.segment_id = segment_id;
    halt(i);
    e.carried.reset();
    return report(i, SegmentState::Aborted, "e-stop is active");
  }
  if (e.moving && segment_id == e.segment_id) return std::nullopt;  // a re-sent copy of the running segment
  if (path.empty()) return refuseSegment(i, segment_id, "segment path is empty");
  e.carried = std::make_unique<CarriedObject>(path, e.pose.position(), params_.object_speed_mps);
  e.segment_id = segment_id;
  e.moving = true;
  return report(i, SegmentState::Accepted);
}

ObjectStatus TableSimulator::refuseSegment(int i, uint32_t segment_id, const std::string& reason) {
  Entity& e = object(i);
  e.segment_id = segment_id;
  halt(i);
  e.carried.reset();  // the refused segment has no progress of its own
  return report(i, SegmentState::Failed, reason);
}

std::optional<ObjectStatus> TableSimulator::stopSegment(int i) {
  Entity& e = object(i);
  if (!e.moving) {
    if (e.carrier >= 0) halt(i);  // ends its carry
    return std::nullopt;
  }
  halt(i);
  return report(i, SegmentState::Aborted, "stopped");
}

std::vector<ObjectStatus> TableSimulator::setEstop(bool active) {
  estopped_ = active;
  std::vector<ObjectStatus> out;
  if (!active) return out;
  for (size_t i = 0; i < entities_.size(); ++i)
    if (entities_[i].moving) {
      halt(static_cast<int>(i));
      out.push_back(report(static_cast<int>(i), SegmentState::Aborted, "e-stop"));
    }
  return out;
}

// Riding loads: toward where the carrier's front is after this step. The offset swings
// from where the load began (carrier frame) to straight ahead at contact, the short way
// round, over the carrier's first kRideSwingM of travel.
void TableSimulator::rideLoads(const std::vector<Eigen::Vector2d>& before) {
  const double dt = periodS();
  for (size_t i = 0; i < entities_.size(); ++i) {
    Entity& e = entities_[i];
    if (e.carrier < 0) continue;
    const Entity& c = entities_[static_cast<size_t>(e.carrier)];
    const Pose2D now = c.robot->truePose();  // the unicycle's pose after this step
    e.ride_travel_m += (now.position() - before[static_cast<size_t>(e.carrier)]).norm();
    const double s = std::min(1.0, e.ride_travel_m / kRideSwingM), w = s * s * (3 - 2 * s);
    const double r0 = e.ride_offset0.norm(), a0 = std::atan2(e.ride_offset0.y(), e.ride_offset0.x());
    const double r = r0 + (e.ride_contact_m - r0) * w, a = now.yaw + (1 - w) * a0;
    const Eigen::Vector2d want = now.position() + r * Eigen::Vector2d(std::cos(a), std::sin(a));
    if (b2Body* body = physics_->bodies[i]) {
      body->SetLinearVelocity(toWorld((want - fromWorld(body->GetPosition())) / dt));
      body->SetAngularVelocity(static_cast<float>(wrapAngle(now.yaw - e.pose.yaw) / dt));
      body->SetLinearDamping(0);
    } else {
      e.pose = {want.x(), want.y(), now.yaw};
    }
  }
}

void TableSimulator::pushLoadsApart() {
  for (size_t i = 0; i < entities_.size(); ++i) {
    Entity& e = entities_[i];
    if (e.carrier < 0 || physics_->bodies[i]) continue;  // with bodies, Box2D pushes
    const Entity& c = entities_[static_cast<size_t>(e.carrier)];
    const Eigen::Vector2d d = e.pose.position() - c.pose.position();
    const double contact_m = c.radius_m + e.radius_m;
    if (d.norm() >= contact_m || d.norm() < 1e-9) continue;
    const Eigen::Vector2d p = c.pose.position() + contact_m * d.normalized();
    e.pose.x = p.x();
    e.pose.y = p.y();
  }
}

std::vector<ObjectStatus> TableSimulator::step() {
  const double dt = periodS();
  std::vector<ObjectStatus> out;
  out.swap(push_ended_);  // pushed loads whose carriers were done (endCarry())
  std::vector<Eigen::Vector2d> before(entities_.size());
  for (size_t i = 0; i < entities_.size(); ++i) before[i] = entities_[i].pose.position();
  // Where each body is driven this step: robots by their wheels (the unicycle's motion),
  // objects along their segments; Box2D then resolves the contacts.
  for (size_t i = 0; i < entities_.size(); ++i) {
    Entity& e = entities_[i];
    b2Body* body = physics_->bodies[i];
    if (e.robot) {
      const Pose2D before = e.robot->truePose();
      e.robot->step();
      const Pose2D after = e.robot->truePose();
      if (body) {
        const Eigen::Vector2d v = (after.position() - before.position()) / dt;
        body->SetLinearVelocity(toWorld(v));
        body->SetAngularVelocity(static_cast<float>(wrapAngle(after.yaw - before.yaw) / dt));
      } else {
        e.pose = after;
      }
    } else if (e.carrier >= 0) {
      continue;  // rides (placed after its carrier, below) or moves only when pushed
    } else if (e.moving) {
      const Eigen::Vector2d p = e.carried->advance(dt);
      if (body) {
        // Toward the carried point, at most twice the segment's speed (a blocked object
        // is blocked, it does not teleport).
        Eigen::Vector2d v = (p - fromWorld(body->GetPosition())) / dt;
        const double cap = 2 * params_.object_speed_mps;
        if (v.norm() > cap) v *= cap / v.norm();
        body->SetLinearVelocity(toWorld(v));
        body->SetLinearDamping(0);  // carried: no friction of its own
      } else {
        e.pose.x = p.x();
        e.pose.y = p.y();
      }
    }
  }
  if (params_.loads_ride) rideLoads(before);
  else pushLoadsApart();
  physics_->began.clear();
  physics_->world.Step(static_cast<float>(dt), 8, 3);
  time_s_ += dt;
  for (size_t i = 0; i < entities_.size(); ++i) {
    b2Body* body = physics_->bodies[i];
    if (!body) continue;
    Entity& e = entities_[i];
    const Eigen::Vector2d p = fromWorld(body->GetPosition());
    e.pose = {p.x(), p.y(), wrapAngle(body->GetAngle())};
    if (e.robot) {
      e.robot->setTruePose(e.pose);
      body->SetLinearVelocity(b2Vec2(0, 0));  // the wheels decide again next step
      body->SetAngularVelocity(0);
    }
  }
  for (const auto& [a, b] : physics_->began) contacts_.push_back({time_s_, a, b});
  measureClearance();
  for (size_t i = 0; i < entities_.size(); ++i) {
    Entity& e = entities_[i];
    if (!e.moving) continue;
    if (e.carrier < 0 && e.carried->arrived()) {
      halt(static_cast<int>(i));
      out.push_back(report(static_cast<int>(i), SegmentState::Done));
    } else if (++e.status_cycle % params_.status_every_cycles == 0) {
      out.push_back(report(static_cast<int>(i), SegmentState::Running));
    }
  }
  return out;
}

Pose2D TableSimulator::truePose(int i) const {
  return entity(i).pose;
}

Pose2D TableSimulator::measuredPose(int i) {
  const Entity& e = entity(i);
  return e.robot ? e.robot->measuredPose() : e.pose;
}

bool carries(const task::TaskSpec& spec, int carrier_step, const task::Token& carrier, int load_step,
             const task::Token& load) {
  const int n = static_cast<int>(spec.entities.size());
  for (const task::Token& t : {carrier, load})
    if (t.entity < 0 || t.entity >= n || t.target >= n) return false;
  return carrier_step == load_step && task::carriedLoad(spec, {carrier, load}, 0) == 1;
}

}  // namespace ddace::exec
