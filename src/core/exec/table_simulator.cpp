#include "ddace/exec/table_simulator.h"

#include <algorithm>
#include <cmath>

#include "ddace/common/error.h"

namespace ddace::exec {

void TableSimulatorParams::validate() const {
  if (!(object_speed_mps > 0) || !std::isfinite(object_speed_mps))
    throw Error("object_speed_mps must be positive and finite");
  if (status_every_cycles < 1) throw Error("status_every_cycles must be at least 1");
}

TableSimulator::TableSimulator(const task::TaskSpec& spec, const std::vector<Pose2D>& start,
                               const DiffDriveParams& robot, const TableSimulatorParams& params,
                               const std::vector<std::string>& stalled)
    : names_(spec.entityNames()), robot_(robot), params_(params) {
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
  if (e.carried) {
    s.progress = e.carried->progress();
    s.distance_to_goal_m = (e.carried->goal() - e.pose.position()).norm();
  }
  s.message = std::move(message);
  return s;
}

void TableSimulator::commandWheels(int i, const WheelSpeeds& wheels) {
  const Entity& e = entity(i);
  if (!e.robot) throw Error("'" + names_[i] + "' is not a robot: it has no wheels");
  e.robot->command(wheels, time_s_);
}

std::optional<ObjectStatus> TableSimulator::startSegment(int i, uint32_t segment_id,
                                                         const std::vector<Eigen::Vector2d>& path) {
  Entity& e = object(i);
  if (estopped_) {
    e.segment_id = segment_id;
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
  e.moving = false;
  e.carried.reset();  // the refused segment has no progress of its own
  return report(i, SegmentState::Failed, reason);
}

std::optional<ObjectStatus> TableSimulator::stopSegment(int i) {
  Entity& e = object(i);
  if (!e.moving) return std::nullopt;
  e.moving = false;
  return report(i, SegmentState::Aborted, "stopped");
}

std::vector<ObjectStatus> TableSimulator::setEstop(bool active) {
  estopped_ = active;
  std::vector<ObjectStatus> out;
  if (!active) return out;
  for (size_t i = 0; i < entities_.size(); ++i)
    if (entities_[i].moving) {
      entities_[i].moving = false;
      out.push_back(report(static_cast<int>(i), SegmentState::Aborted, "e-stop"));
    }
  return out;
}

std::vector<ObjectStatus> TableSimulator::step() {
  const double dt = periodS();
  std::vector<ObjectStatus> out;
  for (size_t i = 0; i < entities_.size(); ++i) {
    Entity& e = entities_[i];
    if (e.robot) {
      e.robot->step();
      e.pose = e.robot->truePose();
    } else if (e.moving) {
      const Eigen::Vector2d p = e.carried->advance(dt);
      e.pose.x = p.x();
      e.pose.y = p.y();
      if (e.carried->arrived()) {
        e.moving = false;
        out.push_back(report(static_cast<int>(i), SegmentState::Done));
      } else if (++e.status_cycle % params_.status_every_cycles == 0) {
        out.push_back(report(static_cast<int>(i), SegmentState::Running));
      }
    }
  }
  time_s_ += dt;
  return out;
}

Pose2D TableSimulator::truePose(int i) const {
  return entity(i).pose;
}

Pose2D TableSimulator::measuredPose(int i) {
  const Entity& e = entity(i);
  return e.robot ? e.robot->measuredPose() : e.pose;
}

}  // namespace ddace::exec
