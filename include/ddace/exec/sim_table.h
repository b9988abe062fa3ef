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
// A person's hand (drag(): rviz's interactive markers) teleports nothing, so no body
// ever jumps into another and every recorded path is one a Hamster can drive: a dragged
// robot drives to where it was dropped on its own wheels, by the robots' path-following
// law (exec::PathFollower), pushing objects and stopped by bodies as under the teleop's
// keys; a dragged object or goal is carried by hand at kHandSpeedMps along the straight
// line, an object stopping at contact with any other body.
//
// Owns: the simulated table of one task. Must not: read a clock or talk to ROS (time
// passes only through step()). Units: metres, radians, seconds, m/s; table frame.
#pragma once

#include <cmath>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ddace/exec/diff_drive.h"
#include "ddace/exec/path_follower.h"
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
  /// How fast a hand carries a dragged object or goal.
  static constexpr double kHandSpeedMps = 0.15;
  /// A dragged robot stops this near where it was dropped.
  static constexpr double kDragStopM = 0.01;
  /// A drag that got no nearer for this long (a body in the way) ends where it is.
  static constexpr double kDragGiveUpS = 2.0;

  /// A person drags `entity` toward `target` (table frame) from now on, replacing its
  /// previous drag (see the file comment for how each kind moves). The drag ends at the
  /// target, after kDragGiveUpS without getting nearer (dragNotes() says so), or, for a
  /// robot, when drive() gives it non-zero wheels (the keys take over; zero wheels are
  /// ignored meanwhile). Throws ddace::Error naming `source` for an entity not in the
  /// task or a non-finite target; nothing changes then.
  void drag(const std::string& entity, const Eigen::Vector2d& target, const std::string& source);
  /// Where each entity being dragged is going, by task index (none: not dragged).
  std::vector<std::optional<Eigen::Vector2d>> dragTargets() const;
  /// The drags that ended short of their target since the last call, one line each
  /// naming the entity, how far short and what to do.
  std::vector<std::string> takeDragNotes();
  /// Advances one period: dragged entities move toward their targets, robots roll on
  /// their wheels, bodies collide, pushed objects slide to rest.
  void step();

  double periodS() const { return sim_->periodS(); }
  double time() const { return sim_->time(); }
  /// Every entity's true pose, in the task's order.
  std::vector<SimEntity> entities() const;
  /// Every contact between two bodies that began, in time order (indices in the task).
  const std::vector<BodyContact>& contacts() const { return sim_->contacts(); }
  const task::TaskSpec& spec() const { return spec_; }

 private:
  struct Drag {
    Eigen::Vector2d target;
    PathFollower follower;  ///< a robot's
    double nearest_m = INFINITY;
    double nearest_at_s = 0;  ///< when it last got nearer
  };
  /// One period of drag `i`: a robot's wheels, a hand's step. False when it ended.
  bool advanceDrag(int i, Drag& d);
  /// Where a hand carrying entity `i` from `from` toward `to` can put it this period.
  Eigen::Vector2d handStep(int i, const Eigen::Vector2d& from, const Eigen::Vector2d& to) const;

  task::TaskSpec spec_;
  std::unique_ptr<TableSimulator> sim_;
  DiffDriveParams robot_;
  std::map<int, Drag> drags_;
  std::vector<std::string> drag_notes_;
};

}  // namespace ddace::exec
