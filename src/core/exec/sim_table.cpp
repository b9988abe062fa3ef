#include "ddace/exec/sim_table.h"

#include <cmath>

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
    : spec_(spec) {
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
  sim_->commandWheels(i, wheels);
}

void SimTable::step() {
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
