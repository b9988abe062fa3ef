#include "ddace/exec/sim_table.h"

#include <cmath>
#include <cstdio>
#include <utility>

#include "ddace/common/error.h"

namespace ddace::exec {

namespace {

/// Where each kind's row lies, as a fraction of the table's depth.
double rowFraction(task::EntityKind kind) {
  switch (kind) {
    case task::EntityKind::Robot:
      return 0.15;
    case task::EntityKind::Object:
      return 0.5;
    case task::EntityKind::Goal:
      break;
  }
  return 0.85;
}

/// Bodies of one row keep at least this gap, so none touches its neighbour at the start.
constexpr double kLayoutGapM = 0.01;

}  // namespace

std::vector<Pose2D> layoutScene(const task::TaskSpec& spec, const Eigen::Vector2d& min, const Eigen::Vector2d& max) {
  const double width_m = max.x() - min.x(), depth_m = max.y() - min.y();
  if (!(width_m > 0) || !(depth_m > 0) || !std::isfinite(width_m) || !std::isfinite(depth_m))
    throw Error("a table of " + std::to_string(width_m) + " x " + std::to_string(depth_m) + " m has no room");
  std::vector<Pose2D> poses(spec.entities.size());
  for (const task::EntityKind kind : {task::EntityKind::Robot, task::EntityKind::Object, task::EntityKind::Goal}) {
    std::vector<int> row;
    double widest_m = 0;
    for (size_t i = 0; i < spec.entities.size(); ++i) {
      if (spec.entities[i].kind != kind) continue;
      row.push_back(static_cast<int>(i));
      widest_m = std::max(widest_m, spec.footprint(static_cast<int>(i)).radius_m);
    }
    if (row.empty()) continue;
    const double spacing_m = width_m / static_cast<double>(row.size() + 1);
    if (spacing_m < 2 * widest_m + kLayoutGapM)
      throw Error("task '" + spec.name + "': " + std::to_string(row.size()) + " " + task::toString(kind) +
                  "s do not fit side by side on a table " + std::to_string(width_m) +
                  " m wide; give their start poses (a demonstration or a scene)");
    for (size_t k = 0; k < row.size(); ++k)
      poses[row[k]] = {min.x() + spacing_m * static_cast<double>(k + 1), min.y() + depth_m * rowFraction(kind),
                       M_PI / 2};
  }
  return poses;
}

SimTable::SimTable(const task::TaskSpec& spec, const std::vector<Pose2D>& start, const DiffDriveParams& robot)
    : spec_(spec), robot_(robot) {
  TableSimulatorParams table;
  table.bodies = true;
  sim_ = std::make_unique<TableSimulator>(spec_, start, robot, table);
}

SimTable::~SimTable() = default;

void SimTable::drive(const std::string& robot, const WheelSpeeds& wheels, const std::string& source) {
  const int i = spec_.entityIndex(robot);
  if (i < 0 || spec_.entities[i].kind != task::EntityKind::Robot)
    throw Error(source + ": '" + robot + "' is no robot of task '" + spec_.name + "'");
  if (!std::isfinite(wheels.left_mps) || !std::isfinite(wheels.right_mps))
    throw Error(source + ": wheel speeds of " + robot + " are not finite");
  if (drags_.count(i)) {
    if (wheels.left_mps == 0 && wheels.right_mps == 0) return;  // a teleop idling on this robot
    drags_.erase(i);                                            // the keys take over
  }
  sim_->commandWheels(i, wheels);
}

void SimTable::drag(const std::string& entity, const Eigen::Vector2d& target, const std::string& source) {
  const int i = spec_.entityIndex(entity);
  if (i < 0) throw Error(source + ": '" + entity + "' is no entity of task '" + spec_.name + "'");
  if (!target.allFinite()) throw Error(source + ": " + entity + " dragged to a non-finite position");
  Drag d{target, PathFollower(), INFINITY, sim_->time()};
  if (spec_.entities[i].kind == task::EntityKind::Robot) {
    FollowerGains gains;
    gains.wheel_base_m = robot_.wheel_base_m;
    gains.max_wheel_speed_mps = robot_.max_wheel_speed_mps;
    gains.stop_radius_m = kDragStopM;
    d.follower = PathFollower(gains);
    d.follower.setPath({{sim_->truePose(i).position(), target}, {}});
  }
  drags_.insert_or_assign(i, std::move(d));
}

std::vector<std::optional<Eigen::Vector2d>> SimTable::dragTargets() const {
  std::vector<std::optional<Eigen::Vector2d>> out(spec_.entities.size());
  for (const auto& [i, d] : drags_) out[static_cast<size_t>(i)] = d.target;
  return out;
}

std::vector<std::string> SimTable::takeDragNotes() {
  return std::exchange(drag_notes_, {});
}

Eigen::Vector2d SimTable::handStep(int i, const Eigen::Vector2d& from, const Eigen::Vector2d& to) const {
  const double left_m = (to - from).norm();
  const double step_m = std::min(left_m, kHandSpeedMps * sim_->periodS());
  if (step_m <= 0) return from;
  const Eigen::Vector2d dir = (to - from) / left_m;
  const double r = sim_->radiusM(i);
  if (r <= 0) return from + dir * step_m;  // a goal has no body: it passes under everything
  // Clear of every other body, or at least not nearer to one it already touches (a robot
  // that drove into the load in hand does not pin it).
  auto clear = [&](const Eigen::Vector2d& p) {
    for (int j = 0; j < static_cast<int>(sim_->size()); ++j) {
      if (j == i || sim_->radiusM(j) <= 0) continue;
      const Eigen::Vector2d q = sim_->truePose(j).position();
      const double d = (p - q).norm(), touch = r + sim_->radiusM(j);
      if (d < touch && d < (from - q).norm()) return false;
    }
    return true;
  };
  if (clear(from + dir * step_m)) return from + dir * step_m;
  double lo = 0, hi = step_m;  // up to contact: the farthest clear point of the step
  for (int k = 0; k < 20; ++k) (clear(from + dir * (lo + hi) / 2) ? lo : hi) = (lo + hi) / 2;
  return from + dir * lo;
}

bool SimTable::advanceDrag(int i, Drag& d) {
  const Eigen::Vector2d at = sim_->truePose(i).position();
  const double left_m = (d.target - at).norm();
  if (spec_.entities[i].kind == task::EntityKind::Robot) {
    const FollowerOutput out = d.follower.compute(sim_->truePose(i));
    sim_->commandWheels(i, out.done ? WheelSpeeds{} : out.wheels);
    if (out.done) return false;
  } else {
    if (left_m <= 1e-6) return false;
    sim_->place(i, handStep(i, at, d.target));
  }
  if (left_m < d.nearest_m - 1e-3) {
    d.nearest_m = left_m;
    d.nearest_at_s = sim_->time();
  } else if (sim_->time() - d.nearest_at_s > kDragGiveUpS) {
    if (spec_.entities[i].kind == task::EntityKind::Robot) sim_->commandWheels(i, WheelSpeeds{});
    char m[64];
    std::snprintf(m, sizeof m, "%.3f m", left_m);
    drag_notes_.push_back(spec_.entities[i].name + " stopped " + m +
                          " short of where it was dropped: it got no "
                          "nearer for " +
                          std::to_string(static_cast<int>(kDragGiveUpS)) +
                          " s (a body in the way); drag it around what blocks it");
    return false;
  }
  return true;
}

void SimTable::step() {
  for (auto it = drags_.begin(); it != drags_.end();)
    it = advanceDrag(it->first, it->second) ? std::next(it) : drags_.erase(it);
  sim_->step();  // no object runs a segment: nothing to report
}

std::vector<SimEntity> SimTable::entities() const {
  std::vector<SimEntity> out;
  out.reserve(spec_.entities.size());
  for (size_t i = 0; i < spec_.entities.size(); ++i)
    out.push_back({spec_.entities[i].name, spec_.entities[i].kind, sim_->truePose(static_cast<int>(i))});
  return out;
}

}  // namespace ddace::exec
