// One simulated table with bodies standing in for the real one: the Hamsters' wheels
// move robot bodies, robots push objects, and the true poses go to a synthetic camera
// whose images the real tracker measures (sim_table_node; launch/execute_real.launch and
// launch/record.launch with sim:=true).
//
// Unlike the mock robots (ros/mock_robot.h), nothing here executes a segment: objects
// move only when a body pushes them and robots only by their wheels, as on the real
// table. The physics is exec::TableSimulator's (Box2D discs, table friction); this class
// names the robots, checks every wheel speed it is given and lays out a scene when no
// demonstration gives one.
//
// Owns: the simulated table of one task. Must not: read a clock or talk to ROS (time
// passes only through step()). Units: metres, radians, seconds, m/s; table frame.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ddace/exec/diff_drive.h"
#include "ddace/exec/table_simulator.h"
#include "ddace/task/task_spec.h"

namespace ddace::exec {

/// Every entity's start pose in `spec`'s order when no demonstration gives one, on the
/// table from corner `min` to corner `max` (metres, table frame): robots in a row along
/// the near edge (facing +y), objects across the middle, goals along the far edge; each
/// row spread evenly, so no two bodies touch. Throws ddace::Error when a row does not fit
/// (its bodies would touch or leave the table).
std::vector<Pose2D> layoutScene(const task::TaskSpec& spec, const Eigen::Vector2d& min, const Eigen::Vector2d& max);

/// One entity as the camera sees it.
struct SimEntity {
  std::string name;
  task::EntityKind kind = task::EntityKind::Robot;
  Pose2D pose;  ///< true pose
};

class SimTable {
 public:
  /// `start`: every entity's pose in `spec`'s order; `robot`: how every robot drives
  /// (its command_timeout_s stops a robot whose wheel speeds stop coming). Throws
  /// ddace::Error for a start of the wrong size or invalid parameters.
  SimTable(const task::TaskSpec& spec, const std::vector<Pose2D>& start, const DiffDriveParams& robot);
  ~SimTable();

  /// The ground speeds of robot `robot`'s wheels from now on (until the next call or the
  /// watchdog). Throws ddace::Error naming `source` when `robot` is no robot of the task
  /// or a speed is not finite; the robot then keeps what it had.
  void drive(const std::string& robot, const WheelSpeeds& wheels, const std::string& source);
  /// Advances one period: robots roll on their wheels, bodies collide, pushed objects
  /// slide to rest.
  void step();

  double periodS() const { return sim_->periodS(); }
  double time() const { return sim_->time(); }
  /// Every entity's true pose, in the task's order.
  std::vector<SimEntity> entities() const;
  /// Every contact between two bodies that began, in time order (indices in the task).
  const std::vector<BodyContact>& contacts() const { return sim_->contacts(); }
  const task::TaskSpec& spec() const { return spec_; }

 private:
  task::TaskSpec spec_;
  std::unique_ptr<TableSimulator> sim_;
};

}  // namespace ddace::exec
